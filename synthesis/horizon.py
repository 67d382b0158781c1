"""The prediction horizon ``i`` chosen from the data, by a stated rule that explains itself.

The horizon is the one design choice of the model-free method (§5.4) without a formula: too short and the
finite-horizon game can destabilise a non-minimum-phase plant or miss a slow mode (the closed loop is unstable
on the true plant although every finite-horizon bound holds); longer costs data and time.  The rule of
:func:`choose_horizon`:

1. a **data-based model** ``P̂`` is identified once, by :func:`~synthesis.subspace_id` (noise-floor order)
   at the largest candidate horizon; two more models of the same order are identified from the first and
   the second half of the record (the **split models**);
2. for each candidate ``i`` in increasing order the nominal design (:func:`~synthesis.hinf_design`,
   ``γ = gamma_ratio·γ_min``) is computed from the predictor of horizon ``i``, and four checks run:

   * **stable on P̂**: the LTI controller (5.3)–(5.4) stabilises ``P̂`` (closed-loop spectral radius
     ``ρ̂ < 1``);
   * **margin clears the split spread**: ``1 − ρ̂`` exceeds ``max |ρ_h − ρ̂|``, ``ρ_h`` the spectral radius
     of the same controller's loop with each split model.  The split models differ from ``P̂`` by about
     the sampling error of ``P̂`` itself (each half has half the data), so the spread is the change of
     ``ρ`` a model error of the size the record shows produces; a margin smaller than that is one the
     data cannot vouch for;
   * **no cancelled right-half-plane zero**: no pole of the controller lies within ``cancel_tol·|ζ|``
     of a zero ``ζ`` of ``P̂`` outside the unit circle (such a loop is internally unstable however
     well its input-output maps look; a guard, since in our measurements the short-horizon designs on
     the non-minimum-phase plant were caught by the stability check: a closed-loop real pole near
     1.17 at i = 20, none of the controller's poles on the zero);
   * **γ_min settled**: ``|γ_min(i) − γ_min(i_prev)| ≤ settle_tol·γ_min(i)``, ``i_prev`` the previous
     candidate (γ_min stopped moving between two candidates: a sign, not a proof, that the finite-horizon
     level is near its ∞-horizon value);

3. the **smallest** ``i`` passing all four is returned.  If none does, the largest candidate stable on ``P̂``
   without a cancellation (else the largest candidate) is returned with ``ok = False`` and the reason.  A record
   whose halves are too short to identify a model of ``P̂``'s order fails the margin check (the reason says how
   many samples would do).

What the checks are **not**: a statement about the true plant.  They are computed on ``P̂`` and the split
models only, and are neither necessary nor sufficient for a stable loop on the plant (measured on the
three-disk plant, ``experiments compare`` records: a loop with ``ρ̂ = 0.99965`` was unstable on the plant,
``ρ = 1.0018``, and one with ``ρ̂ = 1.047`` stable, ``ρ = 0.9998``).  The split spread is one sample of a
sampling error, an estimate and not a bound, and an error common to both halves (a too-low order, dynamics the
record does not excite) does not show in it: on records made as ``compare`` makes them (servo, resonant,
non-minimum-phase, third-order, three-disk y1 and y3 plants; 5 seeds, 2 lengths, γ = 1.1 and 1.35 γ_min; 960
candidate designs) ``|ρ − ρ̂| ≤ spread`` held for 75 % of the three-disk designs and 55 % of the others.  For a
certificate use :func:`unfalsify.robust_design_from_data`.
"""
from __future__ import annotations

import numbers
import warnings
from dataclasses import dataclass

import control
import numpy as np

from ._repr import result
from ._validation import DataError, as_signal, check_level, check_sample_time
from .exceptions import HorizonChoiceWarning
from .hinf import HinfDesign, hinf_design
from .predictor import PersistenceWarning, fit_predictor
from .subspace_id import subspace_id

__all__ = ["HorizonCandidate", "HorizonChoice", "choose_horizon"]

#: candidate horizons of :func:`choose_horizon` (those the record supports are tried)
DEFAULT_HORIZONS = (10, 15, 20, 30, 40, 50, 60, 80)


