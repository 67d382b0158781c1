"""Input checking shared by the whole toolkit.

Every public entry point funnels user data through these helpers so that bad
input fails early with an exception that names the problem and the fix.
"""
from __future__ import annotations

import numbers

import numpy as np

from .exceptions import DataError, InputTypeError

__all__ = ["DataError", "InputTypeError", "as_signal", "as_discrete_system", "to_state_space", "check_same_dt",
           "check_predictor_dt", "check_horizon", "check_level", "check_nonnegative", "check_sample_time", "check_flag",
           "check_count", "check_instance", "as_real_array"]


def as_signal(x, name: str, *, n: int | None = None, width: int | None = None, record: bool = True) -> np.ndarray:
    """Return ``x`` as a float array of shape ``(n, k)`` (time along axis 0).

    Parameters
    ----------
    x : array_like, shape (n,) or (n, k)
        A sampled signal; a 1-D array is one channel.
    name : str
        Name used in error messages (``"u"``, ``"y"``, ...).
    n : int, optional
        Required number of samples.
    width : int, optional
        Required number of channels.
    record : bool
        ``x`` is a whole record (the default): a 2-D array with more columns than rows is then
        taken for a record with time along axis 1 and refused, naming the fix ``x.T``.  Pass
        False for short windows (past samples of a controller, one new sample).

    Raises
    ------
    DataError
        If ``x`` is complex, not 1-D or 2-D, is empty, contains NaN/inf, has the wrong
        length or number of channels, or (``record=True``) more channels than samples.

    Examples
    --------
    >>> import numpy as np
    >>> as_signal(np.arange(3.0), "u").shape
    (3, 1)
    >>> as_signal(np.ones((1, 500)), "u")
    Traceback (most recent call last):
    ...
    synthesis.exceptions.DataError: u has shape (1, 500): more channels (500) than samples (1); time runs along axis 0: pass u.T (shape (500, 1))
    """
    try:
        raw = np.asarray(x)  # once: the complex and text checks and the float conversion all read it
    except (TypeError, ValueError) as exc:  # a ragged nested list
        raise DataError(f"{name} must be a numeric array, got {type(x).__name__}") from exc
    if raw.dtype.kind == "c":
        raise DataError(
            f"{name} is complex; the toolkit works on real sampled signals (pass the real part explicitly "
            "if that is what you mean)")
    if raw.dtype.kind in "US":  # numpy would parse "1.5" as a number: text is not a signal
        raise DataError(f"{name} must be a numeric array, got text; read the file as numbers (e.g. "
                        "experiments.load_record, or np.loadtxt) before passing it")
    try:
        arr = raw.astype(float, copy=False)
    except (TypeError, ValueError) as exc:
        raise DataError(f"{name} must be a numeric array, got {type(x).__name__}") from exc
    x_was_2d = arr.ndim == 2
    if arr.ndim == 1:
        arr = arr[:, None]
    if arr.ndim != 2:
        raise DataError(
            f"{name} must have shape (n,) or (n, channels) with time along axis 0; "
            f"got an array with {arr.ndim} dimensions"
        )
    if arr.shape[0] == 0 or arr.shape[1] == 0:
        raise DataError(f"{name} is empty (shape {arr.shape})")
    if record and x_was_2d and arr.shape[1] > arr.shape[0]:
        raise DataError(
            f"{name} has shape {arr.shape}: more channels ({arr.shape[1]}) than samples ({arr.shape[0]}); "
            f"time runs along axis 0: pass {name}.T (shape ({arr.shape[1]}, {arr.shape[0]}))")
    if not np.all(np.isfinite(arr)):
        bad = int(np.count_nonzero(~np.isfinite(arr)))
        raise DataError(f"{name} contains {bad} NaN or infinite value(s); clean or interpolate the data first")
    if n is not None and arr.shape[0] != n:
        raise DataError(
            f"{name} has {arr.shape[0]} samples but {n} were expected (all signals must have the same length)"
        )
    if width is not None and arr.shape[1] != width:
        # a short window given with time along axis 1 reaches here (the record check above is off for windows)
        turned = (f"; with time along axis 1 (shape {arr.shape}) pass {name}.T"
                  if arr.shape[0] == width and arr.ndim == 2 else "")
        raise DataError(f"{name} has {arr.shape[1]} channel(s) but {width} were expected{turned}")
    return arr


