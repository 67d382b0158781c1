"""Open- and closed-loop simulation of discrete plants (thesis §5.4, Ch. 6, §7.4).

* :func:`collect_data` — open-loop experiment: the plant is driven by ``u`` plus
  process noise (injected at the plant input), and the measured output carries
  sensor noise (§5.4: σ = 0.05 each).
* :func:`closed_loop` — a plant under a controller, by an explicit time loop on the
  state-space matrices.  The controller is either

  - a discrete LTI python-control system with inputs ``[r; y]`` and output ``u``
    (the contract of ``synthesis.lti_controller`` / ``hinf_design(...).controller``),
    or with inputs ``e = r − y`` (a standard error-feedback ``u = K(r − y)``, e.g.
    ``synthesis.discrete_mixsyn(...).controller``); the two are told apart by the
    number of inputs (``2l`` or ``l``);
  - a step-by-step controller object with ``control(r_k) -> u_k`` and
    ``observe(u_k, y_k, r_k)`` (``synthesis.RecedingHorizonController``,
    ``synthesis.AdaptiveHinf``).

  An additive plant perturbation ``Δ`` (a second LTI system in parallel with the
  plant, Ch. 7) and process / sensor noise are optional.
* :func:`closed_loop_adaptive` — :func:`closed_loop` with an adaptive controller,
  also returning its ``γ_min(t)`` and ``γ(t)`` histories.
* :func:`closed_loop_system` — the same LTI loop as a python-control system ``r → [y; u]``
  (closed-loop poles, frequency responses).

Timing at sample ``k``: ``y_k = C x_k + D u_k`` is measured (plus sensor noise),
the controller computes ``u_k`` from its state and ``[r_k; y_k]`` (strictly proper
plants; a controller feedthrough from ``y`` with a non-strictly-proper plant is an
algebraic loop and is refused), then every state advances.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from synthesis.validation import DataError, as_discrete_system, as_real_array

__all__ = [
    "AlgebraicLoopError",
    "OpenLoopData",
    "ClosedLoopResult",
    "collect_data",
    "closed_loop",
    "closed_loop_adaptive",
    "closed_loop_system",
    "lsim",
]


class AlgebraicLoopError(ValueError):
    """Plant feedthrough ``D ≠ 0`` and controller feedthrough from ``y`` ``≠ 0``."""


@dataclass(frozen=True)
class OpenLoopData:
    """Open-loop experiment data (time along axis 0).

    Attributes
    ----------
    t : ndarray, shape (n,)
        Sample times ``k·dt``.
    u : ndarray, shape (n, m)
        Commanded input (what the experimenter records; the plant saw ``u + w``).
    y : ndarray, shape (n, l)
        Measured output (with sensor noise).
    y_clean : ndarray, shape (n, l)
        Plant output without sensor noise.
    dt : float
    x_final : ndarray
        Plant state after the last sample (to continue the experiment in closed loop,
        ``closed_loop(..., x0=data.x_final)``).
    """

    t: np.ndarray
    u: np.ndarray
    y: np.ndarray
    y_clean: np.ndarray
    dt: float
    x_final: np.ndarray | None = None


@dataclass(frozen=True)
class ClosedLoopResult:
    """Closed-loop simulation result (time along axis 0; plots as ``plt.plot(res.t, res.y)``).

    Attributes
    ----------
    t : ndarray, shape (n,)
    r : ndarray, shape (n, l)
        Reference.
    y : ndarray, shape (n, l)
        Plant output (without sensor noise).
    u : ndarray, shape (n, m)
        Control applied (before process noise).
    y_measured : ndarray, shape (n, l)
        Output fed back to the controller (``y`` plus sensor noise).
    dt : float
    gamma_min, gamma : ndarray, shape (n,), optional
        Adaptive runs: ``γ_min`` and ``γ`` of the design in force at each sample.
    update_steps : ndarray of int, optional
        Adaptive runs: samples at which a new design was swapped in.
    update_seconds : ndarray, optional
        Adaptive runs: wall-clock seconds each update took.
    """

    t: np.ndarray
    r: np.ndarray
    y: np.ndarray
    u: np.ndarray
    y_measured: np.ndarray
    dt: float
    gamma_min: np.ndarray | None = None
    gamma: np.ndarray | None = None
    update_steps: np.ndarray | None = field(default=None)
    update_seconds: np.ndarray | None = field(default=None)

    @property
    def e(self) -> np.ndarray:
        """Tracking error ``r − y``."""
        return self.r - self.y


# ---------------------------------------------------------------------------
def _dt(sys) -> float:
    return 1.0 if sys.dt is True else float(sys.dt)


def _check_same_dt(a, b, what: str) -> None:
    if a.dt is True or b.dt is True:
        return
    if not np.isclose(float(a.dt), float(b.dt), rtol=1e-9, atol=0.0):
        raise DataError(f"{what}: sample times differ ({a.dt} vs {b.dt}); use one sample time")


def _signal(x, name: str, width: int, n: int | None = None) -> np.ndarray:
    arr = as_real_array(x, name)  # text or complex samples had raised numpy's ValueError or TypeError
    if arr.ndim == 1:
        arr = arr[:, None]
    if arr.ndim != 2 or arr.shape[0] == 0:
        raise DataError(f"{name} must have shape (n,) or (n, {width}) with time along axis 0, got {np.shape(x)}")
    if arr.shape[1] != width:
        raise DataError(f"{name} has {arr.shape[1]} channel(s), the system needs {width}")
    if n is not None and arr.shape[0] != n:
        raise DataError(f"{name} has {arr.shape[0]} samples, expected {n}")
    if not np.all(np.isfinite(arr)):
        raise DataError(f"{name} contains NaN or infinite values")
    return arr


def _noise(rng, sigma, n: int, width: int, name: str) -> np.ndarray:
    sigma = float(sigma)
    if not np.isfinite(sigma) or sigma < 0:
        raise DataError(f"{name} standard deviation must be >= 0, got {sigma!r}")
    if sigma == 0:
        return np.zeros((n, width))
    return sigma * rng.standard_normal((n, width))


def _plant_matrices(plant, perturbation):
    """``(A, B, C, D)`` of ``plant + perturbation`` (parallel connection, shared input)."""
    P = as_discrete_system(plant, "plant")
    A, B, C, D = (np.asarray(M, float) for M in (P.A, P.B, P.C, P.D))
    if perturbation is not None:
        Dl = as_discrete_system(perturbation, "perturbation")
        _check_same_dt(P, Dl, "plant and perturbation")
        if (Dl.ninputs, Dl.noutputs) != (P.ninputs, P.noutputs):
            raise DataError(
                f"perturbation must have the plant's size ({P.noutputs}x{P.ninputs}), got {Dl.noutputs}x{Dl.ninputs}")
        n1, n2 = A.shape[0], Dl.nstates
        A = np.block([[A, np.zeros((n1, n2))], [np.zeros((n2, n1)), np.asarray(Dl.A, float)]])
        B = np.vstack([B, np.asarray(Dl.B, float)])
        C = np.hstack([C, np.asarray(Dl.C, float)])
        D = D + np.asarray(Dl.D, float)
    return P, A, B, C, D


def _initial_state(x0, n: int, name: str) -> np.ndarray:
    if x0 is None:
        return np.zeros(n)
    x = np.asarray(x0, dtype=float).reshape(-1)
    if x.size != n or not np.all(np.isfinite(x)):
        raise DataError(f"{name} must be {n} finite values, got shape {np.shape(x0)}")
    return x.copy()


# ---------------------------------------------------------------------------
def collect_data(plant, u, *, process_noise: float = 0.0, sensor_noise: float = 0.0,
                 seed=None, x0=None) -> OpenLoopData:
    """Open-loop experiment: ``y = P (u + w) + v`` (§5.4).

    Parameters
    ----------
    plant : control.StateSpace or TransferFunction
        Discrete plant.
    u : array_like, shape (n,) or (n, m)
        Excitation (e.g. :func:`experiments.signals.prbs`).
    process_noise, sensor_noise : float
        Standard deviations of the white Gaussian noises ``w`` (added to the plant
        input) and ``v`` (added to the measured output).
    seed : int or numpy Generator, optional
        Seeds the noises (process noise is drawn first, then sensor noise).
    x0 : array_like, optional
        Initial plant state (default 0).

    Returns
    -------
    OpenLoopData

    Examples
    --------
    >>> import numpy as np
    >>> import control
    >>> from experiments import prbs, servo
    >>> P = servo()
    >>> data = collect_data(P, prbs(100, seed=0), sensor_noise=0.05, seed=1)
    >>> data.u.shape, data.y.shape, data.dt, data.x_final.shape
    ((100, 1), (100, 1), 0.1, (2,))
    >>> round(float(np.std(data.y - data.y_clean)), 2)             # the sensor noise v
    0.04
    >>> clean = collect_data(P, np.ones(5))                        # noise-free: a plain simulation
    >>> bool(np.allclose(clean.y[:, 0], control.forced_response(P, U=np.ones(5)).outputs))
    True
    """
    P, A, B, C, D = _plant_matrices(plant, None)
    u = _signal(u, "u", P.ninputs)
    n = u.shape[0]
    rng = np.random.default_rng(seed)
    w = _noise(rng, process_noise, n, P.ninputs, "process_noise")
    v = _noise(rng, sensor_noise, n, P.noutputs, "sensor_noise")
    x = _initial_state(x0, A.shape[0], "x0")
    y, x = lsim(A, B, C, D, u + w, x)
    dt = _dt(P)
    return OpenLoopData(t=np.arange(n) * dt, u=u, y=y + v, y_clean=y, dt=dt, x_final=x)


def lsim(A, B, C, D, u, x0, *, route: str = "slicot"):
    """``y_k = C x_k + D u_k``, ``x_{k+1} = A x_k + B u_k``: ``(y, x_n)`` with time along axis 0.

    The simulation under :func:`collect_data`, on plain arrays (no checks: the callers pass float arrays of
    matching shapes).

    Parameters
    ----------
    A, B, C, D : ndarray
        Discrete state-space matrices (``nx × nx``, ``nx × m``, ``p × nx``, ``p × m``).
    u : ndarray, shape (n, m)
        Inputs, time along axis 0.
    x0 : array_like, shape (nx,)
        Initial state.
    route : {"slicot", "loop"}, optional
        ``"slicot"``: SLICOT TF01MD (``slycot.tf01md``), one compiled loop; ``"loop"``: the former Python
        loop, kept as the measured reference of the ``bench-norms`` comparison. Both give the same result
        to rounding.

    Returns
    -------
    y : ndarray, shape (n, p)
        Outputs.
    x_n : ndarray, shape (nx,)
        The state after the last sample.

    Examples
    --------
    >>> import numpy as np
    >>> from experiments import lsim
    >>> A, B, C, D = np.array([[0.5]]), np.array([[1.0]]), np.array([[1.0]]), np.array([[0.0]])
    >>> y, x = lsim(A, B, C, D, np.ones((4, 1)), np.zeros(1))
    >>> y.ravel().tolist(), x.tolist()
    ([0.0, 1.0, 1.5, 1.75], [1.875])
    >>> np.allclose(lsim(A, B, C, D, np.ones((4, 1)), np.zeros(1), route="loop")[0], y)
    True
    """
    n, m = u.shape
    nx, p = A.shape[0], C.shape[0]
    if route == "slicot" and nx > 0 and n > 0:
        import slycot

        xf, y = slycot.tf01md(nx, m, p, n, A, B, C, D, np.asfortranarray(u.T), np.array(x0, float))
        return np.ascontiguousarray(np.asarray(y).T), np.asarray(xf, float)
    if nx == 0:
        return u @ D.T, np.zeros(0)
    x = np.array(x0, float)
    y = np.empty((n, p))
    for k in range(n):
        y[k] = C @ x + D @ u[k]
        x = A @ x + B @ u[k]
    return y, x


def closed_loop(plant, controller, r, *, perturbation=None, process_noise: float = 0.0,
                sensor_noise: float = 0.0, seed=None, x0=None, xc0=None) -> ClosedLoopResult:
    """Simulate ``plant`` (plus an optional additive ``perturbation``) under ``controller``.

    Parameters
    ----------
    plant : control.StateSpace or TransferFunction
        Discrete plant ``P`` (``m`` inputs, ``l`` outputs).
    controller : control.StateSpace / TransferFunction, or object
        Discrete LTI controller with inputs ``[r; y]`` (``2l``) or ``e = r − y``
        (``l``) and ``m`` outputs, same sample time as the plant; or an object with
        ``control(r_k) -> u_k`` and ``observe(u_k, y_k, r_k)`` (e.g.
        ``synthesis.RecedingHorizonController`` or ``synthesis.AdaptiveHinf``), which
        is advanced in place.
    r : array_like, shape (n,) or (n, l)
        Reference.
    perturbation : control.StateSpace, optional
        Additive uncertainty ``Δ``: the true plant is ``P + Δ`` (Ch. 7 robustness check).
    process_noise, sensor_noise : float
        Standard deviations of white Gaussian noise added to the plant input and to the
        measured output.
    seed : int or numpy Generator, optional
        Seeds the noises.
    x0 : array_like, optional
        Initial state of the plant (followed by that of ``Δ``), default 0.
    xc0 : array_like, optional
        Initial state of an LTI controller, default 0.

    Returns
    -------
    ClosedLoopResult

    Raises
    ------
    AlgebraicLoopError
        If ``P + Δ`` has a feedthrough and the LTI controller a feedthrough from ``y``.
    ValueError
        On continuous-time systems, mismatched sizes or sample times, NaN input.

    Examples
    --------
    >>> import numpy as np
    >>> import control
    >>> from experiments import servo, step
    >>> P = servo()
    >>> K = control.ss([], [], [], [[2.0]], P.dt)                  # u = 2(r − y), error feedback
    >>> res = closed_loop(P, K, step(200))
    >>> res.y.shape, res.u.shape, round(float(res.y[-1, 0]), 3)    # the integrator tracks the step
    ((200, 1), (200, 1), 1.0)
    >>> K_ry = control.ss([], [], [], [[2.0, -2.0]], P.dt)         # the same law with inputs [r; y]
    >>> bool(np.allclose(closed_loop(P, K_ry, step(200)).y, res.y))
    True
    """
    P, A, B, C, D = _plant_matrices(plant, perturbation)
    m, l = P.ninputs, P.noutputs
    r = _signal(r, "r", l)
    n = r.shape[0]
    rng = np.random.default_rng(seed)
    w = _noise(rng, process_noise, n, m, "process_noise")
    v = _noise(rng, sensor_noise, n, l, "sensor_noise")
    x = _initial_state(x0, A.shape[0], "x0")
    y = np.empty((n, l))
    ym = np.empty((n, l))
    u = np.empty((n, m))
    plant_ft = bool(np.any(D != 0))

    if hasattr(controller, "control") and hasattr(controller, "observe"):
        for k in range(n):
            u[k] = np.asarray(controller.control(r[k]), float).reshape(m)
            y[k] = C @ x + D @ (u[k] + w[k])
            ym[k] = y[k] + v[k]
            controller.observe(u[k], ym[k], r[k])
            x = A @ x + B @ (u[k] + w[k])
    else:
        Ac, Br, By, Cc, Dr, Dy = _controller_parts(P, controller)
        if plant_ft and np.any(Dy != 0):
            raise AlgebraicLoopError(
                "algebraic loop: the plant (plus perturbation) has a feedthrough D != 0 and the controller a "
                "feedthrough from y; use a strictly proper plant or a strictly proper controller")
        xc = _initial_state(xc0, Ac.shape[0], "xc0")
        for k in range(n):
            if plant_ft:  # controller has no feedthrough from y: u first
                u[k] = Cc @ xc + Dr @ r[k]
                y[k] = C @ x + D @ (u[k] + w[k])
                ym[k] = y[k] + v[k]
            else:
                y[k] = C @ x
                ym[k] = y[k] + v[k]
                u[k] = Cc @ xc + Dr @ r[k] + Dy @ ym[k]
            xc = Ac @ xc + Br @ r[k] + By @ ym[k]
            x = A @ x + B @ (u[k] + w[k])
    dt = _dt(P)
    return ClosedLoopResult(t=np.arange(n) * dt, r=r, y=y, u=u, y_measured=ym, dt=dt)


def _controller_parts(P, controller):
    """``(A_K, B_r, B_y, C_K, D_r, D_y)`` of an LTI controller ``u = C_K x_K + D_r r + D_y y``.

    Inputs ``[r; y]`` (``2l``, the subspace controllers (5.3)–(5.4)) or ``e = r − y`` (``l``,
    error feedback: ``B_y = −B_r``, ``D_y = −D_r``); ``m`` outputs and the plant's sample time.
    """
    m, l = P.ninputs, P.noutputs
    K = as_discrete_system(controller, "controller")
    _check_same_dt(P, K, "plant and controller")
    if K.noutputs != m:
        raise DataError(f"controller has {K.noutputs} output(s), the plant {m} input(s)")
    n = K.nstates
    Ac, Bc, Cc, Dc = (np.asarray(M, float).reshape(shape) for M, shape in
                      ((K.A, (n, n)), (K.B, (n, K.ninputs)), (K.C, (m, n)), (K.D, (m, K.ninputs))))
    if K.ninputs == 2 * l:
        return Ac, Bc[:, :l], Bc[:, l:], Cc, Dc[:, :l], Dc[:, l:]
    if K.ninputs == l:  # error feedback u = K (r − y)
        return Ac, Bc, -Bc, Cc, Dc, -Dc
    raise DataError(f"controller must have inputs [r; y] ({2 * l}) or e = r - y ({l}); it has {K.ninputs}")


def closed_loop_system(plant, controller):
    """The LTI closed loop ``r → [y; u]`` of ``plant`` under an LTI ``controller``, as a StateSpace.

    Same loop as :func:`closed_loop` (state ``[x; x_K]``): ``y = C_p x + D_p u`` and
    ``u = C_K x_K + D_r r + D_y y``, solved for ``u = F (D_y C_p x + C_K x_K + D_r r)`` with
    ``F = (I − D_y D_p)⁻¹``.  Its poles decide closed-loop stability independently of a time
    simulation (spectral radius of ``.A`` below 1).

    Parameters
    ----------
    plant : control.StateSpace or TransferFunction
        Discrete plant (``m`` inputs, ``l`` outputs); a feedthrough ``D_p`` is allowed.
    controller : control.StateSpace or TransferFunction
        Inputs ``[r; y]`` (``2l``) or ``e = r − y`` (``l``), ``m`` outputs, same sample time.

    Raises
    ------
    AlgebraicLoopError
        ``I − D_y D_p`` singular (the loop is not well posed).
    ValueError
        Sizes or sample times that do not fit.

    Examples
    --------
    >>> import numpy as np
    >>> import control
    >>> from experiments import servo, step
    >>> P = servo()
    >>> K = control.ss([], [], [], [[2.0]], P.dt)                  # u = 2(r − y), error feedback
    >>> T = closed_loop_system(P, K)                               # r → [y; u]
    >>> T.ninputs, T.noutputs, T.nstates, bool(max(abs(T.poles())) < 1)
    (1, 2, 2, True)
    >>> yu = control.forced_response(T, U=np.ones(200)).outputs
    >>> res = closed_loop(P, K, step(200))                         # the same loop, simulated
    >>> bool(np.allclose(yu[0], res.y[:, 0]) and np.allclose(yu[1], res.u[:, 0]))
    True
    """
    import control

    P = as_discrete_system(plant, "plant")
    Ap, Bp, Cp, Dp = (np.asarray(M, float).reshape(shape) for M, shape in
                      ((P.A, (P.nstates, P.nstates)), (P.B, (P.nstates, P.ninputs)),
                       (P.C, (P.noutputs, P.nstates)), (P.D, (P.noutputs, P.ninputs))))
    Ak, Br, By, Ck, Dr, Dy = _controller_parts(P, controller)
    I_DD = np.eye(P.ninputs) - Dy @ Dp
    if np.linalg.cond(I_DD) > 1e12:
        raise AlgebraicLoopError("the loop is not well posed: I − D_y D_p is singular; make the plant or the "
                                 "controller's y-feedthrough strictly proper")
    F = np.linalg.inv(I_DD)
    Ux, Uk, Ur = F @ Dy @ Cp, F @ Ck, F @ Dr  # u = Ux x + Uk x_K + Ur r
    Yx, Yk, Yr = Cp + Dp @ Ux, Dp @ Uk, Dp @ Ur  # y = Yx x + Yk x_K + Yr r
    A = np.block([[Ap + Bp @ Ux, Bp @ Uk], [By @ Yx, Ak + By @ Yk]])
    B = np.vstack([Bp @ Ur, Br + By @ Yr])
    C = np.block([[Yx, Yk], [Ux, Uk]])
    D = np.vstack([Yr, Ur])
    return control.ss(A, B, C, D, P.dt)


def closed_loop_adaptive(plant, adaptive, r, **kwargs) -> ClosedLoopResult:
    """Closed loop with an adaptive controller (§5.3, §6.3), keeping its ``γ`` history.

    The measured plant output feeds both the controller state and the predictor
    update (``adaptive.observe``).  Takes the keyword arguments of :func:`closed_loop`;
    to continue right after the excitation experiment that initialised the controller
    (§6.3), pass ``x0=data.x_final``.

    Parameters
    ----------
    plant : control.StateSpace
    adaptive : synthesis.AdaptiveHinf
        Advanced in place; its history is read after the run.
    r : array_like, shape (n,) or (n, l)

    Returns
    -------
    ClosedLoopResult
        With ``gamma_min``, ``gamma`` (design in force at each sample of this run),
        ``update_steps`` (samples of this run at which a new design was swapped in) and
        ``update_seconds``.

    Examples
    --------
    The §5.3 controller on the servo, initialised by a 200-sample experiment, updated every 50 samples:

    >>> import numpy as np
    >>> import control
    >>> import synthesis as sy
    >>> from experiments import prbs, servo, step_sequence
    >>> P = servo()
    >>> s = control.tf("s")
    >>> W1 = sy.tustin(100 * (0.01 / 5) * (s + 5) / (s + 0.01), P.dt)
    >>> W2 = sy.tustin(0.05 * (10 / 0.5) * (s + 0.5) / (s + 10), P.dt)
    >>> data = collect_data(P, prbs(200, seed=0), process_noise=0.05, sensor_noise=0.05, seed=1)
    >>> ad = sy.AdaptiveHinf.from_data(data.u, data.y, 15, W1, W2, period=50)
    >>> r = step_sequence(120, [1.0, -1.0], 60)
    >>> res = closed_loop_adaptive(P, ad, r, x0=data.x_final, sensor_noise=0.05, seed=2)
    >>> res.update_steps.tolist(), bool(np.all(res.gamma > res.gamma_min))
    ([50, 100], True)
    >>> bool(np.all(np.abs(res.y[50:60, 0] - 1.0) < 0.1))          # tracking the first step
    True
    """
    for attr in ("control", "observe", "history"):
        if not hasattr(adaptive, attr):
            raise DataError(f"adaptive controller needs a {attr!r} attribute (use synthesis.AdaptiveHinf)")
    start = adaptive.samples_seen
    n_updates_before = len(adaptive.history)
    res = closed_loop(plant, adaptive, r, **kwargs)
    n = res.t.shape[0]
    hist = adaptive.history
    gmin = np.empty(n)
    gam = np.empty(n)
    # design in force at each sample: the last update recorded at or before it
    steps = np.array([h.step for h in hist])
    for k in range(n):
        idx = np.searchsorted(steps, start + k, side="right") - 1
        gmin[k] = hist[idx].gamma_min if idx >= 0 else np.nan
        gam[k] = hist[idx].gamma if idx >= 0 else np.nan
    new = hist[n_updates_before:]
    return ClosedLoopResult(
        t=res.t, r=res.r, y=res.y, u=res.u, y_measured=res.y_measured, dt=res.dt,
        gamma_min=gmin, gamma=gam,
        update_steps=np.array([h.step - start for h in new], dtype=int),
        update_seconds=np.array([h.seconds for h in new]),
    )
