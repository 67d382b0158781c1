"""Plants used in the thesis experiments, as python-control state-space systems.

* :func:`servo` — the servo actuator (5.5) ``P(s) = 1/(s(s+1))``, sampled at 10 Hz
  with a zero-order hold, which gives (5.6)
  ``P_d(z) = (0.004837 z + 0.004679)/(z² − 1.905 z + 0.9048)``.
* :func:`three_disk` — the three-disk torsional plant of §6.1 (``P_{y1,u}``,
  ``P_{y2,u}``, ``P_{y3,u}``, or the one-input three-output model), sampled at
  64 Hz with a zero-order hold.

Both are built in a real *modal* realisation: one state per real pole and a
``[[σ, −ω_d], [ω_d, σ]]`` block per complex pair, each block scaled so that its
input and output gains have equal size.  The lightly damped modes of the
three-disk plant then discretise into scaled rotations (``expm`` of a normal
block), which keeps the sampled model numerically sane, unlike a companion
(controllable canonical) form whose coefficients span ten decades.
"""
from __future__ import annotations

import numbers
from dataclasses import dataclass

import control as ct
import numpy as np
from scipy.linalg import block_diag

from synthesis.validation import DataError, check_instance, check_level, check_sample_time

__all__ = [
    "servo",
    "three_disk",
    "third_order",
    "resonant",
    "nonminimum_phase",
    "PLANT_CATALOGUE",
    "plant_catalogue",
    "ThreeDiskParameters",
    "THREE_DISK",
    "SERVO_DT",
    "THREE_DISK_DT",
    "modal_ss",
    "damped_pair",
    "zoh",
]

SERVO_DT = 0.1
"""Sample time of the §5.4 design example (10 Hz)."""

THREE_DISK_DT = 1.0 / 64.0
"""Sample time of the Chapter 6 experiments (64 Hz)."""


@dataclass(frozen=True)
class ThreeDiskParameters:
    """Parameters of the §6.1 three-disk models (rad/s, radians per volt)."""

    k: float = 24.26
    alpha: float = 0.35
    zeta_z1: float = 0.026
    omega_z1: float = 10.65
    zeta_z2: float = 0.011
    omega_z2: float = 42.00
    zeta_p1: float = 0.024
    omega_p1: float = 15.85
    zeta_p2: float = 0.010
    omega_p2: float = 43.50

    def poles(self) -> np.ndarray:
        """Continuous-time poles ``0, −α`` and the two lightly damped pairs."""
        return np.concatenate(
            [[0.0, -self.alpha], damped_pair(self.zeta_p1, self.omega_p1), damped_pair(self.zeta_p2, self.omega_p2)]
        )

    def numerators(self) -> dict[str, np.ndarray]:
        """Numerator polynomials (highest power first) of ``P_{y1,u}``, ``P_{y2,u}``, ``P_{y3,u}``."""
        q1 = _quad(self.zeta_z1, self.omega_z1)
        q2 = _quad(self.zeta_z2, self.omega_z2)
        return {
            "y1": self.k * np.polymul(q1, q2),
            "y2": self.k * self.omega_z2**2 * q1,
            "y3": np.array([self.k * self.omega_z1**2 * self.omega_z2**2]),
        }

    def denominator(self) -> np.ndarray:
        """Common denominator ``s (s+α)(s² + 2ζ_{p1}ω_{p1}s + ω_{p1}²)(s² + 2ζ_{p2}ω_{p2}s + ω_{p2}²)``."""
        d = np.polymul([1.0, self.alpha, 0.0], _quad(self.zeta_p1, self.omega_p1))
        return np.polymul(d, _quad(self.zeta_p2, self.omega_p2))


THREE_DISK = ThreeDiskParameters()
"""The §6.1 parameter values (thesis §6.1: k, α and the zero/pole damping ratios and frequencies in rad/s)."""


