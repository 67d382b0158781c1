"""Servo design-example pieces shared by ``design-example``, ``chapter7`` and ``demo`` (thesis §5.4).

* the four §5.4 weights (the OCR'd ``0.01/s`` read as ``0.01/5``: the factor that makes W1 100 at DC), Tustin at 10 Hz;
* the one noisy open-loop data set (PRBS ±1, process noise at the plant input, sensor noise);
* closed-loop step responses with a stability verdict taken from the closed-loop
  eigenvalues (an independent route from the time simulation) and step metrics;
* step-response plotting that keeps diverging responses from blowing up the axes.
"""
from __future__ import annotations

import contextlib
import warnings
from dataclasses import asdict, dataclass

import control
import numpy as np

from synthesis import DataError, tustin

from .plants import SERVO_DT, servo
from .signals import prbs, step
from .simulate import closed_loop, closed_loop_system, collect_data

__all__ = [
    "DESIGNS",
    "THESIS_TABLE_5_1",
    "ServoData",
    "StepResult",
    "continuous_weights",
    "design_weights",
    "servo_data",
    "closed_loop_matrix",
    "step_response",
    "step_metrics_rows",
    "plot_steps",
    "collect_warnings",
    "SIGMA_PROCESS",
    "SIGMA_SENSOR",
]

#: §5.4 Table 5.1: design name -> (W1 name, W2 name)
DESIGNS: dict[str, tuple[str, str]] = {
    "Design 1": ("W11", "W21"),
    "Design 2": ("W12", "W21"),
    "Design 3": ("W12", "W22"),
}

#: Table 5.1 of the thesis: design -> (γ_min, γ = 1.1 γ_min)
THESIS_TABLE_5_1: dict[str, tuple[float, float]] = {
    "Design 1": (0.880, 0.968),
    "Design 2": (1.493, 1.642),
    "Design 3": (1.347, 1.482),
}

#: §5.4 noise levels (standard deviations)
SIGMA_PROCESS = 0.05
SIGMA_SENSOR = 0.05

#: Rows above this |y| count as diverged in the plots (the axis is clipped there).
PLOT_LIMIT = 2.0


def continuous_weights() -> dict[str, control.TransferFunction]:
    """The four continuous §5.4 weights (the OCR's ``0.01/s`` reads ``0.01/5``: a DC-gain normalisation, not an integrator).

    ``W1x`` are 100 at DC and 0.2 (W11) / 0.2 (W12) at high frequency; ``W2x`` are 0.05 at
    DC and 1 at high frequency.

    Returns
    -------
    dict of str to control.TransferFunction
        ``"W11"``, ``"W12"`` (performance) and ``"W21"``, ``"W22"`` (control effort); :data:`DESIGNS` pairs them.

    Examples
    --------
    >>> from experiments.lab import continuous_weights
    >>> W = continuous_weights()
    >>> sorted(W), round(float(abs(W["W11"](0))), 6)
    (['W11', 'W12', 'W21', 'W22'], 100.0)
    """
    s = control.tf("s")
    return {
        "W11": 100 * (0.01 / 5) * (s + 5) / (s + 0.01),
        "W21": 0.05 * (10 / 0.5) * (s + 0.5) / (s + 10),
        "W12": 100 * (0.02 / 10) * (s + 10) / (s + 0.02),
        "W22": 0.05 * (20 / 1) * (s + 1) / (s + 20),
    }


def design_weights(dt: float = SERVO_DT) -> dict[str, control.StateSpace]:
    """The §5.4 weights of :func:`continuous_weights` discretised with Tustin at ``dt`` (10 Hz).

    Parameters
    ----------
    dt : float, optional
        Sample time (s); default the servo's 0.1 s.

    Returns
    -------
    dict of str to control.StateSpace
        The four discrete weights under the same names.

    Examples
    --------
    >>> from experiments.lab import design_weights
    >>> W = design_weights()
    >>> W["W11"].dt, round(float(abs(W["W11"](1.0))), 6)  # Tustin keeps the DC gain
    (0.1, 100.0)
    """
    return {name: tustin(W, dt) for name, W in continuous_weights().items()}


@dataclass(frozen=True)
class ServoData:
    """One open-loop data set of the servo (5.6) (time along axis 0)."""

    u: np.ndarray
    y: np.ndarray
    y_clean: np.ndarray
    dt: float
    seed: int
    sigma_process: float
    sigma_sensor: float

    @property
    def n(self) -> int:
        """Number of samples."""
        return self.u.shape[0]

    def first(self, n: int) -> tuple[np.ndarray, np.ndarray]:
        """The first ``n`` samples ``(u, y)`` (the thesis uses one data set for every design)."""
        if n > self.n:
            raise DataError(f"asked for {n} samples of a data set of {self.n}; generate a longer one "
                             f"with servo_data({n}, seed={self.seed})")
        return self.u[:n], self.y[:n]