def as_real_array(x, name: str, *, error=DataError) -> np.ndarray:
    """``x`` as a float array of any shape, refusing what ``np.asarray(x, dtype=float)`` would mangle.

    A complex array would lose its imaginary part with only a ``ComplexWarning``, a string would be
    parsed as a number (``"0.5"``) or fail with numpy's bare ``ValueError``; for a matrix, a gain or
    a sample no shape or finiteness is checked here (the callers know what they need).

    Parameters
    ----------
    x : array_like
        Real numbers (Python's or numpy's, a bool array counts as 0/1).
    name : str
        Name used in error messages.
    error : type, optional
        Exception class raised (a :class:`DataError` subclass, e.g. ``ControllerFileError``).

    Raises
    ------
    error
        If ``x`` is complex, holds strings or is not numeric.

    Examples
    --------
    >>> as_real_array([[1, 2]], "A")
    array([[1., 2.]])
    >>> as_real_array([1j, 0], "A")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    synthesis.exceptions.DataError: A is complex; ...: take the real part (np.real) first if the imaginary part is ...
    >>> as_real_array("0.5", "rcond")
    Traceback (most recent call last):
    ...
    synthesis.exceptions.DataError: rcond must be real numbers, not text ('0.5'): use numbers (e.g. 0.5, not '0.5')
    """
    try:
        arr = np.asarray(x)
    except (TypeError, ValueError) as exc:  # a ragged nested list
        raise error(f"{name} must be an array of real numbers, got {type(x).__name__} that numpy cannot make an "
                    f"array of ({exc})") from exc
    if arr.dtype.kind == "c":
        raise error(f"{name} is complex; the toolkit works with real numbers: take the real part (np.real) first "
                    "if the imaginary part is only rounding")
    if arr.dtype.kind in "US":
        shown = repr(x) if len(repr(x)) <= 40 else repr(x)[:37] + "..."
        raise error(f"{name} must be real numbers, not text ({shown}): use numbers (e.g. 0.5, not '0.5')")
    # objects numpy could not type (None, a Python complex among them, a dict): float() of None is nan, so check
    if arr.dtype.kind == "O" and not all(isinstance(v, numbers.Real) for v in arr.flat):
        raise error(f"{name} must be an array of real numbers, got {type(x).__name__} {x!r:.40}")
    return arr.astype(float, copy=False)


def check_horizon(horizon, n_samples: int | None = None, *, min_columns: int = 1, name: str = "horizon") -> int:
    """Validate the prediction horizon ``i`` (and, given ``n``, that ``j = n - 2i + 1 >= min_columns``); ``name``
    is what the message calls it (an option's field, e.g. ``"DesignSearch.horizons entry"``).

    Examples
    --------
    >>> import numpy as np
    >>> check_horizon(np.int64(10), 100)
    10
    >>> check_horizon(10, 15)
    Traceback (most recent call last):
    ...
    synthesis.exceptions.DataError: too few samples for horizon i=10: n=15 gives j = n - 2i + 1 = -4 columns, need at least 1; collect at least 20 samples or reduce the horizon
    """
    i = check_count(horizon, name, 1)
    if n_samples is not None:
        j = n_samples - 2 * i + 1
        if j < min_columns:
            raise DataError(
                f"too few samples for horizon i={i}: n={n_samples} gives j = n - 2i + 1 = {j} columns, "
                f"need at least {min_columns}; collect at least {2 * i - 1 + min_columns} samples or reduce the horizon"
            )
    return i


