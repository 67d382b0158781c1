"""``python -m experiments design DATA``: from a measured record to a certified (or refused) controller.

The §7.4 workflow on a data file, with no simulator behind it:

1. :func:`experiments.load_record` reads the input and output channels (CSV, NPZ or MAT; ``--u`` and ``--y``
   take comma lists for several) and the sample time (``--dt``, or the step of a time column ``--t``, by default a
   CSV column or an NPZ/MAT array named t or time, also with a unit in brackets: ``time [s]``);
   ``--detrend mean`` subtracts the record's means (an operating point: the models have no constant term), and
   without it the report names any channel whose mean is large (:func:`operating_point`);
2. :func:`unfalsify.robust_design_from_data` in record mode: the (7.5) window (``--window``), σ
   (``--sigma``), the predictors fitted on the first two thirds of the record and the premise of
   the certificate tested on the last third; the design search; the certificate of the loop;
3. the report ``<out>/design/design.md`` (data, the model's output error, δ with its two-sided
   certificate and which δ decided, the search, the verdict and its reason, step and Bode plots
   of the loop on P̂), the controller as ``controller.npz`` and ``controller.mat``
   (:func:`synthesis.save_controller`) and the summary ``design.json``.

``--quick`` is accepted (every subcommand takes it) and changes nothing: the record sets the sizes.
A refusal is a result, not an error: the command exits 0 whether or not the loop is certified and
the report says why.  Bad input (a missing file, NaN, a non-uniform time column, a bad window) ends
the command with an argparse-style message and exit status 2.

Default weights (when neither ``--weights`` nor ``--w1/--w2`` is given) mirror the shape of the §5.4
weights W11, W21 relative to the Nyquist frequency ``ω_N = π/dt`` (at the servo's 10 Hz, W11 crosses
1 near ω_N/30 and W21 passes 0.3 near ω_N/10):

* ``W1 = makeweight(100, (ω_N/30, 1), 0.2, dt)``: performance, 100 at DC falling to 0.2;
* ``W2 = makeweight(0.05, (ω_N/10, 0.3), 1, dt)``: control effort, 0.05 at DC rising to 1.

``--weights W1FILE W2FILE`` reads two weights saved with :func:`synthesis.save_controller` (one
system per file, ``.npz`` or ``.mat``); ``--w1 DC,FREQ,MAG,HF`` (FREQ in rad/s) builds one with
:func:`synthesis.makeweight`.  An output ``--tracking-floor`` leaves untracked (``inf``) gets the static
weight :data:`UNTRACKED_WEIGHT` in W1 (defaults and ``--w1``; weights from files are used as given).
"""
from __future__ import annotations

import dataclasses
import math
import time
import warnings
from pathlib import Path

import numpy as np

from synthesis.validation import DataError

from ..lab.records import RecordError, load_record, record_columns, text_columns, time_unit

__all__ = ["run", "summary_lines", "design_record", "default_weights", "parse_window", "parse_tracking_floor",
           "untracked_outputs", "operating_point", "scale_note", "INPUT_ERRORS", "UNTRACKED_WEIGHT", "SCALE_NOTE"]

#: errors that mean bad input, not a bug: ``cli.main`` turns them into a usage message and exit status 2
INPUT_ERRORS = (DataError, FileNotFoundError)

#: names a CSV time column is recognised by when ``--t`` is not given
_TIME_NAMES = ("t", "time", "time_s", "times", "seconds")

#: ``(dc, crossover as a fraction of Nyquist, gain there, hf)`` of the default weights
W1_DEFAULT = (100.0, 1.0 / 30.0, 1.0, 0.2)
W2_DEFAULT = (0.05, 1.0 / 10.0, 0.3, 1.0)


def default_weights(dt: float, inputs: int = 1, outputs: int = 1, untracked=()) -> tuple:
    """The default W1, W2 at sample time ``dt`` (module docstring) and a sentence stating them.

    Parameters
    ----------
    dt : float
        Sample time of the record.
    inputs, outputs : int
        The record's channels: W1 is ``outputs × outputs`` and W2 ``inputs × inputs``, the same
        weight on every channel (:func:`synthesis.diagonal_weight`).
    untracked : sequence of int
        Outputs not tracked (``--tracking-floor`` ``inf``): W1 weighs them by the static
        :data:`UNTRACKED_WEIGHT` instead, so the design does not chase them.

    Returns
    -------
    W1, W2 : control.StateSpace
        First-order discrete weights (:func:`synthesis.makeweight`).
    text : str
        What they are, for the report.

    Examples
    --------
    >>> W1, W2, text = default_weights(0.1)
    >>> W1.ninputs, W2.ninputs, text.startswith("W1 = makeweight(100")
    (1, 1, True)
    >>> W1, W2, _ = default_weights(1.0, inputs=2, outputs=3)
    >>> W1.ninputs, W2.ninputs
    (3, 2)
    >>> W1, _, text = default_weights(1.0, inputs=1, outputs=2, untracked=[1])
    >>> W1.nstates, float(W1.D[1, 1]), text.endswith("output 1 (not tracked)")
    (1, 0.01, True)
    """
    from synthesis import makeweight

    wn = math.pi / dt
    parts, text = [], []
    for name, (dc, frac, mag, hf) in (("W1", W1_DEFAULT), ("W2", W2_DEFAULT)):
        parts.append(makeweight(dc, (frac * wn, mag), hf, dt))
        text.append(f"{name} = makeweight({dc:g}, ({frac * wn:.4g} rad/s = ω_N/{1 / frac:g}, {mag:g}), {hf:g}, dt)")
    W1, W2 = _diagonal(parts[0], outputs, untracked), _diagonal(parts[1], inputs)
    note = "" if inputs == outputs == 1 else ", the same on every channel (diagonal)"
    return W1, W2, "; ".join(text) + f" (ω_N = π/dt = {wn:.4g} rad/s){note}" + _untracked_text(untracked)


