"""Discrete weighting filters for the mixed-sensitivity cost (thesis §3.1, (3.10)–(3.12)).

A weight is a python-control discrete LTI system with relative McMillan degree 0,
i.e. a full-rank direct feedthrough ``D`` (§3.1, §5.1 comment 3).  This module

* checks and normalises weights (:func:`as_weight`): a scalar or a numpy matrix is a
  static weight, a ``TransferFunction`` is converted to a ``StateSpace``;
* builds discrete weights from continuous designs with the Tustin transform
  (:func:`tustin`), as in §5.4;
* forms the finite-horizon matrices of the control laws: the block lower-triangular
  Toeplitz matrix of Markov parameters ``H`` (3.10)/(3.11) (:func:`markov_toeplitz`)
  and the extended observability matrix ``Γ`` (3.12) (:func:`observability`).

Markov parameters are computed directly from ``(A, B, C, D)``: python-control's
discrete ``impulse_response`` scales by ``1/dt`` and ``control.markov`` assumes a
stable system.
"""
from __future__ import annotations

import numbers

import control
import numpy as np

from .exceptions import WeightError

from ._validation import (DataError, as_discrete_system, check_count, check_flag, check_horizon, check_instance,
                          check_sample_time, to_state_space)

__all__ = [
    "WeightError",
    "as_weight",
    "common_dt",
    "diagonal_weight",
    "is_zero_weight",
    "makeweight",
    "markov_toeplitz",
    "observability",
    "tustin",
]


def tustin(sys_continuous, dt: float) -> control.StateSpace:
    """Discretise a continuous-time weight with the Tustin (bilinear) transform (§5.4).

    Parameters
    ----------
    sys_continuous : control.TransferFunction or control.StateSpace
        Continuous-time weight (``dt = 0``).
    dt : float
        Sample time of the data, > 0.

    Returns
    -------
    control.StateSpace
        Discrete weight with sample time ``dt``.

    Examples
    --------
    The bilinear transform maps ``s = 0`` to ``z = 1`` and ``s = ∞`` to ``z = −1``, so the DC and
    high-frequency gains of ``W(s) = 10 (s + 1)/(s + 10)`` are kept:

    >>> import control, numpy as np
    >>> s = control.tf("s")
    >>> W = tustin(10 * (s + 1) / (s + 10), 0.1)
    >>> W.dt, W.nstates
    (0.1, 1)
    >>> gain = lambda z: round(abs(complex(np.squeeze(W(z)))), 6)
    >>> gain(1.0), gain(-1.0)
    (1.0, 10.0)
    """
    if not isinstance(sys_continuous, (control.TransferFunction, control.StateSpace)):
        raise WeightError(f"tustin needs a python-control TransferFunction or StateSpace, got {type(sys_continuous).__name__}")
    if not control.isctime(sys_continuous, strict=True):
        raise WeightError("tustin needs a continuous-time system (dt = 0); the weight is already discrete")
    if isinstance(dt, bool) or not (isinstance(dt, numbers.Real) and np.isfinite(dt) and dt > 0):
        raise WeightError(f"dt must be a positive finite sample time in seconds, got {dt!r}")
    # python-control's sampling fails on an improper or NaN weight with a bare ValueError: check it first
    ss = to_state_space(sys_continuous, "the weight given to tustin", error=WeightError)
    if not all(np.all(np.isfinite(M)) for M in (ss.A, ss.B, ss.C, ss.D)):
        raise WeightError("the weight given to tustin has NaN or infinite entries; check how it was computed")
    # the state-space form is sampled, never the transfer function: python-control maps a transfer function's
    # polynomial coefficients to z, which loses the weight when its poles crowd z = 1 (measured: a sixth-order
    # weight at dt = 1e-3 came out with a frequency response off by 790 %, at dt = 1e-2 by 1.5e-6; the
    # state-space route, 3e-14), and it refuses a MIMO transfer function
    return control.ss(control.sample_system(ss, float(dt), method="bilinear"))


#: the least distance of the discrete weight's pole and zero from the unit circle: its rounding, eps/margin, is the
#: relative error of the gains (:func:`makeweight`), here 1e-6 at most
_GAIN_ACCURACY_MARGIN = float(np.finfo(float).eps) * 1e6
#: the refusal of gains a first-order weight cannot carry in double precision (:func:`makeweight`)
_EXTREME = ("makeweight: dc = {dc:g}, crossover gain {mag:g} and hf = {hf:g} {why}; lower the ratios dc/mag and "
            "mag/hf or raise the crossover frequency towards the sample rate (a weight's absolute level only "
            "rescales γ)")