def servo_data(n: int, *, seed: int = 0, sigma_process: float = SIGMA_PROCESS,
               sigma_sensor: float = SIGMA_SENSOR, dt: float = SERVO_DT) -> ServoData:
    """PRBS ±1 (unity power) experiment on the servo with process and sensor noise (§5.4).

    The PRBS phase and the two noises are drawn from independent streams spawned from
    ``seed``.  ``y_clean`` is the noise-free response to the same PRBS (no process noise
    either), used for the noise-free comparison of Fig. 5.10.

    Parameters
    ----------
    n : int
        Number of samples.
    seed : int, optional
        Seed of the PRBS phase and the noises.
    sigma_process, sigma_sensor : float, optional
        Standard deviations of the noise at the plant input and at the sensor (0.05 each in §5.4).
    dt : float, optional
        Sample time (s).

    Returns
    -------
    ServoData
        ``u``, ``y``, ``y_clean`` of shape ``(n,)`` and the settings; ``first(k)`` the first ``k`` samples.

    Examples
    --------
    >>> from experiments.lab import servo_data
    >>> d = servo_data(200, seed=0)
    >>> d.n, d.dt, d.y.shape
    (200, 0.1, (200,))
    >>> u, y = d.first(100)
    >>> u.shape
    (100,)
    """
    ss_prbs, ss_noise = np.random.SeedSequence(seed).spawn(2)
    u = prbs(n, seed=np.random.default_rng(ss_prbs))
    plant = servo(dt)
    noisy = collect_data(plant, u, process_noise=sigma_process, sensor_noise=sigma_sensor,
                         seed=np.random.default_rng(ss_noise))
    clean = collect_data(plant, u)
    return ServoData(u=noisy.u[:, 0], y=noisy.y[:, 0], y_clean=clean.y[:, 0], dt=noisy.dt, seed=seed,
                     sigma_process=sigma_process, sigma_sensor=sigma_sensor)


def closed_loop_matrix(plant: control.StateSpace, controller: control.StateSpace) -> np.ndarray:
    """State matrix of the loop ``u = K [r; y]``, ``y = P u``: :func:`experiments.simulate.closed_loop_system`'s ``A``.

    Used for the stability verdict (spectral radius), independently of the time simulation.

    Examples
    --------
    The servo under the proportional law ``u = 0.5 (r − y)`` (controller inputs ``[r; y]``):

    >>> import control, numpy as np
    >>> from experiments import servo
    >>> from experiments.lab import closed_loop_matrix
    >>> A = closed_loop_matrix(servo(), control.ss([], [], [], [[0.5, -0.5]], 0.1))
    >>> A.shape, bool(np.abs(np.linalg.eigvals(A)).max() < 1)
    ((2, 2), True)
    """
    return np.asarray(closed_loop_system(plant, controller).A, float)


@dataclass(frozen=True)
class StepResult:
    """A noise-free closed-loop unit step response and its metrics.

    Metrics (reference 1): ``rise_time`` 10 %→90 % (s), ``overshoot`` (%), ``settling_time``
    (last exit from the ±2 % band, s), ``steady_state_error`` (|1 − mean y| over the last
    10 % of the run), ``max_abs_y``.  ``stable`` comes from the closed-loop eigenvalues
    (``spectral_radius < 1``); the time metrics of an unstable loop are NaN.
    """

    t: np.ndarray
    y: np.ndarray
    u: np.ndarray
    spectral_radius: float
    stable: bool
    rise_time: float
    overshoot: float
    settling_time: float
    steady_state_error: float
    max_abs_y: float

    def metrics(self) -> dict:
        d = asdict(self)
        for k in ("t", "y", "u"):
            d.pop(k)
        return d


def step_response(plant, controller, n_steps: int = 300, *, perturbation=None) -> StepResult:
    """Noise-free unit step of ``plant`` (+ ``perturbation``) under ``controller`` (inputs [r; y]).

    Parameters
    ----------
    plant : control.StateSpace
        Discrete plant.
    controller : control.StateSpace
        Discrete controller with inputs ``[r; y]``.
    n_steps : int, optional
        Length of the run (samples).
    perturbation : control.StateSpace, optional
        Additive perturbation of the plant (its response is in ``y``, and in the stability verdict).

    Returns
    -------
    StepResult
        The response and its metrics; ``stable`` from the closed-loop eigenvalues.

    Examples
    --------
    >>> import control
    >>> from experiments import servo
    >>> from experiments.lab import step_response
    >>> r = step_response(servo(), control.ss([], [], [], [[0.5, -0.5]], 0.1), 300)
    >>> r.stable, round(r.spectral_radius, 3), round(r.overshoot, 1), round(r.rise_time, 1)
    (True, 0.952, 5.0, 2.9)
    """
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # overflow in diverging runs
        res = closed_loop(plant, controller, step(n_steps), perturbation=perturbation)
    true_plant = plant if perturbation is None else control.parallel(control.ss(plant), control.ss(perturbation))
    rho = float(np.max(np.abs(np.linalg.eigvals(closed_loop_matrix(control.ss(true_plant), controller)))))
    t, y, u = res.t, res.y[:, 0], res.u[:, 0]
    stable = bool(rho < 1.0)
    finite = np.isfinite(y)
    max_abs = float(np.max(np.abs(y[finite]))) if finite.any() else float("inf")
    if not finite.all():
        max_abs = float("inf")
    if not stable:
        nan = float("nan")
        return StepResult(t, y, u, rho, False, nan, nan, nan, nan, max_abs)
    return StepResult(t, y, u, rho, True, *_time_metrics(t, y), max_abs)