def servo(dt: float = SERVO_DT, continuous: bool = False) -> ct.StateSpace:
    """Servo actuator (5.5) ``P(s) = 1/(s(s+1))``, optionally ZOH-sampled.

    Parameters
    ----------
    dt : float
        Sample time in seconds (10 Hz in §5.4, which gives (5.6)).
    continuous : bool
        Return the continuous-time model instead of the sampled one.

    Returns
    -------
    control.StateSpace
        Two-state modal realisation (integrator and the pole at −1), one input
        ``u[0]`` and one output ``y[0]``; ``dt`` is the sample time (0 when continuous).

    Examples
    --------
    >>> import numpy as np
    >>> P = servo()
    >>> P.dt, P.nstates, P.ninputs, P.noutputs
    (0.1, 2, 1, 1)
    >>> sorted(np.round(np.abs(P.poles()), 6).tolist())            # ZOH: e^{0·dt} = 1 and e^{−dt}
    [0.904837, 1.0]
    >>> bool(np.isclose(min(np.abs(P.poles())), np.exp(-P.dt)))
    True
    >>> sorted(servo(continuous=True).poles().real.round(6).tolist())
    [-1.0, 0.0]
    """
    sys = modal_ss({"y": np.array([1.0])}, np.array([0.0, -1.0]), name="servo")
    return sys if continuous else zoh(sys, dt)


def three_disk(
    output: str = "y3",
    dt: float = THREE_DISK_DT,
    continuous: bool = False,
    params: ThreeDiskParameters = THREE_DISK,
) -> ct.StateSpace:
    """Three-disk torsional plant of §6.1, optionally ZOH-sampled at 64 Hz.

    Parameters
    ----------
    output : {"y1", "y2", "y3", "all"}
        Which disk angle is measured: ``"y1"`` is the collocated plant (§6.3),
        ``"y3"`` the non-collocated one (§6.2); ``"all"`` gives the one-input,
        three-output model ``[y1; y2; y3]`` (one shared 6-state realisation).
    dt : float
        Sample time in seconds.
    continuous : bool
        Return the continuous-time model instead of the sampled one.
    params : ThreeDiskParameters
        Model parameters (defaults: thesis §6.1 values).

    Returns
    -------
    control.StateSpace
        Six-state modal realisation (integrator, pole at −α, two lightly damped
        pairs), strictly proper.

    Examples
    --------
    >>> P = three_disk()                                           # non-collocated y3, 64 Hz
    >>> P.dt == THREE_DISK_DT == 1 / 64, P.nstates, P.ninputs, P.noutputs
    (True, 6, 1, 1)
    >>> three_disk("all").noutputs                                 # [y1; y2; y3]
    3
    """
    nums = params.numerators()
    if output == "all":
        chosen = nums
    elif output in nums:
        chosen = {output: nums[output]}
    else:
        raise DataError(f"output must be one of 'y1', 'y2', 'y3', 'all'; got {output!r}")
    sys = modal_ss(chosen, params.poles(), name=f"three_disk_{output}")
    return sys if continuous else zoh(sys, dt)


def third_order(dt: float = SERVO_DT, continuous: bool = False) -> ct.StateSpace:
    """Stable third-order plant ``6/((s+1)(s+2)(s+3))`` (unit DC gain), ZOH-sampled (10 Hz default).

    Not from the thesis: a test plant of different character for the §7.4 pipeline.

    Examples
    --------
    >>> import control
    >>> P = third_order()
    >>> P.dt, P.nstates, round(float(control.dcgain(P)), 6)        # unit DC gain, kept by the ZOH
    (0.1, 3, 1.0)
    """
    sys = modal_ss({"y": np.array([6.0])}, np.array([-1.0, -2.0, -3.0]), name="third_order")
    return sys if continuous else zoh(sys, dt)


def resonant(zeta: float = 0.05, omega: float = 2.0, dt: float = SERVO_DT, continuous: bool = False) -> ct.StateSpace:
    """Lightly damped resonant plant ``ω²/(s² + 2ζωs + ω²)`` (unit DC gain), ZOH-sampled.

    Defaults ζ = 0.05, ω = 2 rad/s: a resonance peak of ``1/(2ζ) = 10`` (20 dB).  Not from the thesis.

    Examples
    --------
    >>> import control
    >>> P = resonant()                                             # ζ = 0.05, ω = 2 rad/s
    >>> P.dt, P.nstates, round(float(control.dcgain(P)), 6)
    (0.1, 2, 1.0)
    >>> round(abs(complex(resonant(continuous=True)(2j))), 6)      # the peak 1/(2ζ) at s = jω
    10.0
    """
    if not (0 < zeta < 1 and omega > 0):
        raise DataError(f"need 0 < zeta < 1 and omega > 0, got zeta={zeta!r}, omega={omega!r}")
    sys = modal_ss({"y": np.array([omega * omega])}, damped_pair(zeta, omega), name="resonant")
    return sys if continuous else zoh(sys, dt)


