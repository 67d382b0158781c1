"""Adaptive implementation of the subspace H∞ controller (thesis §5.3, Fig. 5.1, §6.3).

The controller ``K`` is the receding-horizon law (5.3)–(5.4), whose state is past data plus
weight-filter states; the ``Adapt`` block (:class:`AdaptiveHinf`) every ``period`` samples

1. pushes the new ``(u, y)`` pairs into a :class:`~synthesis.RecursivePredictor` (growing or
   sliding window, §2.3.1),
2. computes ``γ_min`` (3.8) of the latest predictor,
3. selects ``γ`` by a policy (:class:`GammaPolicy`: ``γ = (1 + α)γ_min`` or ``γ_min + α``),
4. computes new gains ``k1 … k4`` (5.1)–(5.2) and swaps them into ``K`` without
   transforming its state (:meth:`~synthesis.RecedingHorizonController.set_design`).

``K`` is then a linear time-varying system.  It has the step-by-step interface
``control(r_k) -> u_k`` / ``observe(u_k, y_k, r_k)`` used by
``experiments.simulate.closed_loop`` (and ``closed_loop_adaptive``).
"""
from __future__ import annotations

import time
import warnings
from dataclasses import dataclass

import numpy as np

from ._validation import DataError, as_signal, check_count, check_level, check_nonnegative
from .controller import RecedingHorizonController
from .exceptions import HorizonWarning
from .hinf import _design_from_plan, _map_plan, _predictor_parts, _warn_no_control
from .recursive import RecursivePredictor
from ._repr import result

__all__ = ["GammaPolicy", "AdaptiveUpdate", "AdaptiveHinf"]


@dataclass(frozen=True)
class GammaPolicy:
    """Rule choosing ``γ`` from the latest ``γ_min`` (§5.3).

    Attributes
    ----------
    kind : {"ratio", "offset"}
        ``"ratio"``: ``γ = (1 + α) γ_min`` (§5.3.1 suggests α = 0.1);
        ``"offset"``: ``γ = γ_min + α`` (§6.3 uses α = 0.6).
    alpha : float
        ``α > 0``.

    Examples
    --------
    A policy is called with ``γ_min`` and returns ``γ``; pass it as ``policy=`` to :class:`AdaptiveHinf` (or as
    ``gamma=`` to :func:`~synthesis.hinf_design`):

    >>> GammaPolicy()(2.0), GammaPolicy("offset", 0.6)(2.0)
    (2.2, 2.6)
    >>> GammaPolicy("offset", 0.0)
    Traceback (most recent call last):
        ...
    synthesis.exceptions.DataError: GammaPolicy alpha must be a finite number > 0, got 0.0
    """

    kind: str = "ratio"
    alpha: float = 0.1

    def __post_init__(self):
        if self.kind not in ("ratio", "offset"):
            raise DataError(f"GammaPolicy kind must be 'ratio' or 'offset', got {self.kind!r}")
        check_level(self.alpha, "GammaPolicy alpha")  # a bool (True) had passed as alpha = 1

    def __call__(self, gmin: float) -> float:
        gmin = check_nonnegative(gmin, "gamma_min")  # numbers only: float() had parsed "1"
        return (1.0 + self.alpha) * gmin if self.kind == "ratio" else gmin + self.alpha


@result
@dataclass(frozen=True)
class AdaptiveUpdate:
    """One design swapped into the controller.

    Attributes
    ----------
    step : int
        Number of samples the controller had observed when the design took effect (it is
        used from that sample on; 0 for the initial design).
    gamma_min, gamma : float
    seconds : float
        Wall-clock time of the update (predictor push, ``γ_min``, gains).
    n_columns : int
        Columns ``j`` of the data window behind the design.
    warnings : tuple of str
        Warnings raised while computing it (e.g. a rank-deficient window).
    cpu_seconds : float
        CPU time of the calling thread during the update (``time.thread_time``): the work
        itself, without the time the operating system gave to other processes (on a shared
        machine the wall time is this plus waiting).  Multi-threaded BLAS work in other
        threads is not included.
    phases : tuple of (str, float)
        Where :attr:`seconds` went: ``("push", s)`` (new samples into the recursive
        predictor), ``("predictor", s)`` (``L_w``, ``L_u`` from the Gram, §2.3.1) and
        ``("design", s)`` (performance map, ``γ_min``, policy and gains (5.1)–(5.2), and the
        horizon check).
    control_pvalue : float or None
        :attr:`Predictor.control_pvalue <synthesis.Predictor.control_pvalue>` of the window behind the design: above
        0.01 the data show no effect of the control over the horizon (a :class:`~synthesis.HorizonWarning`, raised
        once per run, see :class:`AdaptiveHinf`); ``None`` where it is not computed.
    """

    step: int
    gamma_min: float
    gamma: float
    seconds: float
    n_columns: int
    warnings: tuple = ()
    phases: tuple = ()
    cpu_seconds: float = float("nan")
    control_pvalue: float | None = None