#: W1's static weight on an output that is not tracked (``--tracking-floor`` ``inf``), as in the MIMO pipeline
#: study: with fewer inputs than outputs the loop cannot track every output, and the same W1 on all of them made
#: the design trade the tracked output's error against the others' (a step error 0.14–0.94 on output 0 of three
#: one-input two-output records, none certified; all three certified with this weight)
UNTRACKED_WEIGHT = 0.01


def _diagonal(W, channels: int, untracked=()):
    """``W`` on every channel, or :data:`UNTRACKED_WEIGHT` on the channels in ``untracked``."""
    from synthesis import diagonal_weight

    if channels == 1 and not untracked:
        return W
    return diagonal_weight(*(UNTRACKED_WEIGHT if k in untracked else W for k in range(channels)))


def _untracked_text(untracked) -> str:
    if not untracked:
        return ""
    outs = ", ".join(str(k) for k in untracked)
    return f"; W1 = {UNTRACKED_WEIGHT:g} (static) on output{'s' if len(untracked) > 1 else ''} {outs} (not tracked)"


def untracked_outputs(floor) -> tuple:
    """The outputs ``--tracking-floor`` leaves untracked (floor ``inf``): indices, empty for one floor.

    Examples
    --------
    >>> untracked_outputs((0.1, float("inf"), float("inf"))), untracked_outputs(0.1), untracked_outputs(None)
    ((1, 2), (), ())
    """
    if floor is None or np.ndim(floor) == 0:
        return ()
    return tuple(k for k, f in enumerate(floor) if math.isinf(f))


def _weight_from_spec(spec: str, dt: float, what: str):
    """``"DC,FREQ,MAG,HF"`` → ``makeweight(DC, (FREQ, MAG), HF, dt)``."""
    from synthesis import makeweight

    try:
        dc, freq, mag, hf = (float(x) for x in spec.split(","))
    except ValueError:
        raise DataError(f"--{what} must be four numbers DC,FREQ,MAG,HF (FREQ in rad/s), got {spec!r}") from None
    return makeweight(dc, (freq, mag), hf, dt)


def _weights(extra: dict, dt: float, inputs: int = 1, outputs: int = 1, untracked=()) -> tuple:
    """W1, W2 and how they were chosen, from ``--weights`` / ``--w1 --w2`` or the defaults (``untracked``: outputs
    W1 weighs by :data:`UNTRACKED_WEIGHT`; weights read from files are the user's, as given)."""
    files, w1, w2 = extra.get("weights"), extra.get("w1"), extra.get("w2")
    if files and (w1 or w2):
        raise DataError("pass either --weights W1FILE W2FILE or --w1/--w2, not both")
    if files:
        from synthesis import load_controller

        W1, W2 = (load_controller(f) for f in files)
        for name, W, f in (("W1", W1, files[0]), ("W2", W2, files[1])):
            if W.dt is not True and not math.isclose(float(W.dt), dt, rel_tol=1e-9):
                raise DataError(f"{name} from {f!r} has sample time {W.dt} but the record's is {dt:g}; "
                                "save the weights at the record's sample time")
        return W1, W2, f"W1 from {files[0]}, W2 from {files[1]}"
    if bool(w1) != bool(w2):
        raise DataError("pass both --w1 and --w2 (or neither, for the defaults)")
    if w1:
        return (_diagonal(_weight_from_spec(w1, dt, "w1"), outputs, untracked),
                _diagonal(_weight_from_spec(w2, dt, "w2"), inputs),
                f"W1 = makeweight({w1}) and W2 = makeweight({w2}) (DC, FREQ rad/s, MAG, HF; given"
                + ("" if inputs == outputs == 1 else "; the same on every channel") + ")" + _untracked_text(untracked))
    return default_weights(dt, inputs, outputs, untracked)


def parse_window(text: str | None):
    """``"START:LEN"`` → ``(start, length)``; ``"auto"`` or None → ``"auto"``.

    Raises
    ------
    DataError
        Anything else.
    """
    if text is None or text.strip().lower() == "auto":
        return "auto"
    try:
        start, length = (int(x) for x in text.split(":"))
    except ValueError:
        raise DataError(f"--window must be START:LEN (samples, e.g. 0:49) or auto, got {text!r}") from None
    if start < 0 or length <= 0:
        raise DataError(f"--window {text}: START must be >= 0 and LEN > 0")
    return start, length


def _parse_sigma(text):
    if text is None or str(text).strip().lower() == "auto":
        return "auto"
    try:
        return float(text)
    except ValueError:
        raise DataError(f"--sigma must be a positive number or auto, got {text!r}") from None


def parse_tracking_floor(text):
    """``"F"`` or ``"F1,F2,..."`` (one floor per output channel; ``inf`` for an output not tracked) → a float or a
    tuple; None → None (the certificate's default).

    Raises
    ------
    DataError
        Anything but numbers ≥ 0 or ``inf``.

    Examples
    --------
    >>> parse_tracking_floor("0.2"), parse_tracking_floor("0.1, inf")
    (0.2, (0.1, inf))
    """
    if text is None:
        return None
    try:
        floors = tuple(float(x) for x in str(text).split(","))
    except ValueError:
        floors = ()
    if not floors or any(not f >= 0.0 for f in floors):
        raise DataError(f"--tracking-floor must be a number >= 0 or one per output channel (e.g. 0.1,inf: output 1 "
                        f"not tracked), got {text!r}")
    return floors[0] if len(floors) == 1 else floors


def _column(text):
    """A column given on the command line: an integer index or a name; a comma list stays a list."""
    if text is None:
        return None
    items = [s.strip() for s in str(text).split(",")]
    items = [int(s) if s.lstrip("-").isdigit() else s for s in items]
    return items[0] if len(items) == 1 else items