@result
@dataclass(frozen=True, eq=False)
class HorizonCandidate:
    """One horizon tried by :func:`choose_horizon`; every check is on the data-based models, none on the plant.

    Attributes
    ----------
    horizon : int
    gamma_min : float
        γ_min of the design at this horizon.
    change : float
        ``|γ_min(i) − γ_min(i_prev)| / γ_min(i)`` (``nan`` for the first candidate).
    spectral_radius : float
        ``ρ̂``: of the loop of the design's controller with the data-based model ``P̂``.
    stable : bool
        ``ρ̂ < 1``: the loop with ``P̂`` (not with the plant) is stable.
    cancels : bool
        A right-half-plane zero of ``P̂`` is cancelled by a controller pole.
    settled : bool
        γ_min changed by at most ``settle_tol`` from the previous candidate.
    split_radii : tuple of float
        Spectral radii of the same controller's loop with the models of the record's first and second half
        (empty when the record is too short to split).
    spread : float
        ``max |ρ_h − ρ̂|`` over ``split_radii`` (``inf`` when there are none).
    margin_clear : bool
        ``1 − ρ̂ > spread``: the loop's margin on ``P̂`` is larger than the change a model error of the size
        the record shows produced (module docstring).
    """

    horizon: int
    gamma_min: float
    change: float
    spectral_radius: float
    stable: bool
    cancels: bool
    settled: bool
    split_radii: tuple = ()
    spread: float = float("inf")
    margin_clear: bool = False

    @property
    def passes(self) -> bool:
        """All four checks hold (on ``P̂`` and the split models; nothing is checked on the plant)."""
        return bool(self.stable and self.margin_clear and not self.cancels and self.settled)


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
        True when the chosen ``i`` passes all four checks — on the data-based model ``P̂`` and the split
        models.  Not a statement that the loop is stable on the plant (see :attr:`assumptions`).
    design : HinfDesign
        The nominal design at ``horizon`` (on the whole record).
    model : control.StateSpace
        The data-based model ``P̂`` the checks used.
    model_order : int
        Its order (noise-floor criterion).
    candidates : tuple of HorizonCandidate
        Every horizon tried, in order (the scan stops at the first that passes).
    split_models : tuple of control.StateSpace
        The models of the record's first and second half (order ``model_order``) behind the margin check;
        empty when the record is too short to split.
    assumptions : str
        What the verdict rests on, in words: the models the checks used and what they do not show.
    """

    horizon: int
    reason: str
    ok: bool
    design: HinfDesign
    model: control.StateSpace
    model_order: int
    candidates: tuple
    split_models: tuple = ()
    assumptions: str = ""


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


def _split_models(u, y, horizon, order, dt, ratio):
    """Models of order ``order`` from each half of the record, at the largest horizon ``≤ horizon`` that a half
    supports (``ratio`` Hankel columns per regressor); ``()`` and the samples needed when a half is too short."""
    n, m = u.shape
    l = y.shape[1]
    half = n // 2
    ratio = max(ratio, 1.0)                                 # subspace_id's own minimum
    h = min(horizon, int((half + 1) // (2 + ratio * (2 * m + l))))
    if h * l <= order:
        h_need = order // l + 1
        return (), h, int(np.ceil(2 * (ratio * h_need * (2 * m + l) + 2 * h_need - 1)))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PersistenceWarning)
        models = tuple(subspace_id(u[s], y[s], h, order=order, dt=dt).model
                       for s in (slice(0, half), slice(half, 2 * half)))
    return models, h, None


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
        See ``horizons``; also the split models' horizon is the largest ``≤`` that of ``P̂`` with this many
        columns per regressor in half the record.

    Returns
    -------
    HorizonChoice
        ``.horizon``, ``.reason``, ``.ok``, the design at that horizon, every candidate's checks, the models
        they used and ``.assumptions``.  ``ok`` says the checks on the data's models passed, not that the loop
        is stable on the plant.

    Raises
    ------
    DataError
        Bad data or weights; fewer than two candidate horizons fit the record (collect more data or
        pass smaller ``horizons``); bad tolerances.

    Warns
    -----
    HorizonChoiceWarning
        When no candidate passes (``ok`` False): the returned design is a fallback, with the reason.

    Examples
    --------
    The non-minimum-phase plant ``2(1 − s)/((s + 1)(s + 2))`` at 10 Hz with the §5.4 weights: short
    horizons are refused (their designs destabilise ``P̂``, or γ_min has not settled):

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
    >>> print(choice.assumptions)  # doctest: +ELLIPSIS
    Every check is on data-based models, none on the plant: ... may be unstable on the plant; ...
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
        second = cand[min(1, len(cand) - 1)]
        need = int(np.ceil(min_column_ratio * second * (2 * m + l))) + 2 * second
        raise DataError(f"only {len(fits)} of the candidate horizons {cand} fit {n} samples "
                        f"(j ≥ {min_column_ratio:g}·i(2m+l) Hankel columns): collect at least {need} samples or "
                        "pass smaller horizons")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PersistenceWarning)
        sid = subspace_id(u, y, min(fits[-1], 64), dt=dt)
    P_hat = sid.model
    split, split_h, split_need = _split_models(u, y, sid.horizon, sid.order, dt, min_column_ratio)
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
        radii = tuple(_loop_radius(M, design.controller, l) for M in split)
        spread = max((abs(r - rho) for r in radii), default=float("inf"))
        row = HorizonCandidate(horizon=h, gamma_min=g, change=change, spectral_radius=rho, stable=rho < 1.0,
                               cancels=_cancels(P_hat, design.controller, cancel_tol),
                               settled=bool(prev is not None and change <= settle_tol),
                               split_radii=radii, spread=spread, margin_clear=bool(1.0 - rho > spread))
        rows.append(row)
        prev = g
        if row.passes:
            chosen = row
            break
    split_note = (f"the record is too short to split: halves of {n // 2} samples do not identify a model of order "
                  f"{sid.order} (collect at least {split_need} samples)" if not split else "")
    failed = "; ".join(f"i = {r.horizon}: " + ", ".join(
        w for w, bad in (("unstable on P̂ (spectral radius %.4g)" % r.spectral_radius, not r.stable),
                         ("margin on P̂ not clear of the split spread" + (
                             f" (1 − ρ̂ = {1 - r.spectral_radius:.2g} ≤ {r.spread:.2g})" if split else ""),
                          r.stable and not r.margin_clear),
                         ("cancels a right-half-plane zero of P̂", r.cancels),
                         ("γ_min not settled" + ("" if np.isnan(r.change) else f" (changed {100 * r.change:.1f} %)"),
                          not r.settled)) if bad) for r in rows if not r.passes)
    model_note = f"P̂ of order {sid.order} by subspace identification (noise-floor criterion, i = {sid.horizon})"
    if chosen is not None:
        reason = (f"i = {chosen.horizon} is the smallest candidate whose design stabilises the data-based model "
                  f"{model_note} with a margin 1 − ρ̂ = {1 - chosen.spectral_radius:.2g} above the spread "
                  f"{chosen.spread:.2g} of ρ over the models of the record's two halves, cancels no right-half-plane "
                  f"zero of P̂, and whose γ_min = {chosen.gamma_min:.4g} changed by {100 * chosen.change:.1f} % ≤ "
                  f"{100 * settle_tol:g} % from the previous candidate (checks on the data's models, not on the "
                  "plant)" + (f"; refused: {failed}" if failed else ""))
        ok = True
    else:
        stable = [r for r in rows if r.stable and not r.cancels]
        chosen = stable[-1] if stable else rows[-1]
        reason = (f"no candidate horizon passes all checks ({failed}"
                  + (f"; {split_note}" if split_note else "") + f"); i = {chosen.horizon} is the largest "
                  + ("one stable" if stable else "candidate, none being stable") + f" on the data-based model "
                  f"{model_note}: collect more data (longer horizons) or revise the weights")
        ok = False
        warnings.warn(f"choose_horizon: {reason}", HorizonChoiceWarning, stacklevel=2)
    assumptions = (f"Every check is on data-based models, none on the plant: P̂ (order {sid.order}, subspace "
                   f"identification of all {n} samples at i = {sid.horizon}) stands in for the plant, and "
                   + (f"the spread of the loop's spectral radius over two models of the same order from the record's "
                      f"halves ({n // 2} samples each, i = {split_h}) stands in for the effect of P̂'s error (one "
                      "split: an estimate, not a bound, blind to errors common to both halves)"
                      if split else f"the margin check could not run: {split_note}")
                   + ". A loop that passes may be unstable on the plant; for a certificate use "
                   "unfalsify.robust_design_from_data.")
    return HorizonChoice(horizon=chosen.horizon, reason=reason, ok=ok, design=designs[chosen.horizon], model=P_hat,
                         model_order=sid.order, candidates=tuple(rows), split_models=split, assumptions=assumptions)