def makeweight(dc: float, crossover, hf: float, dt: float) -> control.StateSpace:
    """First-order weight from its gains at DC, at one frequency and at high frequency.

    In the manner of MATLAB's ``makeweight(dcgain, [freq, mag], hfgain, Ts)``.  The continuous
    design is

    ``W(s) = (hf·s + dc·a) / (s + a)``,  ``a = ω_c · sqrt((mag² − hf²) / (dc² − mag²))``,

    so that ``W(0) = dc``, ``|W(jω_c)| = mag`` and ``W(∞) = hf``: stable (pole ``−a``), minimum
    phase (zero ``−a·dc/hf``) and biproper (``D = hf ≠ 0``: relative degree 0, as a weight must
    be, §3.1).  It is discretised by the Tustin transform *prewarped at* ``ω_c``,
    ``s = K (z − 1)/(z + 1)`` with ``K = ω_c / tan(ω_c·dt/2)``, which maps ``z = e^{jω_c dt}`` to
    ``s = jω_c`` exactly: the discrete weight has ``|W(e^{jω_c dt})| = mag`` (to rounding),
    ``W(1) = dc`` and ``W(−1) = hf`` (the Nyquist frequency takes the place of ``ω = ∞``), and its
    pole ``(K − a)/(K + a)`` and zero ``(hf·K − dc·a)/(hf·K + dc·a)`` lie inside the unit circle.

    Parameters
    ----------
    dc : float
        Gain at DC (absolute, not dB), > 0.
    crossover : (float, float)
        ``(freq, mag)``: the frequency ``ω_c`` in rad/s (below the Nyquist frequency ``π/dt``) and
        the gain there, strictly between ``dc`` and ``hf``.
    hf : float
        Gain at high frequency (at the Nyquist frequency for the discrete weight), > 0.
    dt : float
        Sample time of the data, > 0; ``0`` returns the continuous design.

    Returns
    -------
    control.StateSpace
        One state, one input, one output, sample time ``dt``.

    Raises
    ------
    WeightError
        A gain or the frequency not a positive finite number; ``mag`` not strictly between ``dc``
        and ``hf`` (a first-order weight is monotonic in ``|W|``); ``freq ≥ π/dt``; gains whose ratio (against
        ``freq·dt``) would put the discrete pole or zero within rounding of the unit circle, where the weight's
        gains are no longer its own to 1e-6 (``dc/mag`` about 1e9 at ``freq·dt = 0.05``).

    Examples
    --------
    A performance weight W1: large at low frequency, crossing 1 at 0.5 rad/s, 0.5 at high frequency;
    data sampled at 10 Hz:

    >>> import numpy as np
    >>> from synthesis import makeweight
    >>> W1 = makeweight(100.0, (0.5, 1.0), 0.5, 0.1)
    >>> gain = lambda w: abs(complex(np.squeeze(W1(np.exp(1j * w * 0.1)))))
    >>> round(gain(0.0), 9), round(gain(0.5), 9), round(gain(np.pi / 0.1), 9)
    (100.0, 1.0, 0.5)
    >>> makeweight(100.0, (0.5, 200.0), 0.5, 0.1)
    Traceback (most recent call last):
    ...
    synthesis.exceptions.WeightError: makeweight: the crossover gain mag = 200 must lie strictly between dc = 100 and hf = 0.5 (a first-order weight's gain moves monotonically from dc to hf); choose mag in (0.5, 100)
    """
    def positive(value, what):
        if isinstance(value, bool) or not isinstance(value, numbers.Real) or not (np.isfinite(value) and value > 0):
            raise WeightError(f"makeweight: {what} must be a positive finite number (an absolute gain or rad/s, "
                              f"not dB), got {value!r}")
        return float(value)

    dc, hf = positive(dc, "dc"), positive(hf, "hf")
    try:
        freq, mag = crossover
    except (TypeError, ValueError):
        raise WeightError(f"makeweight: crossover must be a pair (freq in rad/s, mag), got {crossover!r}") from None
    freq, mag = positive(freq, "the crossover frequency"), positive(mag, "the crossover gain mag")
    if dc == hf:  # the interval below is empty: "choose mag in (1, 1)" named no fix
        raise WeightError(f"makeweight: dc = hf = {dc:g} leaves no gain strictly between them for the crossover: a "
                          f"weight of constant gain has none; pass the number {dc:g} itself as a static weight")
    if not min(dc, hf) < mag < max(dc, hf):
        raise WeightError(
            f"makeweight: the crossover gain mag = {mag:g} must lie strictly between dc = {dc:g} and hf = {hf:g} "
            "(a first-order weight's gain moves monotonically from dc to hf); choose mag in "
            f"({min(dc, hf):g}, {max(dc, hf):g})")
    if isinstance(dt, bool) or not isinstance(dt, numbers.Real) or not (np.isfinite(dt) and dt >= 0):
        raise WeightError(f"makeweight: dt must be the data's sample time (> 0), or 0 for the continuous design; "
                          f"got {dt!r}")
    # the squares' differences as products of ratios: mag ** 2 had raised OverflowError for gains near 1e300
    a = freq * np.sqrt(((mag - hf) / (dc - mag)) * ((mag + hf) / (dc + mag)))
    if not np.isfinite(a * max(dc, hf)):
        raise WeightError(_EXTREME.format(dc=dc, hf=hf, mag=mag, why="give coefficients beyond floating point"))
    if dt == 0:
        return control.ss(control.tf([hf, dc * a], [1.0, a]))
    nyquist = np.pi / dt
    if freq >= nyquist:
        raise WeightError(
            f"makeweight: the crossover frequency {freq:g} rad/s is not below the Nyquist frequency π/dt = "
            f"{nyquist:g} rad/s of dt = {dt:g}; choose a lower frequency or sample faster")
    K = freq / np.tan(freq * dt / 2)
    num = [hf * K + dc * a, dc * a - hf * K]
    den = [K + a, a - K]
    # a large gain ratio puts the pole (K − a)/(K + a) or the zero within rounding of the unit circle, and the
    # rounding of 1 − |pole| is the relative error of W(1) (dc = 1e11: 2.4e-4; 1e300 had returned W(1) = inf)
    if not 1.0 - max(abs(den[1] / den[0]), abs(num[1] / num[0])) > _GAIN_ACCURACY_MARGIN:
        raise WeightError(_EXTREME.format(dc=dc, hf=hf, mag=mag,
                                          why=f"put the discrete weight's pole or zero within rounding of the unit "
                                              f"circle at dt = {dt:g} (its gains would be off by more than 1e-6)"))
    return control.ss(control.tf(num, den, float(dt)))