def _select(path: Path, extra: dict):
    """The record's u, y, t selection: the user's, or the defaults (column after the time column, the next).

    Several channels: ``--u`` and ``--y`` take comma lists (names or indices).  A file with more than
    two signal columns and neither given is refused: which columns are inputs only the user knows.
    """
    variable = extra.get("variable")
    u, y, t = _column(extra.get("u")), _column(extra.get("y")), _column(extra.get("t"))
    names, width = record_columns(path, variable)
    if t is None and names is not None:
        # a CSV with a column called t/time: its step is the sample time (no --dt needed; with --dt, the two are
        # checked against each other), and it is never taken for a signal
        hits = [k for k, nm in enumerate(names) if _is_time_name(nm)]
        t = names[hits[0]] if hits else None
    elif t is None and width is None and variable is None:
        t = _time_array(path, u, y)
    if u is None or y is None:
        if width is None:
            u, y = ("u" if u is None else u), ("y" if y is None else y)  # NPZ/MAT arrays named u and y
        else:
            t_index = None if t is None else _time_index(t, names, width, path)
            # a column of text (a logger's status) is no signal: counted as one, it had made "t,u,y,status" a file of
            # "3 signal columns" that must name --u and --y, and without a header been offered as the output
            text = [k for k in text_columns(path) if k != t_index]
            rest = [k for k in range(width) if k != t_index and k not in text]
            taken = _chosen(u, y)
            free = [k for k in rest if k not in taken and not (names and names[k] in taken)]
            missing = " and ".join(f"--{w}" for w, sel in (("u", u), ("y", y)) if sel is None)
            left_out = _text_note(text, names)
            if len(rest) > 2 and len(free) > (u is None) + (y is None):
                cols = ", ".join(names[k] for k in rest) if names else f"{len(rest)} columns"
                raise RecordError(f"{str(path)!r} has {len(rest)} signal columns ({cols}{left_out}): say which are "
                                  "inputs with --u and which are outputs with --y (names or 0-based indices, "
                                  f"comma-separated for several channels, e.g. --u 0,1 --y 2,3); {missing} is missing")
            pick = (lambda k: names[k]) if names else (lambda k: k)
            if len(free) < (u is None) + (y is None):
                cols = ", ".join(names) if names else f"{width} columns"
                raise RecordError(f"{str(path)!r} ({cols}{left_out}) leaves no column for {missing} once the others "
                                  f"are taken; pass {missing} (names or 0-based indices)")
            if u is None:
                u, free = pick(free[0]), free[1:]
            if y is None:
                y = pick(free[0])
    return u, y, t, variable


def _text_note(text, names) -> str:
    """``"; status holds text, not a signal"`` for the text columns left out of the signals, '' without any."""
    if not text:
        return ""
    cols = ", ".join(names[k] if names else f"column {k}" for k in text)
    return f"; {cols} hold{'s' if len(text) == 1 else ''} text, not a signal"


def _time_array(path: Path, u, y):
    """An NPZ/MAT array named like a time column (t, time, …, as a CSV's), one-dimensional and not chosen as a signal;
    None when there is none or more than one.  A CSV's time column was read and an NPZ's ``t`` was not: the same
    record saved with ``numpy.savez(f, u=u, y=y, t=t)`` had been refused for want of a sample time."""
    from synthesis.export import read_variables

    chosen = _chosen(u, y)
    arrays = read_variables(path, error=RecordError)
    hits = [k for k, a in arrays.items() if _is_time_name(k) and k not in chosen
            and np.asarray(a).dtype.kind in "biuf" and np.size(a) > 1 and max(np.shape(a)) == np.size(a)]
    return hits[0] if len(hits) == 1 else None


def _is_time_name(name: str) -> bool:
    """A column or array named like a time column: t, time, … (:data:`_TIME_NAMES`, any case), also with a unit in
    brackets, ``time [s]`` or ``Time (ms)`` as loggers write them (such a column had not been found, and the record
    was refused for "no time column").  A unit that is not one of time (``Time (UTC)``, date-time stamps) is not: it
    cannot give the sample time, and taken for it, had refused the record even with ``--dt``."""
    bare, unit, seconds = time_unit(name)
    return bare.lower() in _TIME_NAMES and (unit is None or seconds is not None)


def _chosen(u, y) -> list:
    """The columns ``--u`` and ``--y`` name (each one column, a list of them, or None)."""
    return [c for sel in (u, y) if sel is not None for c in (sel if isinstance(sel, list) else [sel])]


def _time_index(t, names, width: int, path: Path) -> int:
    """The 0-based column of ``--t`` (a header name, or an index)."""
    if isinstance(t, str):
        if not names or t not in names:
            where = f"the header ({', '.join(names)})" if names else "a file without a header"
            raise RecordError(f"--t {t!r} is not a column of {str(path)!r}: {where}; pass the time column's name "
                              f"exactly, or its 0-based index")
        return names.index(t)
    if not -width <= int(t) < width:
        raise RecordError(f"--t {t} is not a column of {str(path)!r}, which has {width} (0-based indices)")
    return int(t) % width