def as_discrete_system(sys, name: str, *, hint: str = ""):
    """Return ``sys`` as a discrete-time python-control ``StateSpace`` with finite matrices.

    Parameters
    ----------
    sys : control.StateSpace or control.TransferFunction
        A discrete-time LTI system (``dt > 0`` or ``dt=True``).
    name : str
        Name used in error messages (``"P"``, ``"plant"``, ...).
    hint : str, optional
        Extra advice appended to the continuous-time error.

    Raises
    ------
    InputTypeError
        If ``sys`` is not a python-control LTI system.
    DataError
        If ``sys`` is continuous time, has NaN/inf entries or is a transfer function that is not proper.

    Examples
    --------
    >>> import control
    >>> P = as_discrete_system(control.tf([0.5], [1, -0.8], 0.1), "P")
    >>> type(P).__name__, P.nstates, P.dt
    ('StateSpace', 1, 0.1)
    >>> as_discrete_system(control.tf([1], [1, 1]), "P")
    Traceback (most recent call last):
    ...
    synthesis.exceptions.DataError: P is continuous-time (dt = 0); discretise it first (e.g. control.c2d(sys, dt, 'zoh'))
    """
    import control  # local: keeps the numpy-only helpers importable without python-control

    sys = to_state_space(sys, name)
    if not isinstance(sys, control.StateSpace):
        raise InputTypeError(
            f"{name} must be a python-control StateSpace or TransferFunction, got {type(sys).__name__}; "
            "build it with control.ss(A, B, C, D, dt) or control.tf(num, den, dt)")
    if not control.isdtime(sys, strict=True):
        raise DataError(
            f"{name} is continuous-time (dt = 0); discretise it first (e.g. control.c2d(sys, dt, 'zoh'))"
            + (f"; {hint}" if hint else ""))
    for mat in (sys.A, sys.B, sys.C, sys.D):
        if not np.all(np.isfinite(mat)):
            raise DataError(f"{name} has NaN or infinite entries")
    return sys


def check_level(value, name: str, *, allow_inf: bool = False, minimum: float = 0.0,
                maximum: float | None = None) -> float:
    """Return ``value`` as a float ``> minimum`` (a level γ, a ratio, a tolerance, ...), and ``< maximum`` if given.

    Parameters
    ----------
    value : real number
        The value to check; ``bool`` and strings are refused.
    name : str
        Name used in error messages (``"gamma"``, ``"gamma_ratio"``, ...).
    allow_inf : bool
        Accept ``+inf`` (e.g. ``gamma = inf``, the LQ limit).
    minimum : float
        Strict lower bound.
    maximum : float, optional
        Strict upper bound (e.g. 1 for a significance level in (0, 1)).

    Raises
    ------
    DataError
        If ``value`` is not a real number, is NaN, is infinite (unless allowed), ``<= minimum`` or ``>= maximum``.

    Examples
    --------
    >>> check_level(1.1, "gamma_ratio", minimum=1.0)
    1.1
    >>> check_level("2", "gamma")
    Traceback (most recent call last):
    ...
    synthesis.exceptions.DataError: gamma must be a real number > 0, got '2'
    >>> check_level(0.05, "level", maximum=1.0)
    0.05
    >>> check_level(None, "level", maximum=1.0)
    Traceback (most recent call last):
    ...
    synthesis.exceptions.DataError: level must be a real number in (0, 1), got None
    """
    bounds = f"> {minimum:g}" if maximum is None else f"in ({minimum:g}, {maximum:g})"
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise DataError(f"{name} must be a real number {bounds}, got {value!r}")
    v = float(value)
    if np.isnan(v) or not v > minimum or (np.isinf(v) and not allow_inf) or (maximum is not None and not v < maximum):
        raise DataError(f"{name} must be a {'' if allow_inf else 'finite '}number {bounds}, got {value!r}")
    return v


def check_nonnegative(value, name: str, *, allow_inf: bool = False) -> float:
    """Return ``value`` as a float ``>= 0`` (a bound that may be 0: a δ, a tracking floor, ...).

    Parameters
    ----------
    value : real number
        The value to check; ``bool`` and strings are refused.
    name : str
        Name used in error messages.
    allow_inf : bool
        Accept ``+inf``.

    Raises
    ------
    DataError
        If ``value`` is not a real number, is NaN, negative, or infinite (unless allowed).

    Examples
    --------
    >>> check_nonnegative(0, "delta")
    0.0
    >>> check_nonnegative(float("nan"), "delta")
    Traceback (most recent call last):
    ...
    synthesis.exceptions.DataError: delta must be a finite number >= 0, got nan
    """
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not (
            (np.isfinite(value) or (allow_inf and value == np.inf)) and value >= 0):
        raise DataError(f"{name} must be a finite number >= 0{' or inf' if allow_inf else ''}, got {value!r}")
    return float(value)