def diagonal_weight(*weights, channels: int | None = None) -> control.StateSpace:
    """A diagonal weight for several channels: one SISO weight per channel, or one weight repeated.

    The mixed-sensitivity weights of a plant with ``l`` outputs and ``m`` inputs are ``l × l`` (W1, on
    the error) and ``m × m`` (W2, on the input).  ``diagonal_weight(W, channels=2)`` weights both
    channels alike; ``diagonal_weight(Wa, Wb)`` each its own way.

    Parameters
    ----------
    *weights : scalar, python-control system
        SISO weights (checked by :func:`as_weight`), one per channel, or one with ``channels``.
    channels : int, optional
        Repeat the single weight given this many times.

    Returns
    -------
    control.StateSpace
        The block-diagonal weight, discrete, with the weights' common sample time.

    Raises
    ------
    WeightError
        No weight, a weight with more than one channel, weights with different sample times, or
        ``channels`` with more than one weight.

    Examples
    --------
    >>> W = makeweight(10.0, (0.3, 1.0), 0.5, 1.0)
    >>> W2 = diagonal_weight(W, channels=2)
    >>> W2.ninputs, W2.noutputs, W2.nstates
    (2, 2, 2)
    >>> import numpy as np
    >>> bool(np.allclose(W2(1.0), np.diag([W(1.0), W(1.0)])))
    True
    >>> diagonal_weight(W, 0.1).noutputs          # a dynamic and a static channel
    2
    """
    if not weights:
        raise WeightError("diagonal_weight needs at least one weight")
    if channels is not None:
        if len(weights) != 1:
            raise WeightError(f"channels={channels!r} repeats one weight; got {len(weights)} weights: pass one weight "
                              "with channels=, or one weight per channel without it")
        weights = weights * check_count(channels, "channels", 1, error=WeightError)
    dt = common_dt(*[w for w in weights if isinstance(w, (control.StateSpace, control.TransferFunction))])
    parts = [as_weight(w, f"weights[{k}]", dt=dt) for k, w in enumerate(weights)]
    for k, w in enumerate(parts):
        if w.ninputs != 1 or w.noutputs != 1:
            raise WeightError(f"weights[{k}] has {w.ninputs} input(s) and {w.noutputs} output(s); diagonal_weight "
                              "stacks single-channel weights")
    return control.append(*parts)


