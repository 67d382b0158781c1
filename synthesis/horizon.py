"""The prediction horizon ``i`` chosen from the data, by a stated rule that explains itself.

The horizon is the one design choice of the model-free method (§5.4) without a formula: too short and the
finite-horizon game can cancel a right-half-plane zero or miss a slow mode (the closed loop is unstable
on the true plant although every finite-horizon bound holds); longer costs data and time.  The rule of
:func:`choose_horizon`:

1. a **data-based model** ``P̂`` is identified once, by :func:`~synthesis.subspace_id` (noise-floor order)
   at the largest candidate horizon;
2. for each candidate ``i`` in increasing order the nominal design (:func:`~synthesis.hinf_design`,
   ``γ = gamma_ratio·γ_min``) is computed from the predictor of horizon ``i``, and three checks run:

   * **stable**: the LTI controller (5.3)–(5.4) stabilises ``P̂`` (closed-loop spectral radius ``< 1``);
   * **no cancelled right-half-plane zero**: no pole of the controller lies within ``cancel_tol·|ζ|``
     of a zero ``ζ`` of ``P̂`` outside the unit circle (such a loop is internally unstable however
     well its input-output maps look; a guard, since in our measurements the short-horizon designs on
     the non-minimum-phase plant were caught by the stability check: a closed-loop real pole near
     1.17 at i = 20, none of the controller's poles on the zero);
   * **γ_min settled**: ``|γ_min(i) − γ_min(i_prev)| ≤ settle_tol·γ_min(i)``, ``i_prev`` the previous
     candidate (the finite-horizon level has converged towards its ∞-horizon value);

3. the **smallest** ``i`` passing all three is returned.  If none does, the largest stable one (else the
   largest candidate) is returned with ``ok = False`` and the reason.

The checks use only the data (``P̂`` stands in for the plant); they are necessary conditions, not a
certificate — for one use :func:`unfalsify.robust_design_from_data`.
"""
from __future__ import annotations

import numbers
import warnings
from dataclasses import dataclass

import control
import numpy as np

from ._repr import result
from ._validation import DataError, as_signal, check_level, check_sample_time
from .hinf import HinfDesign, hinf_design
from .predictor import PersistenceWarning, fit_predictor
from .subspace_id import subspace_id

__all__ = ["HorizonCandidate", "HorizonChoice", "choose_horizon"]

#: candidate horizons of :func:`choose_horizon` (those the record supports are tried)
DEFAULT_HORIZONS = (10, 15, 20, 30, 40, 50, 60, 80)


@result
@dataclass(frozen=True, eq=False)
class HorizonCandidate:
    """One horizon tried by :func:`choose_horizon`.

    Attributes
    ----------
    horizon : int
    gamma_min : float
        γ_min of the design at this horizon.
    change : float
        ``|γ_min(i) − γ_min(i_prev)| / γ_min(i)`` (``nan`` for the first candidate).
    spectral_radius : float
        Of the loop of the design's controller with the data-based model ``P̂``.
    stable, cancels, settled : bool
        The three checks (module docstring); ``cancels`` True means a right-half-plane zero is cancelled.
    """

    horizon: int
    gamma_min: float
    change: float
    spectral_radius: float
    stable: bool
    cancels: bool
    settled: bool

    @property
    def passes(self) -> bool:
        """All three checks hold."""
        return bool(self.stable and not self.cancels and self.settled)


@result
@dataclass(frozen=True, eq=False)
class HorizonChoice:
    """Result of :func:`choose_horizon`.

    Attributes
    ----------
    horizon : int
        The chosen ``i``.
    reason : str
        Why: the rule's verdict in words, naming the candidates that failed and which check.
    ok : bool
        True when the chosen ``i`` passes all three checks.
    design : HinfDesign
        The nominal design at ``horizon`` (on the whole record).
    model : control.StateSpace
        The data-based model ``P̂`` the checks used.
    model_order : int
        Its order (noise-floor criterion).
    candidates : tuple of HorizonCandidate
        Every horizon tried, in order (the scan stops at the first that passes).
    """

    horizon: int
    reason: str
    ok: bool
    design: HinfDesign
    model: control.StateSpace
    model_order: int
    candidates: tuple