class AdaptiveHinf:
    """Adaptive model-free subspace H∞ controller (Fig. 5.1).

    Parameters
    ----------
    predictor : RecursivePredictor
        Initialised with the experiment data (e.g. :meth:`RecursivePredictor.from_data`).
    W1, W2 : weights
        As for :func:`~synthesis.hinf_design` (discrete, relative degree 0).
    period : int
        Samples between updates (§6.3: 50).  A period longer than the run means no update.
    policy : GammaPolicy
        ``γ`` selection rule; default ``γ = 1.1 γ_min``.
    u_past, y_past : array_like, optional
        Data immediately before the first controlled sample (at least ``i`` samples), used
        to initialise the controller's past-data window (§5.1 comment 6); zeros otherwise.
    **design_kwargs
        Passed to :func:`~synthesis.hinf_design` (``causal=``, ``uncertainty=``, ``dt=``).  The
        weights are validated and their Toeplitz / observability blocks built once, here; each
        update computes only the predictor, the predictor terms of the performance map and the
        saddle point, so every design equals ``hinf_design(predictor, W1, W2, gamma=policy,
        **design_kwargs)`` on the same data window.  Its ``controller`` (``StateSpace``) is
        built only if read.

    Warns
    -----
    HorizonWarning
        Once per run, at the first design (the initial one or an update) whose data window shows no effect of the
        control over the horizon (:attr:`Predictor.control_pvalue <synthesis.Predictor.control_pvalue>` above 0.01,
        the check :func:`~synthesis.hinf_design` makes): the horizon is not longer than the plant's delay.  Every
        design's p-value is in :attr:`history` (:attr:`AdaptiveUpdate.control_pvalue`), and the warning text of
        each design that failed the check in its :attr:`AdaptiveUpdate.warnings`.  Once, not at each redesign nor at
        each change of verdict: on a window near the threshold the verdict can flip from one update to the next.
        On windows of closed-loop data alone the controller (its weight states, the reference) carries older data
        into ``u_k``, which the test can read as an effect: measured on ``0.5 z^-d / (1 − 0.7 z^-1)`` (sliding
        windows of 150 columns, 10 seeds), 88–96 % of the designs at ``i = d`` failed the check, 14 % at ``i = 1``
        below ``d = 2``.  The initial design, on the open-loop record, is the most telling.  A record spliced from
        two experiments (an integrating plant restarted from rest) fails the check as well, and so can a sliding
        window of closed-loop data at a horizon well above the delay (the servo at ``i = 8``, reference steps, noise
        0.05: 2 of 30 runs warned with a 150-column window, 3 of 270 updates; 0 of 30 with a growing window):
        there the window does not determine ``L_u``.
    PersistenceWarning, and any other
        The first warning of the run is raised once, the later ones are recorded in :attr:`history`.

    Attributes
    ----------
    controller : RecedingHorizonController
        The LTV controller ``K``.
    history : list of AdaptiveUpdate
        The initial design and every update.
    samples_seen : int
        Samples observed so far.

    Examples
    --------
    Start from a 200-sample excitation record of the plant ``y_k = 0.5 u_{k-1} + 0.2 u_{k-2}`` at ``i = 4``, a
    sliding window of 150 columns, a redesign every 20 samples and ``γ = γ_min + 0.6`` (§6.3):

    >>> import numpy as np
    >>> from synthesis import hinf_design, makeweight
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(200)
    >>> y = np.convolve(u, [0.0, 0.5, 0.2])[:200] + 0.01 * rng.standard_normal(200)
    >>> W1 = makeweight(10.0, (0.5, 1.0), 0.5, 0.1)
    >>> K = AdaptiveHinf.from_data(u, y, 4, W1, 0.1, period=20, window=150,
    ...                            policy=GammaPolicy("offset", 0.6), dt=0.1)

    Run it in closed loop as a :class:`~synthesis.RecedingHorizonController` (:meth:`control`, the plant,
    :meth:`observe`); every 20th :meth:`observe` pushes the new samples and swaps in new gains:

    >>> u_hist = list(u[-2:])
    >>> for k in range(60):
    ...     u_k = K.control()
    ...     y_k = 0.5 * u_hist[-1] + 0.2 * u_hist[-2] + 0.01 * rng.standard_normal()
    ...     K.observe(u_k, y_k, r_k=1.0)
    ...     u_hist.append(u_k[0])
    >>> [h.step for h in K.history], [h.n_columns for h in K.history]
    ([0, 20, 40, 60], [150, 150, 150, 150])
    >>> K.gamma_min_history.shape, bool(all(abs(h.gamma - h.gamma_min - 0.6) < 1e-9 for h in K.history))
    ((4, 2), True)

    The design in force is :func:`~synthesis.hinf_design` on the current window:

    >>> batch = hinf_design(K.recursive.predictor(), W1, 0.1, gamma=K.policy, dt=0.1)
    >>> bool(np.allclose(K.design.gain, batch.gain))
    True
    """

    def __init__(self, predictor: RecursivePredictor, W1, W2, *, period: int,
                 policy: GammaPolicy = GammaPolicy(), u_past=None, y_past=None, **design_kwargs):
        if not isinstance(predictor, RecursivePredictor):
            raise DataError("predictor must be a synthesis.RecursivePredictor (use RecursivePredictor.from_data)")
        check_count(period, "period (samples between redesigns)", 1)
        if not isinstance(policy, GammaPolicy):
            raise DataError("policy must be a synthesis.GammaPolicy")
        fixed = sorted({"gamma", "gamma_ratio"} & set(design_kwargs))
        if fixed:
            raise DataError(
                f"{', '.join(fixed)} cannot be passed to AdaptiveHinf: gamma follows gamma_min through the policy; "
                "use policy=GammaPolicy('ratio', alpha) or GammaPolicy('offset', alpha)")
        self.recursive = predictor
        self.W1, self.W2 = W1, W2
        self.period = int(period)
        self.policy = policy
        self._design_kwargs = dict(design_kwargs)
        self.samples_seen = 0
        self.history: list[AdaptiveUpdate] = []
        # samples observed since the last update, [u y] per row (grown by doubling)
        self._z_buf = np.empty((min(self.period, 256), predictor.m + predictor.l))
        self._n_buf = 0
        self._warned = False  # the first warning of the run was raised
        self._horizon_warned = False  # the HorizonWarning was raised (once per run)
        # the weights do not change between updates: validate them and build their Toeplitz /
        # observability blocks once (§5.3: only (Lw, Lu) change)
        rp = predictor
        self._plan = _map_plan(rp.horizon, rp.m, rp.l, W1, W2, **self._design_kwargs)
        design, record = self._design(step=0, t0=time.perf_counter(), c0=time.thread_time())
        self.controller = RecedingHorizonController(design)
        self.controller.reset(u_past, y_past)
        self.history.append(record)

    @classmethod
    def from_data(cls, u, y, horizon: int, W1, W2, *, period: int, window: int | None = None,
                  policy: GammaPolicy = GammaPolicy(), **design_kwargs) -> "AdaptiveHinf":
        """Initialise from an excitation record (§6.3: 6 s of white noise).

        The predictor is built from ``(u, y)`` (sliding ``window`` columns if given) and the
        controller's past-data window from the last ``i`` samples of the record.
        """
        u = as_signal(u, "u")
        y = as_signal(y, "y", n=u.shape[0])
        pred = RecursivePredictor.from_data(u, y, horizon, window=window)
        return cls(pred, W1, W2, period=period, policy=policy, u_past=u, y_past=y, **design_kwargs)

    # ------------------------------------------------------------------ adaptation
    def _design(self, step: int, t0: float, t_push: float = 0.0, c0: float | None = None):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            t1 = time.perf_counter()
            pred = self.recursive.predictor()
            t2 = time.perf_counter()
            Lw, Lu, *_ = _predictor_parts(pred)
            design = _design_from_plan(pred, Lw, Lu, self._plan, self.policy)
            # the horizon check of hinf_design, which this loop does not call (_design_from_plan is its engine)
            _warn_no_control(pred, stacklevel=1)
            p = pred.control_pvalue
        t3 = time.perf_counter()
        cpu = time.thread_time() - c0 if c0 is not None else float("nan")
        seconds = t3 - t0
        phases = (("push", t_push), ("predictor", t2 - t1), ("design", t3 - t2))
        msgs = tuple(f"{w.category.__name__}: {w.message}" for w in caught)
        self._raise_once(caught, msgs, step)
        record = AdaptiveUpdate(step=step, gamma_min=float(design.gamma_min), gamma=float(design.gamma),
                                seconds=seconds, n_columns=int(self.recursive.n_columns), warnings=msgs,
                                phases=phases, cpu_seconds=cpu, control_pvalue=None if p is None else float(p))
        return design, record

    def _raise_once(self, caught, msgs, step: int) -> None:
        """Raise the run's first warning, and its first :class:`HorizonWarning` (once per run: a verdict near the
        threshold may flip between updates); the rest are only recorded in :attr:`history`."""
        horizon = next((k for k, w in enumerate(caught) if issubclass(w.category, HorizonWarning)), None)
        shown = []
        if caught and not self._warned:
            self._warned = True
            shown.append(0)
        if horizon is not None and not self._horizon_warned:
            self._horizon_warned = True
            if horizon not in shown:
                shown.append(horizon)
        for k in shown:
            warnings.warn(
                f"adaptive update at step {step}: {msgs[k]} (further update warnings are only recorded in "
                "AdaptiveHinf.history)", caught[k].category, stacklevel=4)

    def update(self) -> AdaptiveUpdate:
        """Push the buffered samples into the predictor, recompute and swap in the gains now."""
        t0, c0 = time.perf_counter(), time.thread_time()
        if self._n_buf:
            # observe() stored the samples the controller validated (finite, right sizes)
            self.recursive._push_samples(self._z_buf[: self._n_buf])
            self._n_buf = 0
        design, record = self._design(step=self.samples_seen, t0=t0, t_push=time.perf_counter() - t0, c0=c0)
        self.controller.set_design(design)
        self.history.append(record)
        return record

    # ------------------------------------------------------------------ operation
    @property
    def design(self):
        """The design in force."""
        return self.controller.design

    def control(self, r_k=None) -> np.ndarray:
        """The control ``u_k`` (shape ``(m,)``) from the current gains."""
        return self.controller.control(r_k)

    def observe(self, u_k, y_k, r_k=None) -> None:
        """Record ``u_k``, measured ``y_k`` and ``r_k``; update the design every ``period`` samples."""
        self.controller.observe(u_k, y_k, r_k)  # validates u_k, y_k (finite, m and l values)
        m = self.recursive.m
        if self._n_buf == self._z_buf.shape[0]:
            self._z_buf = np.vstack([self._z_buf, np.empty_like(self._z_buf)])
        row = self._z_buf[self._n_buf]
        row[:m] = np.reshape(np.asarray(u_k, dtype=float), -1)
        row[m:] = np.reshape(np.asarray(y_k, dtype=float), -1)
        self._n_buf += 1
        self.samples_seen += 1
        if self.samples_seen % self.period == 0:
            self.update()

    def __repr__(self) -> str:
        d = self.design
        return (f"AdaptiveHinf(horizon={self.recursive.horizon}, m={self.recursive.m}, l={self.recursive.l}, "
                f"period={self.period}, policy={self.policy!r}, samples_seen={self.samples_seen}, "
                f"updates={len(self.history) - 1}, gamma={float(d.gamma):.6g}, gamma_min={float(d.gamma_min):.6g})")

    @property
    def gamma_min_history(self) -> np.ndarray:
        """``(step, γ_min)`` of every design, shape ``(n_updates + 1, 2)``."""
        return np.array([(h.step, h.gamma_min) for h in self.history])