def check_sample_time(dt, name: str = "dt", *, allow_true: bool = True, error=DataError):
    """Return a valid discrete sample time: a positive finite float, or ``True`` (unspecified).

    ``error``: the class raised (a :class:`DataError` subclass, e.g. ``WeightError``).

    Raises
    ------
    error
        If ``dt`` is 0 / ``False`` / ``None`` (continuous time), negative, NaN, infinite or not a number.

    Examples
    --------
    >>> check_sample_time(1), check_sample_time(True)
    (1.0, True)
    >>> check_sample_time(True, allow_true=False)
    Traceback (most recent call last):
    ...
    synthesis.exceptions.DataError: dt must be a positive finite sample time, got True; 0 or None would mean continuous time
    >>> check_sample_time(0, "Ts")
    Traceback (most recent call last):
    ...
    synthesis.exceptions.DataError: Ts must be a positive finite sample time or True (unspecified), got 0; 0 or None would mean continuous time
    """
    if dt is True and allow_true:
        return True
    if isinstance(dt, bool) or not isinstance(dt, numbers.Real) or not (np.isfinite(dt) and dt > 0):
        allowed = "a positive finite sample time" + (" or True (unspecified)" if allow_true else "")
        raise error(f"{name} must be {allowed}, got {dt!r}; 0 or None would mean continuous time")
    return float(dt)


def to_state_space(sys, name: str, *, error=DataError):
    """Convert a python-control ``TransferFunction`` to ``StateSpace`` after checking it; pass anything else through.

    Parameters
    ----------
    sys : object
        Typically a ``control.TransferFunction`` or ``control.StateSpace``.
    name : str
        Name used in error messages.
    error : type, optional
        Exception class raised (a :class:`DataError` subclass, e.g. ``WeightError``).

    Raises
    ------
    error
        If a transfer function has NaN/inf coefficients, a zero denominator, or is not proper
        (numerator degree above the denominator's: not causal, no state-space realisation).
    """
    import control

    if not isinstance(sys, control.TransferFunction):
        return sys
    for i, (nums, dens) in enumerate(zip(sys.num, sys.den)):
        for j, (num, den) in enumerate(zip(nums, dens)):
            where = f" (output {i}, input {j})" if sys.noutputs * sys.ninputs > 1 else ""
            num, den = np.atleast_1d(np.asarray(num, float)), np.atleast_1d(np.asarray(den, float))
            if not (np.all(np.isfinite(num)) and np.all(np.isfinite(den))):
                raise error(f"{name} has NaN or infinite transfer-function coefficients{where}; "
                            "check how the weight or system was computed")
            den_nz, num_nz = np.flatnonzero(den), np.flatnonzero(num)
            if den_nz.size == 0:
                raise error(f"{name} has a zero denominator{where}")
            deg_den = den.size - 1 - den_nz[0]
            deg_num = num.size - 1 - num_nz[0] if num_nz.size else 0
            if deg_num > deg_den:
                raise error(
                    f"{name} is not proper{where}: numerator degree {deg_num} > denominator degree {deg_den}, "
                    "so it is not causal and has no state-space realisation; add poles (e.g. a far-away "
                    "low-pass factor) or remove zeros")
    try:
        return control.ss(sys)
    except (ValueError, np.linalg.LinAlgError) as exc:  # pragma: no cover - defensive
        raise error(f"{name} could not be converted to state space: {exc}") from exc


def check_same_dt(a, b, name_a: str, name_b: str) -> None:
    """Raise :class:`DataError` unless two discrete systems share a sample time (``True`` matches any).

    Examples
    --------
    >>> import control
    >>> P = control.tf([0.5], [1, -0.8], 0.1)
    >>> check_same_dt(P, control.tf([1, -0.5], [1, -0.9], True), "P", "W1")   # True matches any: no error
    >>> check_same_dt(P, control.tf([1, -0.5], [1, -0.9], 0.2), "P", "W1")
    Traceback (most recent call last):
    ...
    synthesis.exceptions.DataError: P has sample time 0.1 but W1 has 0.2; both must be discretised at the same sample time (e.g. control.c2d(G, 0.2, 'zoh') or synthesis.tustin(W, 0.2))
    """
    da, db = a.dt, b.dt
    if da is True or db is True or da == db or (da and db and np.isclose(float(da), float(db), rtol=1e-12)):
        return
    raise DataError(
        f"{name_a} has sample time {da} but {name_b} has {db}; both must be discretised at the same sample "
        f"time (e.g. control.c2d(G, {db}, 'zoh') or synthesis.tustin(W, {db}))")