def nonminimum_phase(dt: float = SERVO_DT, continuous: bool = False) -> ct.StateSpace:
    """Non-minimum-phase plant ``2(1 − s)/((s+1)(s+2))`` (unit DC gain, zero at s = +1), ZOH-sampled.

    Not from the thesis.  The receding-horizon laws with short horizons destabilise it
    (unstable loops at i = 10–20 on 10 Hz data, with a controller pole at 1.2, not on the zero at 1.11).

    Examples
    --------
    >>> import control
    >>> P = nonminimum_phase()
    >>> P.dt, P.nstates, round(float(control.dcgain(P)), 6)
    (0.1, 2, 1.0)
    >>> nonminimum_phase(continuous=True).zeros().real.round(6).tolist()     # the zero at s = +1
    [1.0]
    """
    sys = modal_ss({"y": np.array([-2.0, 2.0])}, np.array([-1.0, -2.0]), name="nonminimum_phase")
    return sys if continuous else zoh(sys, dt)


#: name -> (factory, one-line description): plants of different character for pipeline studies.
PLANT_CATALOGUE = {
    "servo": (servo, "1/(s(s+1)) at 10 Hz: integrating (§5.4)"),
    "third_order": (third_order, "6/((s+1)(s+2)(s+3)) at 10 Hz: stable, third order"),
    "resonant": (resonant, "4/(s²+0.2s+4) at 10 Hz: lightly damped, ζ = 0.05"),
    "nonminimum_phase": (nonminimum_phase, "2(1−s)/((s+1)(s+2)) at 10 Hz: zero at s = +1"),
    "three_disk_y1": (lambda: three_disk("y1"), "three-disk, collocated y1, 64 Hz (§6.1): integrator + two resonances"),
}


def plant_catalogue() -> dict[str, ct.StateSpace]:
    """The plants of :data:`PLANT_CATALOGUE`, built (discrete, default sample times).

    Examples
    --------
    >>> plants = plant_catalogue()
    >>> list(plants) == list(PLANT_CATALOGUE)
    True
    >>> {name: P.dt for name, P in plants.items()}
    {'servo': 0.1, 'third_order': 0.1, 'resonant': 0.1, 'nonminimum_phase': 0.1, 'three_disk_y1': 0.015625}
    """
    return {name: factory() for name, (factory, _) in PLANT_CATALOGUE.items()}


# ---------------------------------------------------------------------------
def _quad(zeta: float, omega: float) -> np.ndarray:
    return np.array([1.0, 2.0 * zeta * omega, omega * omega])


def damped_pair(zeta: float, omega: float) -> np.ndarray:
    """The poles ``−ζω ± jω√(1 − ζ²)`` of ``s² + 2ζωs + ω²`` (``0 ≤ ζ < 1``), as a length-2 complex array.

    Examples
    --------
    >>> from experiments import damped_pair
    >>> damped_pair(0.6, 5.0)
    array([-3.+4.j, -3.-4.j])
    """
    # checked: None or text had raised TypeError, NaN had returned NaN poles, ζ ≥ 1 a NaN imaginary part
    omega = check_level(omega, "omega (the natural frequency, rad/s)")
    if isinstance(zeta, bool) or not isinstance(zeta, numbers.Real) or not 0.0 <= zeta < 1.0:
        raise DataError(f"zeta must be a damping ratio in [0, 1) (an oscillating pair), got {zeta!r}")
    re = -zeta * omega
    im = omega * np.sqrt(1.0 - zeta * zeta)
    return np.array([re + 1j * im, re - 1j * im])