def _ss_parts(W) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    return (np.atleast_2d(np.asarray(W.A, float)).reshape(W.nstates, W.nstates),
            np.asarray(W.B, float).reshape(W.nstates, W.ninputs),
            np.asarray(W.C, float).reshape(W.noutputs, W.nstates),
            np.asarray(W.D, float).reshape(W.noutputs, W.ninputs))


def is_zero_weight(W) -> bool:
    """True when the weight's transfer function is identically zero (D = 0 and all C Aᵏ B = 0).

    Parameters
    ----------
    W : control.StateSpace or control.TransferFunction
        A python-control system (e.g. one returned by :func:`as_weight`, which turns a scalar or a
        matrix into one).

    Raises
    ------
    InputTypeError
        ``W`` is not a python-control ``StateSpace`` or ``TransferFunction``.
    WeightError
        ``W`` is an improper transfer function or has NaN/inf coefficients.

    Examples
    --------
    >>> import control
    >>> is_zero_weight(control.ss([[0.5]], [[1.0]], [[0.0]], [[0.0]], 0.1))   # C = 0, D = 0
    True
    >>> is_zero_weight(control.ss([[0.5]], [[1.0]], [[1.0]], [[0.0]], 0.1))   # 1/(z − 0.5)
    False
    >>> is_zero_weight(control.tf([0.0], [1.0], 0.1))
    True
    """
    check_instance(W, (control.StateSpace, control.TransferFunction), "W",
                   "a python-control StateSpace or TransferFunction (make a scalar or matrix weight one with "
                   "is_zero_weight(as_weight(W, name)))")
    A, B, C, D = _ss_parts(to_state_space(W, "W", error=WeightError))
    if np.any(D != 0):
        return False
    M = B
    for _ in range(A.shape[0]):
        if np.any(C @ M != 0):
            return False
        M = A @ M
    return True


def _static(D: np.ndarray, dt) -> control.StateSpace:
    q, p = D.shape
    return control.ss(np.zeros((0, 0)), np.zeros((0, p)), np.zeros((q, 0)), D, dt)