def _time_metrics(t: np.ndarray, y: np.ndarray) -> tuple[float, float, float, float]:
    tail = max(1, len(y) // 10)
    final = float(np.mean(y[-tail:]))
    sse = abs(1.0 - final)

    def first_cross(level):
        idx = np.nonzero(y >= level)[0]
        return t[idx[0]] if idx.size else np.nan

    rise = float(first_cross(0.9) - first_cross(0.1))
    overshoot = float(max(0.0, (np.max(y) - 1.0) * 100.0))
    outside = np.nonzero(np.abs(y - 1.0) > 0.02)[0]
    if outside.size == 0:
        settling = 0.0
    elif outside[-1] == len(y) - 1:
        settling = float("nan")  # never settles within the run
    else:
        settling = float(t[outside[-1] + 1])
    return rise, overshoot, settling, sse


def step_metrics_rows(results: dict[str, StepResult]) -> tuple[list[str], list[list]]:
    """Headers and rows of a step-metrics table (unstable loops marked, metrics '—').

    Parameters
    ----------
    results : dict of str to StepResult
        Case name → :func:`step_response` result.

    Returns
    -------
    headers : list of str
    rows : list of list
        One row per case, for :class:`experiments.lab.report.Report` tables.

    Examples
    --------
    >>> import control
    >>> from experiments import servo
    >>> from experiments.lab import step_metrics_rows, step_response
    >>> r = step_response(servo(), control.ss([], [], [], [[0.5, -0.5]], 0.1), 300)
    >>> headers, rows = step_metrics_rows({"P 0.5": r})
    >>> headers[:2], rows[0][:2]
    (['case', 'closed loop'], ['P 0.5', 'stable'])
    """
    headers = ["case", "closed loop", "spectral radius", "rise time (s)", "overshoot (%)",
               "settling 2 % (s)", "steady-state error", "max \\|y\\|"]
    rows = []
    for name, r in results.items():
        if r.stable:
            rows.append([name, "stable", r.spectral_radius] + [
                v if np.isfinite(v) else "—"
                for v in (r.rise_time, r.overshoot, r.settling_time, r.steady_state_error, r.max_abs_y)])
        else:
            rows.append([name, "**unstable**", r.spectral_radius, "—", "—", "—", "—",
                         f"{r.max_abs_y:.3g}"])
    return headers, rows


def plot_steps(ax, results: dict[str, StepResult], title: str) -> None:
    """Step responses on ``ax``; unstable loops dashed, labelled, and clipped at ±PLOT_LIMIT.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        Where to draw.
    results : dict of str to StepResult
        Case name → :func:`step_response` result.
    title : str
        Axes title.

    Examples
    --------
    >>> import control
    >>> from matplotlib.figure import Figure
    >>> from experiments import servo
    >>> from experiments.lab import plot_steps, step_response
    >>> r = step_response(servo(), control.ss([], [], [], [[0.5, -0.5]], 0.1), 100)
    >>> ax = Figure().subplots()
    >>> plot_steps(ax, {"P 0.5": r}, "servo, proportional law")
    >>> [line.get_label() for line in ax.get_lines()][:1]
    ['P 0.5']
    """
    for name, r in results.items():
        y = np.array(r.y, dtype=float)
        out = np.nonzero(~np.isfinite(y) | (np.abs(y) > 2 * PLOT_LIMIT))[0]
        if out.size:  # draw a diverging response up to where it leaves the axes, then stop
            y[out[0] + 1:] = np.nan
            y[out[0]] = np.sign(np.nan_to_num(r.y[out[0]], posinf=1.0, neginf=-1.0)) * 2 * PLOT_LIMIT
        if r.stable:
            ax.plot(r.t, y, label=name)
        else:
            ax.plot(r.t, y, "--", label=f"{name} (unstable)")
    ax.axhline(1.0, color="0.6", lw=0.8, ls=":")
    ax.set_ylim(-0.5, PLOT_LIMIT)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("y (servo output; reference step 1)")
    ax.set_title(title)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)


@contextlib.contextmanager
def collect_warnings():
    """Record (instead of printing) every warning raised inside the block; yields the list.

    The sweeps expect some (near-γ_min levels, rank-deficient noise-free regressors, inaccurate
    solver statuses); the reports list them.

    Examples
    --------
    >>> import warnings
    >>> from experiments.lab import collect_warnings
    >>> with collect_warnings() as log:
    ...     warnings.warn("near γ_min")
    >>> [str(w.message) for w in log]
    ['near γ_min']
    """
    with warnings.catch_warnings(record=True) as log:
        warnings.simplefilter("always")
        yield log