def operating_point(rec, detrend: str = "none"):
    """The record about its operating point (``detrend="mean"``: the means of u and y subtracted) or as read, and
    what the report says about it.

    The predictor, P̂ and the controller have no constant term: a record taken around an operating point (an input
    between 0 and a level, a sensor bias) is read as dynamics (:func:`unfalsify.operating_point_note` says what that
    did on the adversarial catalogue).

    Returns
    -------
    record : Record
        ``rec``, or a copy with ``u − ū`` and ``y − ȳ``.
    point : dict
        ``{"u": ū, "y": ȳ, "removed": bool}`` (lists, one entry per channel).
    text : str
        The report's sentence: what was done, and how to apply the controller; or which channels have a mean
        above :data:`unfalsify.OFFSET_NOTE` of their standard deviation and the option that removes it
        (:func:`unfalsify.operating_point_note`).

    Examples
    --------
    >>> import numpy as np
    >>> from experiments.lab.records import Record
    >>> rec = Record(u=np.c_[[0.0, 2.0, 0.0, 2.0]], y=np.c_[[1.0, 1.5, 1.0, 1.5]], dt=1.0, source="x")
    >>> centred, point, text = operating_point(rec, "mean")
    >>> centred.u[:, 0].tolist(), point["y"], text.startswith("The record's means")
    ([-1.0, 1.0, -1.0, 1.0], [1.25], True)
    >>> print(operating_point(rec)[2][:48])
    The mean of u (1) is 1 times its standard deviat
    """
    from unfalsify import operating_point_note

    if detrend not in ("none", "mean"):
        raise DataError(f"--detrend must be none or mean, got {detrend!r}")
    mu, my = rec.u.mean(axis=0), rec.y.mean(axis=0)
    point = {"u": [float(v) for v in mu], "y": [float(v) for v in my], "removed": detrend == "mean"}
    if detrend == "mean":
        text = (f"The record's means (ū = {_vector(mu)}, ȳ = {_vector(my)}) were subtracted (`--detrend mean`): P̂, "
                "δ and the controller act on deviations from this operating point; feed the controller r − ȳ and "
                "y − ȳ and add ū to its output.")
        return dataclasses.replace(rec, u=rec.u - mu, y=rec.y - my), point, text
    note = operating_point_note(rec.u, rec.y)
    return rec, point, (note[0].upper() + note[1:] + "." if note else "")


def _vector(x) -> str:
    return f"{float(x[0]):.4g}" if len(x) == 1 else "[" + ", ".join(f"{float(v):.4g}" for v in x) + "]"


#: a record whose gain rms(y)/rms(u) lies outside [1/SCALE_NOTE, SCALE_NOTE], or whose inputs' (outputs') rms differ
#: by more than this factor, is named in the report: the default weights suit signals of comparable size
SCALE_NOTE = 100.0


def scale_note(rec, defaults: bool = True) -> str:
    """The report's sentence on the record's units, or ``""``: the weights are the same on every channel and the
    default W2 weighs the control effort in u's units, so they suit a gain ``rms(y)/rms(u)`` of order one.

    Measured (the hunt of 2026-11-28, three first-order-dominated plants, 1500 samples, horizon 8): a record whose
    gain the units made 1.6e-6 or 1.6e-4 was never certified with the default weights (the step did not track: "use a
    weight W1 with more gain at low frequency", which does not help), nor one of gain 1.7e6 (unstable on P̂); with W2
    times the gain, as this sentence proposes, all 15 records of gains 1.6e-6 … 1.7e6 were certified and held on the
    true plant.

    Parameters
    ----------
    rec : Record
        The record as designed on (after ``--detrend``).
    defaults : bool
        The default weights are used (neither ``--weights`` nor ``--w1/--w2``): only then is the scaled ``--w1 --w2``
        proposed.

    Examples
    --------
    >>> import numpy as np
    >>> from experiments.lab.records import Record
    >>> u = np.sign(np.sin(np.arange(200.0)))[:, None]
    >>> note = scale_note(Record(u=1e3 * u, y=1e-3 * u, dt=0.1, source="x"))
    >>> note.startswith("The record's gain rms(y)/rms(u) is 1e-06"), note.endswith("--w2 5e-08,3.14159,3e-07,1e-06.")
    (True, True)
    >>> scale_note(Record(u=u, y=2 * u, dt=0.1, source="x"))
    ''
    """
    rms = [np.sqrt(np.mean(np.square(x), axis=0)) for x in (rec.u, rec.y)]
    if not all(np.all(r > 0) for r in rms):
        return ""  # a silent channel: the pipeline's own checks name it
    parts = []
    for what, r, names in (("input", rms[0], rec.u_columns), ("output", rms[1], rec.y_columns)):
        if r.size > 1 and r.max() / r.min() > SCALE_NOTE:
            parts.append(f"the {what}s' rms range from {r.min():.3g} ({names[int(np.argmin(r))]}) to {r.max():.3g} "
                         f"({names[int(np.argmax(r))]})")
    text = []
    if parts:
        text.append("; ".join(parts) + ": the weights are the same on every channel, so the design weighs the "
                    "channels by their units; rescale them to comparable units (e.g. divide each by its rms) before "
                    "the design, or give a weight per channel with --weights")
    gain = float(np.exp(np.mean(np.log(rms[1])) - np.mean(np.log(rms[0]))))
    if defaults and not 1.0 / SCALE_NOTE <= gain <= SCALE_NOTE:
        wn = math.pi / rec.dt
        (d1, f1, m1, h1), (d2, f2, m2, h2) = W1_DEFAULT, W2_DEFAULT
        text.append(f"the record's gain rms(y)/rms(u) is {gain:.3g}: the default W2 ({d2:g} at DC) weighs the "
                    "control effort in u's units and suits a gain of order one; for the default design in these units "
                    f"pass W2 times {gain:.3g}: --w1 {d1:g},{f1 * wn:.6g},{m1:g},{h1:g} "
                    f"--w2 {d2 * gain:.6g},{f2 * wn:.6g},{m2 * gain:.6g},{h2 * gain:.6g}")
    return (". ".join(t[0].upper() + t[1:] for t in text) + ".") if text else ""


def design_record(u, y, dt: float, horizon: int, W1, W2, *, window="auto", sigma="auto", untested="warn",
                  feedthrough=False, tracking_floor=None):
    """Run :func:`unfalsify.robust_design_from_data` in record mode, catching the refusal warning; ``untested``,
    ``feedthrough`` and ``tracking_floor`` (None: the default) are those of :class:`unfalsify.CertificateOptions`.

    Returns
    -------
    result : unfalsify.RobustDesignResult
    warned : list of str
        The warnings raised (the ``NotCertifiedWarning`` of a refusal among them).
    """
    import unfalsify as uf

    floor = {} if tracking_floor is None else {"tracking_floor": tracking_floor}
    options = uf.CertificateOptions(untested=untested, feedthrough=feedthrough, **floor)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = uf.robust_design_from_data(_channels(u), _channels(y), horizon, W1, W2, sigma, dt=dt, window=window,
                                         certificate=options)
    return res, [f"{w.category.__name__}: {w.message}" for w in caught]