def as_weight(W, name: str, *, inputs: int | None = None, outputs: int | None = None,
              dt=None, allow_zero: bool = False, square_rank: bool = False) -> control.StateSpace:
    """Check a weighting filter and return it as a discrete ``StateSpace``.

    Parameters
    ----------
    W : scalar, array_like, control.StateSpace or control.TransferFunction
        The weight.  A scalar or a 2-D array is a static weight (its matrix is ``D``).
    name : str
        Name used in error messages (``"W1"``, …).
    inputs, outputs : int, optional
        Required number of input / output channels.
    dt : float or True, optional
        Sample time given to a static weight (dynamic weights keep theirs; use
        :func:`common_dt` to check that they agree).
    allow_zero : bool
        Accept an identically zero weight (Theorem 3.6's ``W3 = W4 = 0``).
    square_rank : bool
        Require ``rank D = min(shape D)`` instead of full column rank (used for ``W4``,
        whose ``Q4,outer = H4 H4ᵀ`` need only be semidefinite).

    Raises
    ------
    WeightError
        Continuous-time dynamics, NaN/inf entries, wrong dimensions, or a feedthrough
        ``D`` without full column rank (relative degree > 0 makes ``Q = HᵀH``
        singular, §3.1).

    Examples
    --------
    A scalar is a static weight (no states) and takes the sample time given; a transfer function
    becomes a ``StateSpace``:

    >>> import control
    >>> W2 = as_weight(0.5, "W2", dt=0.1)
    >>> W2.nstates, W2.dt, W2.D.tolist()
    (0, 0.1, [[0.5]])
    >>> W1 = as_weight(control.tf([1, -0.5], [1, -0.9], 0.1), "W1", inputs=1)
    >>> type(W1).__name__, W1.nstates
    ('StateSpace', 1)

    A strictly proper weight (``D = 0``) is refused:

    >>> as_weight(control.tf([1], [1, -0.9], 0.1), "W1")
    Traceback (most recent call last):
    ...
    synthesis.exceptions.WeightError: W1 must have relative degree 0, i.e. a full-rank feedthrough D (§3.1); its D = [[0.0]] has rank 0 < 1. Add a small direct term (e.g. a far-away zero) to make it biproper
    """
    allow_zero = check_flag(allow_zero, "allow_zero", error=WeightError)
    square_rank = check_flag(square_rank, "square_rank", error=WeightError)
    if dt is not None:  # python-control would refuse a bad one later with a bare ValueError ("invalid timebase")
        dt = check_sample_time(dt, "dt", error=WeightError)
    W = to_state_space(W, name, error=WeightError)
    if isinstance(W, control.StateSpace):
        A, B, C, D = _ss_parts(W)
        if W.nstates == 0:
            sys = _static(D, dt if dt is not None else (W.dt if W.dt else True))
        else:
            if not control.isdtime(W, strict=True):
                raise WeightError(
                    f"{name} is a continuous-time system (dt = {W.dt}); discretise it with "
                    "synthesis.tustin(W, dt) at the data's sample time")
            sys = W
    elif isinstance(W, (numbers.Real, np.ndarray, list, tuple)):
        try:
            D = np.atleast_2d(np.asarray(W, dtype=float))
        except (TypeError, ValueError) as exc:
            raise WeightError(f"{name} must be numeric, got {W!r}") from exc
        if D.ndim != 2:
            raise WeightError(f"{name}: a static weight must be a scalar or a 2-D matrix, got shape {D.shape}")
        A, B, C = np.zeros((0, 0)), np.zeros((0, D.shape[1])), np.zeros((D.shape[0], 0))
        sys = None
    else:
        raise WeightError(f"{name} must be a python-control system, a scalar or a matrix; got {type(W).__name__}")
    for part, val in (("A", A), ("B", B), ("C", C), ("D", D)):
        if not np.all(np.isfinite(val)):
            raise WeightError(f"{name}.{part} contains NaN or infinite values")
    if sys is None:
        sys = _static(D, dt if dt is not None else True)
    if inputs is not None and sys.ninputs != inputs:
        hint = (f"; for several channels stack SISO weights: synthesis.diagonal_weight({name}, channels={inputs})"
                if sys.ninputs == 1 else
                f"; build {name} for the predictor's {inputs} channel(s) (a weight of a record with other channels, or "
                f"diagonal_weight(..., channels={sys.ninputs}) where channels={inputs} was meant?)")
        raise WeightError(f"{name} has {sys.ninputs} input(s) but must have {inputs} to match the predictor{hint}")
    if outputs is not None and sys.noutputs != outputs:
        raise WeightError(f"{name} has {sys.noutputs} output(s) but must have {outputs} to match the predictor")
    if allow_zero and is_zero_weight(sys):
        return sys
    need = min(D.shape) if square_rank else D.shape[1]
    rank = np.linalg.matrix_rank(D) if D.size else 0
    if D.shape[0] < D.shape[1] and not square_rank:
        raise WeightError(
            f"{name} has {D.shape[0]} output(s) and {D.shape[1]} input(s): a weight needs at least as many "
            "outputs as inputs (§3.1)")
    if rank < need or need == 0:
        raise WeightError(
            f"{name} must have relative degree 0, i.e. a full-rank feedthrough D (§3.1); its D = {D.tolist()} "
            f"has rank {rank} < {need}. Add a small direct term (e.g. a far-away zero) to make it biproper")
    return sys


def common_dt(*weights) -> float | bool:
    """The one sample time shared by the dynamic weights; ``True`` if all are static.

    Raises
    ------
    WeightError
        If two dynamic weights have different sample times.

    Examples
    --------
    Static weights do not count:

    >>> import control
    >>> W1 = control.ss([[0.9]], [[1.0]], [[0.1]], [[1.0]], 0.1)
    >>> W2 = as_weight(0.5, "W2")
    >>> common_dt(W1, W2), common_dt(W2)
    (0.1, True)
    >>> common_dt(W1, control.ss([[0.9]], [[1.0]], [[0.1]], [[1.0]], 0.2))
    Traceback (most recent call last):
    ...
    synthesis.exceptions.WeightError: weights have different sample times [0.1, 0.2]; discretise all of them at the data's sample time
    """
    dts = []
    for W in weights:
        # scalars and matrices (static weights, as as_weight takes them) have no sample time to agree on
        if not isinstance(W, control.InputOutputSystem) or getattr(W, "nstates", 0) == 0:
            continue
        if W.dt is not True:
            dts.append(float(W.dt))
    if not dts:
        return True
    if any(not np.isclose(d, dts[0], rtol=1e-9, atol=0) for d in dts):
        raise WeightError(
            f"weights have different sample times {sorted(set(dts))}; discretise all of them at the data's "
            "sample time")
    return dts[0]