def zoh(sys: ct.StateSpace, dt: float) -> ct.StateSpace:
    """Zero-order-hold discretisation of a continuous plant at ``dt`` (named ``<name>_zoh``), as the plants here are.

    Raises
    ------
    ValueError
        ``dt`` not a positive finite number.

    Examples
    --------
    >>> import control
    >>> from experiments import zoh
    >>> P = zoh(control.ss([[-1.0]], [[1.0]], [[1.0]], [[0.0]], name="lag"), 0.1)
    >>> P.dt, P.name, round(float(P.A[0, 0]), 6)
    (0.1, 'lag_zoh', 0.904837)
    """
    # checked: a non-system had raised AttributeError, a text dt TypeError; a discrete system is not re-sampled
    check_instance(sys, (ct.StateSpace, ct.TransferFunction), "sys", "a continuous-time python-control system")
    if sys.dt not in (0, None):
        raise DataError(f"sys is already discrete (dt = {sys.dt}); zoh discretises a continuous plant (dt = 0)")
    dt = check_sample_time(dt, "dt", allow_true=False)
    return ct.c2d(sys, dt, method="zoh", name=sys.name + "_zoh")


def modal_ss(numerators: dict[str, np.ndarray], poles: np.ndarray, name: str) -> ct.StateSpace:
    """Real modal realisation of ``N_o(s)/Π(s − p)`` for each output ``o``.

    The poles must be distinct; complex poles come in conjugate pairs (the one
    with positive imaginary part is used).  Residues are computed from the
    factored denominator, ``ρ = N(p)/Π_{q≠p}(p − q)``.

    Parameters
    ----------
    numerators : dict of str to array_like
        Output name → numerator polynomial coefficients (highest power first).
    poles : array_like
        The distinct poles (complex ones in conjugate pairs, e.g. from :func:`damped_pair`).
    name : str
        System name.

    Returns
    -------
    control.StateSpace
        Continuous, one input ``u[0]`` and one output ``y[k]`` per numerator (in the order of ``numerators``):
        python-control's default signal names, which the toolkit's controllers use too (inputs ``r[0]``,
        ``y[0]``, output ``u[0]``), so that ``control.interconnect([P, K], inplist=["r[0]"],
        outlist=["y[0]", "u[0]"])`` closes the loop by name.  The keys of ``numerators`` stay in ``name``'s
        caller (e.g. ``three_disk("y3")``), not in the signal names.

    Examples
    --------
    ``6/((s+1)(s+2)(s+3))``, then discretised as the plants are:

    >>> import numpy as np
    >>> from experiments import modal_ss, zoh
    >>> G = modal_ss({"y": np.array([6.0])}, np.array([-1.0, -2.0, -3.0]), name="third_order")
    >>> G.nstates, round(float(G.dcgain()), 12)
    (3, 1.0)
    >>> zoh(G, 0.1).dt
    0.1
    """
    poles = np.asarray(poles, dtype=complex)
    outputs = list(numerators)
    blocks_a, blocks_b, blocks_c = [], [], []
    for idx, p in enumerate(poles):
        if p.imag < 0:
            continue
        others = np.delete(poles, idx)
        dprime = np.prod(p - others)
        res = np.array([np.polyval(numerators[o], p) / dprime for o in outputs])
        if p.imag == 0:
            a = np.array([[p.real]])
            b = np.array([[1.0]])
            c = res.real[:, None]
        else:
            # z' = p z + u, y = 2 Re(ρ z): real coordinates [Re z; Im z].
            a = np.array([[p.real, -p.imag], [p.imag, p.real]])
            b = np.array([[1.0], [0.0]])
            c = np.column_stack([2.0 * res.real, -2.0 * res.imag])
        scale = np.sqrt(np.linalg.norm(c) / np.linalg.norm(b))
        blocks_a.append(a)
        blocks_b.append(b * scale)
        blocks_c.append(c / scale)
    A = block_diag(*blocks_a)
    B = np.vstack(blocks_b)
    C = np.hstack(blocks_c)
    D = np.zeros((len(outputs), 1))
    # python-control's default names: a plant named "u"/"y" did not connect by name to the controllers' "u[0]"/"y[0]"
    return ct.ss(A, B, C, D, inputs=["u[0]"], outputs=[f"y[{k}]" for k in range(len(outputs))], name=name)