def _channels(x) -> np.ndarray:
    """A signal as ``(n,)`` for one channel (the SISO path) or ``(n, k)`` for several."""
    x = np.asarray(x, float)
    x = x.reshape(x.shape[0], -1)
    return x[:, 0] if x.shape[1] == 1 else x


def _fmt(x) -> str:
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return "—"
    return "∞" if x == math.inf else f"{x:.4g}"


def _simulate(sys, u):
    """Output of ``sys`` driven by ``u`` (n, m) from rest, (n, l) (NaN from where it blows up: an unstable P̂ does)."""
    from ..lab.simulate import lsim

    A, B, C, D = (np.atleast_2d(np.asarray(m, float)) for m in (sys.A, sys.B, sys.C, sys.D))
    u = np.asarray(u, float).reshape(np.shape(u)[0], -1)
    with np.errstate(all="ignore"):
        y = lsim(A, B, C, D, u, np.zeros(A.shape[0]))[0]
    y = np.asarray(y, float).reshape(u.shape[0], -1)
    y[~np.isfinite(y)] = np.nan
    return y


def _channel_labels(names, what: str) -> list[str]:
    return [f"{what} ({c})" for c in names] if len(names) > 1 else [f"{what} ({names[0]})"]


def _figures(out: Path, rec, res, fit_end: int, window: tuple[int, int]) -> tuple[list, dict]:
    """Data, output error, step and Bode plots; returns (paths, numbers for the report)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..lab.report import save_figure
    from ..lab.simulate import closed_loop_system

    u, y, dt = rec.u, rec.y, rec.dt
    t = np.arange(rec.n) * dt
    xlabel = "time (s)" if dt != 1 else "sample"
    figs, numbers = [], {}

    fig, (ax1, ax2) = plt.subplots(2, 1, sharex=True, figsize=(8, 4.5))
    for k, lab in enumerate(_channel_labels(rec.u_columns, "u")):
        ax1.plot(t, u[:, k], lw=0.7, label=lab)
    for k, lab in enumerate(_channel_labels(rec.y_columns, "y")):
        ax2.plot(t, y[:, k], lw=0.7, color=f"C{k + 1}", label=lab)
    for ax in (ax1, ax2):
        ax.axvspan(window[0] * dt, window[1] * dt, color="C2", alpha=0.15, label="(7.5) window")
        ax.axvline(fit_end * dt, color="k", ls="--", lw=0.8, label="held out from here")
        ax.legend(loc="upper right", fontsize=7)
    ax1.set_ylabel("input u")
    ax2.set_ylabel("output y")
    ax2.set_xlabel(xlabel)
    ax1.set_title("Record")
    figs.append(save_figure(fig, out / "data.png"))

    yhat = _simulate(res.model, u)
    err = y - yhat
    numbers["oe_rms_fit"] = float(np.sqrt(np.nanmean(err[:fit_end] ** 2)))
    numbers["oe_rms_held_out"] = float(np.sqrt(np.nanmean(err[fit_end:] ** 2)))
    numbers["y_rms"] = float(np.sqrt(np.mean(y ** 2)))
    fig, (ax1, ax2) = plt.subplots(2, 1, sharex=True, figsize=(8, 4.5))
    for k, name in enumerate(rec.y_columns):
        suffix = f" {name}" if rec.l > 1 else ""
        ax1.plot(t, y[:, k], lw=0.7, color=f"C{2 * k}", label=f"measured y{suffix}")
        ax1.plot(t, yhat[:, k], lw=0.7, ls="--", color=f"C{2 * k + 1}", label=f"P̂ u{suffix} (simulated from rest)")
        ax2.plot(t, err[:, k], lw=0.7, label=f"output error y − P̂u{suffix}")
    ax1.axvline(fit_end * dt, color="k", ls=":", lw=0.8, label="held out from here")
    ax1.set_ylabel("output")
    ax1.legend(loc="upper right", fontsize=7)
    ax2.set_ylabel("y − P̂u")
    ax2.legend(loc="upper right", fontsize=7)
    ax2.set_xlabel(xlabel)
    ax1.set_title("Model P̂ against the record")
    figs.append(save_figure(fig, out / "output_error.png"))

    loop = closed_loop_system(res.model, res.controller)  # r → [y; u]
    l = rec.l
    n_step = 200
    fig, (ax1, ax2) = plt.subplots(2, 1, sharex=True, figsize=(8, 4.5))
    ts = np.arange(n_step) * dt
    finals = []
    for c in range(l):  # a step on each reference channel alone
        resp = _step(loop, n_step, c)
        suffix = f" (step on r{c})" if l > 1 else ""
        ax1.plot(ts, resp[:, c], color=f"C{c}", label=f"y{c if l > 1 else ''}{suffix}")
        ax2.plot(ts, resp[:, l:], color=f"C{c}", lw=0.8)
        finals.append(float(resp[-1, c]) if np.isfinite(resp[-1, c]) else float("nan"))
    ax1.plot(ts, np.ones(n_step), "k:", lw=0.8, label="reference")
    ax1.set_ylabel("output")
    ax1.legend(fontsize=7)
    ax2.set_ylabel("control u")
    ax2.set_xlabel(xlabel)
    ax1.set_title("Unit step of the loop on P̂" + (" (each reference channel alone)" if l > 1 else ""))
    figs.append(save_figure(fig, out / "step.png"))
    numbers["step_final"] = finals[0] if l == 1 else finals

    w = np.logspace(np.log10(math.pi / dt) - 3, np.log10(math.pi / dt), 400)
    z = np.exp(1j * w * dt)
    F = [_freq(loop, zk) for zk in z]
    T = np.array([_gain(f[:l]) for f in F])
    S = np.array([_gain(np.eye(l) - f[:l]) for f in F])
    Ur = np.array([_gain(f[l:]) for f in F])
    # the model's peak gain on the grid: the scale δ (an additive bound) is to be read against
    numbers["model_peak_gain"] = float(max(_gain(_freq(res.model, zk)) for zk in z))
    fig, ax = plt.subplots(figsize=(8, 4))
    norm = "σ̄" if l > 1 or rec.m > 1 else "|·|"
    ax.loglog(w, T, label=f"{norm} T (r → y)")
    ax.loglog(w, S, ls="--", label=f"{norm} S = I − T")
    ax.loglog(w, Ur, ls=":", label=f"{norm} (r → u)")
    ax.set_xlabel("frequency (rad/s)")
    ax.set_ylabel("magnitude" + (" (largest singular value)" if norm == "σ̄" else ""))
    ax.set_title("Loop on P̂")
    ax.legend(fontsize=7)
    figs.append(save_figure(fig, out / "bode.png"))
    return figs, numbers


def _gain(M) -> float:
    """Largest singular value (the modulus for one channel)."""
    return float(np.linalg.norm(np.atleast_2d(M), 2))


def _freq(sys, z):
    A, B, C, D = (np.atleast_2d(np.asarray(m, float)) for m in (sys.A, sys.B, sys.C, sys.D))
    n = A.shape[0]
    return C @ np.linalg.solve(z * np.eye(n) - A, B) + D if n else D.astype(complex)


def _step(loop, n: int, channel: int = 0):
    """Response ``(n, outputs)`` of ``loop`` to a unit step on input ``channel`` from rest."""
    from ..lab.simulate import lsim

    A, B, C, D = (np.atleast_2d(np.asarray(m, float)) for m in (loop.A, loop.B, loop.C, loop.D))
    r = np.zeros((n, B.shape[1]))
    r[:, channel] = 1.0
    with np.errstate(all="ignore"):
        out = np.asarray(lsim(A, B, C, D, r, np.zeros(A.shape[0]))[0], float)
    return out.reshape(n, -1)


def _finals(value) -> str:
    if isinstance(value, list):
        return ", ".join(f"y{c} {_fmt(v)} (step on r{c})" for c, v in enumerate(value))
    return _fmt(value)


def report_design(out: Path, rec, res, warned, *, horizon, window_arg, sigma_arg, weights_text, t_start,
                  title="Design from data", name="design", intro="", operating=None, scale="") -> dict:
    """Write the report, the controller files and the JSON summary of one design; return the summary."""
    from synthesis import save_controller

    from ..lab.report import Report, finish_report

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    n = rec.n
    fit_end = n - int(n / 3)  # robust_design_from_data's held-out last third (HELD_OUT_FRACTION)
    unf = res.unfalsification
    win = tuple(int(k) for k in res.window)  # the samples robust_design_from_data took as the (7.5) window
    npz = save_controller(out / "controller.npz", res.controller)
    mat = save_controller(out / "controller.mat", res.controller)
    figs, numbers = _figures(out, rec, res, fit_end, win)
    cert = unf.certificate
    prem = res.premise

    rep = Report(title)
    if intro:
        rep.text(intro)
    rep.section("Record",
                f"`{rec.source}`: {n} samples, dt = {rec.dt:g}{_dt_origin(rec)}, input{'s' if rec.m > 1 else ''} "
                f"{', '.join(map(str, rec.u_columns))}, output{'s' if rec.l > 1 else ''} "
                f"{', '.join(map(str, rec.y_columns))}.  The (7.5) window is samples [{win[0]}, {win[1]}) (`--window "
                f"{'auto' if window_arg == 'auto' else f'{window_arg[0]}:{window_arg[1]}'}`); the predictors "
                f"are fitted on [0, {fit_end}) and the last {n - fit_end} samples are held out for the test of "
                f"the certificate's premise.  Horizon i = {horizon}."
                + (f"  {operating[1]}" if operating and operating[1] else ""))
    rep.figure(figs[0], "Record, the (7.5) window and the held-out part")
    rep.section("Weights", weights_text + "." + (f"  {scale}" if scale else ""))
    rep.section("Model P̂ and its output error",
                f"rms of y − P̂u (P̂ simulated from rest): {_fmt(numbers['oe_rms_fit'])} on the fitting part, "
                f"{_fmt(numbers['oe_rms_held_out'])} on the held-out part (rms of y: {_fmt(numbers['y_rms'])}).")
    rep.figure(figs[1], "Measured output against P̂u, and the output error")
    excitation_worst, margin_evidence = _excitation_number(res, "worst"), _excitation_number(res, "margin")
    rep.section("δ")
    rep.table(["quantity", "value"], [
        ["σ (admissible rms noise of (7.5))" + (" — auto: half the window's residual rms" if sigma_arg == "auto"
                                                 else ""), _fmt(float(cert.sigma))],
        ["δ of (7.5)", _fmt(res.delta_subspace)],
        ["certificate bracket of (7.5): lower bound", _fmt(float(cert.lower_bound))],
        ["certificate bracket of (7.5): upper bound", _fmt(float(cert.upper_bound))],
        ["δ of P̂'s output error (Theorem 7.1, held out)", _fmt(res.delta_output_error)],
        ["δ designed and certified for (the larger)", _fmt(res.delta)],
        ["decided by", prem.decided_by if prem is not None else "—"],
        ["time invariance over the record (Chow's test, p-value)", _invariance_text(res)],
        ["loop against the data: (|P − P̂| estimate + r)·|K(I+P̂K)⁻¹|, worst (< 1 needed)", _fmt(excitation_worst)],
        ["loop against the data: evidence that the plant lacks the δ margin (< 1 needed)", _fmt(margin_evidence)],
        ["peak gain of P̂ (frequency grid), for scale", _fmt(numbers["model_peak_gain"])],
    ])
    rep.section("Design search", "Every design tried, in order; the first certified one is returned.")
    rows = []
    for k, s in enumerate(res.search):
        rows.append([k, s.horizon, "yes" if s.causal else "no", _fmt(s.gamma_ratio), _fmt(s.w3_gain),
                     _fmt(s.gamma), "yes" if s.certified else "no", s.reason or "—"])
    rep.table(["#", "horizon", "causal", "γ/γ_min", "W3 gain", "γ", "certified", "reason"], rows)
    verdict = "CERTIFIED" if res.certified else "NOT CERTIFIED"
    rep.section("Verdict", f"**{verdict}** for {_family(res)}."
                + (f"\n\nReason: {res.reason}" if res.reason else
                   f"\n\nThe loop is stable on P̂ and P̂_ref, small gain is proven for "
                   f"{'δ' if res.uncertainty == 'additive' else 'ε'}, the step tracks (mean error over its last "
                   f"quarter at most {_floors_text(res.certificate.tracking_floor)}), and the held-out data do not "
                   "falsify the premise.")
                + (f"\n\nThe additive form was left: {res.additive_reason}" if res.additive_reason else "")
                + "".join(f"\n\nAssumed, not testable on these data: {a}." for a in res.assumed)
                + (f"\n\nNot confirmed by the data: {res.premise_note}." if res.premise_note else ""))
    rep.section("The loop on P̂",
                f"Controller (inputs [r; y], output u, {res.controller.nstates} states): `{npz.name}`, "
                f"`{mat.name}` (synthesis.load_controller reads either).  Final value of the unit step on "
                f"P̂ after 200 samples: {_finals(numbers['step_final'])}.")
    rep.figure(figs[2], "Unit step of the loop on P̂")
    rep.figure(figs[3], "Closed-loop magnitudes on P̂")
    summary = {
        "source": rec.source, "samples": n, "dt": rec.dt,
        "u": rec.u_columns[0] if rec.m == 1 else list(rec.u_columns),
        "y": rec.y_columns[0] if rec.l == 1 else list(rec.y_columns),
        "horizon": int(horizon), "window": list(win), "fit_end": fit_end,
        "sigma": float(cert.sigma), "certified": bool(res.certified), "reason": res.reason,
        "uncertainty": res.uncertainty, "epsilon": float(res.epsilon) if res.uncertainty == "coprime" else None,
        "certificate_margin": float(res.certificate.margin), "margin": float(res.margin),
        "additive_reason": res.additive_reason,
        "tracking_floor": _floors_json(res.certificate.tracking_floor), "assumed": list(res.assumed),
        "premise_note": res.premise_note,
        "invariance_p_value": float(res.invariance.p_value) if res.invariance is not None else None,
        "excitation_worst": excitation_worst, "margin_evidence": margin_evidence,
        "delta": float(res.delta), "delta_subspace": float(res.delta_subspace),
        "delta_output_error": float(res.delta_output_error),
        "delta_lower_bound": float(cert.lower_bound), "delta_upper_bound": float(cert.upper_bound),
        "decided_by": prem.decided_by if prem is not None else None,
        "search": [{"horizon": s.horizon, "causal": s.causal, "gamma_ratio": s.gamma_ratio, "w3_gain": s.w3_gain,
                    "gamma": s.gamma, "certified": s.certified, "reason": s.reason} for s in res.search],
        "weights": weights_text, **numbers,
        **({"operating_point": operating[0], "operating_point_note": operating[1]} if operating else {}),
        "scale_note": scale,
        "controller_npz": str(npz), "controller_mat": str(mat),
    }
    return finish_report(rep, summary, out, name, warn_log=warned, figures=figs, t_start=t_start,
                         warnings_heading="Warnings raised")


def _floors_text(floor) -> str:
    """The tracking floor as the report states it: one number, or one per output (``inf``: not tracked)."""
    floors = np.atleast_1d(np.asarray(floor, float))
    return f"{floors[0]:g}" if floors.size == 1 else "(" + ", ".join(f"{f:g}" for f in floors) + ") per output"


def _dt_origin(rec) -> str:
    """Where the sample time came from, for the report: the weights and the controller take it in seconds, and a
    time column in ms or µs under a bare name (``time``) cannot be told from one in seconds."""
    if rec.t is None:
        return " (given)"
    return (" (the time column's step, in seconds: a column in other units names them, e.g. 'time [ms]', and is "
            "converted)")


def _floors_json(floor):
    """The tracking floor for ``design.json``: a number or a list, ``None`` for an output not tracked (JSON has no
    infinity)."""
    floors = [None if math.isinf(f) else float(f) for f in np.atleast_1d(np.asarray(floor, float))]
    return floors[0] if len(floors) == 1 else floors


def _family(res) -> str:
    """The set of plants the verdict speaks of: the additive ball about P̂, or the coprime-factor ball."""
    # the certificate's margin (default 0.25), not ``res.margin``, the W3 rule's (0.1): the report had stated the
    # ball as 1.1 δ beside a premise note and a README that say 1.25 δ
    ball = f"every plant within (1 + {res.certificate.margin:g})"
    if res.uncertainty == "coprime":
        return (f"ε = {_fmt(res.epsilon)} in coprime-factor form ({ball}·ε of P̂ = M̂⁻¹N̂ in ‖[Δ_N Δ_M]‖∞; "
                f"the design is sized by δ = {_fmt(res.delta)})")
    return f"δ = {_fmt(res.delta)} ({ball}·δ of P̂ in ‖Δ‖∞)"


def _excitation_number(res, name: str):
    """``res.excitation.<name>`` of the returned loop (∞ where a band the loop is sensitive to is not excited), or
    None where the check did not run (an unstable loop) or gave no number (NaN)."""
    value = getattr(res.excitation, name, None)  # getattr(None, ...) is None too: no check ran
    return float(value) if value is not None and not np.isnan(value) else None


def _invariance_text(res) -> str:
    """The time-invariance test's p-value, order and samples, or why it did not run."""
    inv = res.invariance
    if inv is None:
        return res.invariance_note or "—"
    verdict = "rejected" if inv.rejected else "not rejected"
    return f"{inv.p_value:.3g} ({verdict} at {inv.level:g}; ARX({inv.order}), {inv.samples} samples)"