def markov_toeplitz(sys, i: int) -> np.ndarray:
    """Block lower-triangular Toeplitz matrix of Markov parameters (3.10)/(3.11).

    ``H[r, c] = D`` for ``r = c``, ``C A^{r-c-1} B`` for ``r > c``, 0 above the diagonal;
    blocks are ``(outputs × inputs)``; the result has shape ``(i·p, i·q)``.

    Parameters
    ----------
    sys : control.StateSpace, control.TransferFunction, scalar or 2-D array
        Discrete-time system (a scalar or matrix is a static gain ``D``).
    i : int
        Horizon (number of block rows and columns).

    Raises
    ------
    DataError
        Continuous-time dynamics (Markov parameters are discrete-time objects), NaN/inf entries,
        a bad horizon.

    Examples
    --------
    ``G(z) = 2 + 1/(z − 0.5)``: Markov parameters ``2, 1, 0.5, …``

    >>> import control, numpy as np
    >>> G = control.ss([[0.5]], [[1.0]], [[1.0]], [[2.0]], 1)
    >>> H = markov_toeplitz(G, 3)
    >>> H
    array([[2. , 0. , 0. ],
           [1. , 2. , 0. ],
           [0.5, 1. , 2. ]])

    ``H u`` is the response from rest to the input sequence ``u``:

    >>> u = np.array([1.0, -2.0, 0.5])
    >>> np.allclose(H @ u, control.forced_response(G, U=u).outputs)
    True
    """
    i = check_horizon(i)
    A, B, C, D = _ss_parts(_discrete(sys))
    p, q = D.shape
    blocks = np.zeros((i + 1, p, q))  # blocks[k] = k-th Markov parameter; blocks[i] = 0 (upper part)
    blocks[0] = D
    AkB = B
    for k in range(1, i):
        blocks[k] = C @ AkB
        AkB = A @ AkB
    lag = np.subtract.outer(np.arange(i), np.arange(i))  # r - c
    lag = np.where(lag >= 0, lag, i)
    return blocks[lag].transpose(0, 2, 1, 3).reshape(i * p, i * q)


def observability(sys, i: int) -> np.ndarray:
    """Extended observability matrix ``Γ = [C; CA; …; CA^{i-1}]`` (3.12), shape ``(i·p, n)``.

    Accepts what :func:`markov_toeplitz` accepts and raises the same errors.

    Examples
    --------
    >>> import control, numpy as np
    >>> G = control.ss([[0.5, 1.0], [0.0, 0.2]], [[0.0], [1.0]], [[1.0, 0.0]], [[0.0]], 0.1)
    >>> observability(G, 3)
    array([[1.  , 0.  ],
           [0.5 , 1.  ],
           [0.25, 0.7 ]])

    With ``i = n`` it is the observability matrix of :func:`control.obsv`:

    >>> np.allclose(observability(G, 2), control.obsv(G.A, G.C))
    True
    """
    i = check_horizon(i)
    A, _, C, _ = _ss_parts(_discrete(sys))
    rows = []
    CA = C
    for _ in range(i):
        rows.append(CA)
        CA = CA @ A
    return np.vstack(rows) if rows else np.zeros((0, A.shape[0]))


def _discrete(sys) -> control.StateSpace:
    """``sys`` as a ``StateSpace``; a static gain may have any sample time, dynamics must be discrete."""
    if isinstance(sys, (numbers.Real, np.ndarray, list, tuple)):
        D = np.atleast_2d(np.asarray(sys, dtype=float))
        if D.ndim != 2 or not np.all(np.isfinite(D)):
            raise DataError(f"a static gain must be a finite scalar or 2-D matrix, got {sys!r}")
        return _static(D, True)
    if isinstance(sys, control.TransferFunction):
        sys = control.ss(sys)
    if isinstance(sys, control.StateSpace) and sys.nstates == 0:
        if not np.all(np.isfinite(np.asarray(sys.D, dtype=float))):
            raise DataError("the system's D contains NaN or infinite values")
        return sys
    return as_discrete_system(sys, "sys", hint="Markov parameters and Γ are defined for discrete-time systems")