def check_predictor_dt(pred, dt, *, error=DataError):
    """The data's sample time: ``dt`` if given, else the predictor's (``fit_predictor(..., dt=)``); both must agree.

    Parameters
    ----------
    pred : synthesis.Predictor or object
        A predictor; one without a ``dt`` attribute (or with ``dt=None``) carries no sample time.
    dt : float, True or None
        The sample time the caller was given (None: not given).  Not validated here when the
        predictor carries none: the caller checks it (:func:`check_sample_time`).
    error : type, optional
        Exception class raised (a :class:`DataError` subclass, e.g. ``WeightError``).

    Returns
    -------
    float, True or None
        ``dt``, or the predictor's when ``dt`` is None (None when neither has one).

    Raises
    ------
    error
        If ``dt`` is given and differs from the predictor's (``True``, unspecified, differs too: the
        predictor's is known).

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> check_predictor_dt(SimpleNamespace(dt=0.5), None), check_predictor_dt(SimpleNamespace(dt=None), 1.0)
    (0.5, 1.0)
    >>> check_predictor_dt(SimpleNamespace(dt=0.5), 1.0)
    Traceback (most recent call last):
    ...
    synthesis.exceptions.DataError: dt = 1.0 but the predictor was fitted on data sampled at 0.5 (Predictor.dt); pass the data's sample time once: drop dt= or refit with fit_predictor(u, y, i, dt=...)
    """
    pdt = getattr(pred, "dt", None)
    if pdt is None:
        return dt
    if dt is None:
        return pdt
    if isinstance(dt, bool) or not isinstance(dt, numbers.Real) or not np.isclose(float(dt), float(pdt), rtol=1e-9,
                                                                                    atol=0):
        raise error(
            f"dt = {dt!r} but the predictor was fitted on data sampled at {pdt} (Predictor.dt); pass the data's "
            "sample time once: drop dt= or refit with fit_predictor(u, y, i, dt=...)")
    return dt


def check_flag(value, name: str, *, error=DataError) -> bool:
    """``value`` as a bool when it is one (Python's or numpy's), else ``DataError``: a string such as ``"no"`` is
    truthy, and reading it as True would silently do the opposite of what was asked.  ``error``: the class
    raised (a :class:`DataError` subclass, e.g. ``WeightError``).

    Examples
    --------
    >>> check_flag(True, "causal"), check_flag(np.bool_(False), "causal")
    (True, False)
    >>> check_flag("no", "causal")
    Traceback (most recent call last):
    ...
    synthesis.exceptions.DataError: causal must be True or False, got 'no'
    """
    if not isinstance(value, (bool, np.bool_)):
        raise error(f"{name} must be True or False, got {value!r}")
    return bool(value)


def check_count(value, name: str, least: int, *, error=DataError) -> int:
    """``value`` as an int ≥ ``least`` (an integer type, Python's or numpy's, not a bool), else ``error`` naming
    ``name``: a float such as ``5.0`` or ``5.5`` is refused, not rounded.

    Examples
    --------
    >>> check_count(np.int64(3), "rows", 1)
    3
    >>> check_count(2.0, "rows", 1)
    Traceback (most recent call last):
    ...
    synthesis.exceptions.DataError: rows must be an integer ≥ 1, got 2.0
    """
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Integral) or value < least:
        raise error(f"{name} must be an integer ≥ {least}, got {value!r}")
    return int(value)