def _loop_radius(P, K, l):
    Ky = control.ss(K)[:, l:]
    loop = control.feedback(control.ss(P), Ky, sign=+1)
    A = np.asarray(loop.A, float)
    return float(np.max(np.abs(np.linalg.eigvals(A)))) if A.size else 0.0


def _cancels(P, K, tol):
    try:
        z = np.atleast_1d(control.ss(P).zeros())
    except Exception:  # pragma: no cover - a model without finite zeros
        return False
    z = z[np.isfinite(z) & (np.abs(z) > 1.0)]
    if z.size == 0:
        return False
    p = np.linalg.eigvals(np.asarray(control.ss(K).A, float))
    return bool(np.any(np.min(np.abs(z[:, None] - p[None, :]), axis=1) <= tol * np.abs(z)))


def choose_horizon(u, y, W1, W2, *, dt, horizons=None, gamma_ratio: float = 1.1, settle_tol: float = 0.05,
                   cancel_tol: float = 0.02, min_column_ratio: float = 3.0) -> HorizonChoice:
    """Choose the prediction horizon ``i`` from the data by the rule of the module docstring.

    Parameters
    ----------
    u, y : array_like, shape (n,) or (n, channels)
        The experiment (time along axis 0).
    W1, W2 : weights
        As for :func:`~synthesis.hinf_design`.
    dt : float
        The data's sample time (checked against the weights').
    horizons : sequence of int, optional
        Two or more candidates, default :data:`DEFAULT_HORIZONS`; those leaving fewer than ``min_column_ratio``
        Hankel columns per regressor (``j < ratio·i(2m + l)``) are skipped.
    gamma_ratio : float
        γ / γ_min of the designs (default 1.1).
    settle_tol : float
        Relative change of γ_min between consecutive candidates counted as settled (default 5 %).
    cancel_tol : float
        Relative distance of a controller pole to a right-half-plane zero of ``P̂`` counted as a
        cancellation (default 2 %).
    min_column_ratio : float
        See ``horizons``.

    Returns
    -------
    HorizonChoice
        ``.horizon``, ``.reason``, ``.ok``, the design at that horizon and every candidate's checks.

    Raises
    ------
    DataError
        Bad data or weights; fewer than two candidate horizons fit the record (collect more data or
        pass smaller ``horizons``); bad tolerances.

    Examples
    --------
    The non-minimum-phase plant ``2(1 − s)/((s + 1)(s + 2))`` at 10 Hz with the §5.4 weights: short
    horizons are refused (not settled, or the design cancels the zero at ``z = e^{0.1}``):

    >>> import control, numpy as np
    >>> import synthesis as sy
    >>> dt = 0.1
    >>> P = control.c2d(control.tf([-2, 2], [1, 3, 2]), dt)
    >>> rng = np.random.default_rng(1)
    >>> u = np.sign(rng.standard_normal(1500))
    >>> y = control.forced_response(P, U=u + 0.05 * rng.standard_normal(1500)).outputs
    >>> y = y + 0.05 * rng.standard_normal(1500)
    >>> s = control.tf("s")
    >>> W1 = sy.tustin(100 * (0.01 / 5) * (s + 5) / (s + 0.01), dt)
    >>> W2 = sy.tustin(0.05 * (10 / 0.5) * (s + 0.5) / (s + 10), dt)
    >>> choice = sy.choose_horizon(u, y, W1, W2, dt=dt)
    >>> choice.ok, choice.horizon > 20
    (True, True)
    >>> print(choice.reason)  # doctest: +ELLIPSIS
    i = ... is the smallest candidate whose design stabilises the data-based model ...
    """
    u = as_signal(u, "u")
    y = as_signal(y, "y", n=u.shape[0])
    n, m = u.shape
    l = y.shape[1]
    dt = check_sample_time(dt, "dt", allow_true=False)
    gamma_ratio = check_level(gamma_ratio, "gamma_ratio", minimum=1.0)
    settle_tol = check_level(settle_tol, "settle_tol")
    cancel_tol = check_level(cancel_tol, "cancel_tol")
    min_column_ratio = check_level(min_column_ratio, "min_column_ratio")
    horizons = DEFAULT_HORIZONS if horizons is None else horizons
    try:
        cand = sorted({int(h) for h in horizons if not isinstance(h, bool) and isinstance(h, numbers.Integral)})
    except TypeError:
        raise DataError(f"horizons must be a sequence of integers, got {horizons!r}") from None
    if len(cand) < 2 or len(cand) != len(list(horizons)) or any(h < 2 for h in cand):
        raise DataError(f"horizons must be two or more distinct integers >= 2 (the choice compares a horizon with the "
                        f"next), got {horizons!r}")
    fits = [h for h in cand if n - 2 * h + 1 >= min_column_ratio * h * (2 * m + l)]
    if len(fits) < 2:
        need = int(np.ceil(min_column_ratio * cand[min(1, len(cand) - 1)] * (2 * m + l))) + 2 * cand[min(1, len(cand) - 1)]
        raise DataError(f"only {len(fits)} of the candidate horizons {cand} fit {n} samples (j ≥ {min_column_ratio:g}·i(2m+l) "
                        f"Hankel columns): collect at least {need} samples or pass smaller horizons")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PersistenceWarning)
        sid = subspace_id(u, y, min(fits[-1], 64), dt=dt)
    P_hat = sid.model
    rows: list[HorizonCandidate] = []
    designs: dict[int, HinfDesign] = {}
    prev = None
    chosen = None
    for h in fits:
        design = hinf_design(fit_predictor(u, y, h, dt=dt), W1, W2, gamma_ratio=gamma_ratio, dt=dt)
        designs[h] = design
        g = float(design.gamma_min)
        change = float("nan") if prev is None else abs(g - prev) / g
        rho = _loop_radius(P_hat, design.controller, l)
        row = HorizonCandidate(horizon=h, gamma_min=g, change=change, spectral_radius=rho, stable=rho < 1.0,
                               cancels=_cancels(P_hat, design.controller, cancel_tol),
                               settled=bool(prev is not None and change <= settle_tol))
        rows.append(row)
        prev = g
        if row.passes:
            chosen = row
            break
    failed = "; ".join(f"i = {r.horizon}: " + ", ".join(
        w for w, bad in (("unstable on P̂ (spectral radius %.4g)" % r.spectral_radius, not r.stable),
                         ("cancels a right-half-plane zero of P̂", r.cancels),
                         ("γ_min not settled" + ("" if np.isnan(r.change) else f" (changed {100 * r.change:.1f} %)"),
                          not r.settled)) if bad) for r in rows if not r.passes)
    model_note = f"P̂ of order {sid.order} by subspace identification (noise-floor criterion, i = {sid.horizon})"
    if chosen is not None:
        reason = (f"i = {chosen.horizon} is the smallest candidate whose design stabilises the data-based model "
                  f"{model_note}, cancels no right-half-plane zero of it, and whose γ_min = {chosen.gamma_min:.4g} "
                  f"changed by {100 * chosen.change:.1f} % ≤ {100 * settle_tol:g} % from the previous candidate"
                  + (f"; refused: {failed}" if failed else ""))
        ok = True
    else:
        stable = [r for r in rows if r.stable and not r.cancels]
        chosen = stable[-1] if stable else rows[-1]
        reason = (f"no candidate horizon passes all checks ({failed}); i = {chosen.horizon} is the largest "
                  + ("stable one" if stable else "candidate") + f" on the data-based model {model_note}: "
                  "collect more data (longer horizons) or revise the weights")
        ok = False
    return HorizonChoice(horizon=chosen.horizon, reason=reason, ok=ok, design=designs[chosen.horizon], model=P_hat,
                         model_order=sid.order, candidates=tuple(rows))