def run(opts) -> dict:
    """``python -m experiments design DATA ...`` (module docstring); returns the JSON summary."""
    t_start = time.perf_counter()
    ex = opts.extra
    path = Path(ex["data"])
    u, y, t, variable = _select(path, ex)
    rec = load_record(path, u=u, y=y, t=t, dt=ex.get("dt"), variable=variable)
    rec, point, point_text = operating_point(rec, ex.get("detrend") or "none")
    floor = parse_tracking_floor(ex.get("tracking_floor"))
    if isinstance(floor, tuple) and len(floor) != rec.l:
        raise DataError(f"--tracking-floor gives {len(floor)} floors for {rec.l} output channels: give one number, or "
                        f"one per output")
    W1, W2, weights_text = _weights(ex, rec.dt, rec.m, rec.l, untracked_outputs(floor))
    window, sigma = parse_window(ex.get("window")), _parse_sigma(ex.get("sigma"))
    horizon = ex["horizon"]
    res, warned = design_record(rec.u, rec.y, rec.dt, horizon, W1, W2, window=window, sigma=sigma,
                                untested=ex.get("untested") or "warn", feedthrough=bool(ex.get("feedthrough")),
                                tracking_floor=floor)
    defaults = not (ex.get("weights") or ex.get("w1") or ex.get("w2"))
    return report_design(opts.out, rec, res, warned, horizon=horizon, window_arg=window, sigma_arg=sigma,
                         weights_text=weights_text, t_start=t_start, operating=(point, point_text),
                         scale=scale_note(rec, defaults))