def check_instance(value, types, name: str, what: str):
    """``value`` when it is an instance of ``types``, else :class:`InputTypeError` naming ``name`` and ``what`` is
    expected: an object of another type would otherwise fail deep inside with an ``AttributeError``.

    Examples
    --------
    >>> check_instance(3.0, float, "gain", "a float")
    3.0
    >>> check_instance("P", float, "gain", "a float (e.g. 0.5)")
    Traceback (most recent call last):
    ...
    synthesis.exceptions.InputTypeError: gain must be a float (e.g. 0.5), got str 'P'
    """
    if not isinstance(value, types):
        shown = repr(value) if len(repr(value)) <= 60 else repr(value)[:57] + "..."
        raise InputTypeError(f"{name} must be {what}, got {type(value).__name__} {shown}")
    return value


def check_output_moves(y: np.ndarray, where: str) -> None:
    """Raise DataError when an output channel is constant on every sample of ``where``: it holds no response to the
    input.  Without this a zero output reached σ = "auto" = 0 and was refused as "sigma must be > 0", and a constant
    one (fitted exactly by y_k = y_{k−1}) as "noise-free data": neither names the slip, a wrong output column or a
    sensor that recorded nothing.

    Examples
    --------
    >>> import numpy as np
    >>> check_output_moves(np.array([0.1, 0.3, 0.2]), "the record")          # moves: nothing to say
    >>> check_output_moves(np.column_stack([[0.1, 0.3, 0.2], [2.0, 2.0, 2.0]]), "the record")
    Traceback (most recent call last):
    ...
    synthesis.exceptions.DataError: output 1 is constant (2) on every sample of the record: it holds no response ...
    """
    y = np.asarray(y, dtype=float).reshape(np.shape(y)[0], -1)
    flat = [k for k in range(y.shape[1]) if y.shape[0] and np.ptp(y[:, k]) == 0.0]
    if flat:
        k = flat[0]
        name = "the output" if y.shape[1] == 1 else f"output {k}"
        raise DataError(
            f"{name} is constant ({y[0, k]:.4g}) on every sample of {where}: it holds no response to the input, so the "
            "data say nothing of the plant; check that the output column is the sensor's (y=, or --y of python -m "
            "experiments design) and that the sensor recorded (a disconnected or saturated sensor reads a constant)")


def check_inputs_move(u: np.ndarray, where: str, *, each_channel: bool = True) -> None:
    """Raise DataError when an input channel is zero on every sample of ``where``: the record holds no response to
    it.  Without this :func:`~synthesis.fit_predictor` went on with a ``PersistenceWarning`` and returned
    ``L_u ≈ 0``, from which ``hinf_design`` built a controller with no word about the control's effect (the F-test
    of ``L_u = 0`` has no power then).  An input at rest for part of the record moves.

    ``each_channel=False`` refuses only an input that is zero everywhere (``u`` of any shape, e.g. the block Hankel
    ``U_f`` of a window): the unfalsification programs, where no output is then a response, δ is undefined, and
    their noise-floor refusal would blame σ and the window instead.

    Examples
    --------
    >>> import numpy as np
    >>> check_inputs_move(np.array([0.0, 0.0, 1.0, -1.0]), "the record")    # at rest, then moving: accepted
    >>> check_inputs_move(np.zeros((4, 1)), "the record")
    Traceback (most recent call last):
    ...
    synthesis.exceptions.DataError: the input is zero on every sample of the record: the data hold no response to ...

    One channel of zeros among moving ones: refused channel by channel, accepted as a whole:

    >>> two = np.column_stack([[0.0, 1.0, -1.0, 1.0], np.zeros(4)])
    >>> check_inputs_move(two, "the record")
    Traceback (most recent call last):
    ...
    synthesis.exceptions.DataError: input u[:, 1] is zero on every sample of the record: the data hold no response ...
    >>> check_inputs_move(two, "the record", each_channel=False)
    """
    u = np.asarray(u, dtype=float)
    if each_channel:
        u = u.reshape(np.shape(u)[0], -1)
        dead = [k for k in range(u.shape[1]) if not np.any(u[:, k])]
    else:
        dead = [] if np.any(u) else [0]
    if dead:
        name = f"input u[:, {dead[0]}]" if each_channel and u.shape[1] > 1 else "the input"
        raise DataError(
            f"{name} is zero on every sample of {where}: the data hold no response to it; use a record whose input "
            "moves (a PRBS or a multisine; a constant input with its mean subtracted, `--detrend mean`, is zero), or "
            "check the input column (u=, or --u of python -m experiments design)")