def summary_lines(summary: dict) -> list[str]:
    """The verdict, δ and the controller files, for the CLI's closing summary."""
    verdict = "certified" if summary["certified"] else f"NOT certified: {summary['reason']}"
    if summary["certified"] and summary.get("uncertainty") == "coprime":
        verdict = f"certified in coprime-factor form for ε = {float(summary['epsilon']):.4g}, not for δ"
    assumed = [f"assumed, not testable on these data: {a}" for a in summary.get("assumed", ())]
    point = [summary[k] for k in ("operating_point_note", "scale_note") if summary.get(k)]
    if summary["certified"] and summary.get("premise_note"):
        point.insert(0, f"not confirmed by the data: {summary['premise_note']}")
    return [f"δ = {float(summary['delta']):.4g} ({summary['decided_by']}); {verdict}", *assumed, *point,
            f"controller: {summary['controller_npz']}, {summary['controller_mat']}"]


#: the options of ``design`` (argparse specs for ``cli.COMMANDS``)
OPTIONS = (
    (("data",), dict(dest="data", metavar="DATA", help="record file: .csv/.txt (header names or indices), .npz, .mat")),
    (("--horizon", "-i"), dict(dest="horizon", type=int, required=True, help="horizon i of (7.5) and the design")),
    (("--dt",), dict(dest="dt", type=float, default=None, help="sample time (omit with a time column)")),
    (("--window",), dict(dest="window", default="auto", metavar="START:LEN|auto",
                         help="the (7.5) window in the first two thirds of the record (default: auto)")),
    (("--sigma",), dict(dest="sigma", default="auto", metavar="S|auto",
                        help="admissible rms noise of (7.5) (default auto: half the window's residual rms)")),
    (("--u",), dict(dest="u", default=None, metavar="COL", help="input column (name or 0-based index)")),
    (("--y",), dict(dest="y", default=None, metavar="COL", help="output column (name or 0-based index)")),
    (("--t",), dict(dest="t", default=None, metavar="COL",
                    help="time column (default: a CSV column, or an NPZ/MAT array, named t or time)")),
    (("--variable",), dict(dest="variable", default=None, metavar="NAME",
                           help="NPZ/MAT: the matrix holding the channels (then columns are indices)")),
    (("--weights",), dict(dest="weights", nargs=2, default=None, metavar=("W1FILE", "W2FILE"),
                          help="W1 and W2 saved with synthesis.save_controller (.npz or .mat each)")),
    (("--w1",), dict(dest="w1", default=None, metavar="DC,FREQ,MAG,HF",
                      help="W1 = makeweight(DC, (FREQ, MAG), HF, dt)")),
    (("--w2",), dict(dest="w2", default=None, metavar="DC,FREQ,MAG,HF",
                      help="W2 = makeweight(DC, (FREQ, MAG), HF, dt)")),
    (("--detrend",), dict(dest="detrend", choices=("none", "mean"), default="none",
                          help="mean: subtract the record's means of u and y (an operating point) before the design; "
                               "the report says how to apply the controller (default: none, the record as read)")),
    (("--untested",), dict(dest="untested", choices=("warn", "refuse"), default="warn",
                           help="a premise the record cannot test (a two-level input shows no saturation): certify "
                                "on it and say so (warn, the default) or refuse")),
    (("--tracking-floor",), dict(dest="tracking_floor", default=None, metavar="F[,F...]",
                                 help="largest mean step error over the step's last quarter, one number or one per "
                                      "output (inf: that output not tracked, e.g. 0.1,inf for a plant with fewer "
                                      "inputs than outputs; W1 (--w1 or the default, not --weights) then weighs it "
                                      "by 0.01) (default: 0.1)")),
    (("--feedthrough",), dict(dest="feedthrough", action="store_true",
                              help="the plant has a direct feedthrough (y_k responds to u_k): the feedback test leaves "
                                   "lag 0 out, where a feedthrough looks like feedback (default: strictly proper)")),
)
