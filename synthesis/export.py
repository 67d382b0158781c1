"""Save a controller to a file other tools can read, and load it back.

:func:`save_controller` writes a python-control system as its matrices ``A, B, C, D``, its sample
time ``dt`` and its signal names, to a NumPy ``.npz`` archive or a MATLAB ``.mat`` file
(``scipy.io.savemat``); :func:`load_controller` reads either back as a ``control.StateSpace``
with the same matrices (bit for bit: float64 is stored as is), sample time and names.

In the ``.mat`` file the variables are ``A, B, C, D, dt`` (and ``Ts``, the same value under
MATLAB's name), ``InputName``, ``OutputName``, ``StateName`` (cell arrays of strings) and
``Name``; in MATLAB ``K = ss(A, B, C, D, Ts, 'InputName', InputName, 'OutputName', OutputName)``
rebuilds the controller.  An unspecified discrete sample time (``dt=True``) is stored as
``-1``, MATLAB's convention, and read back as ``True``.
"""
from __future__ import annotations

import os
import zipfile
from pathlib import Path

import numpy as np

from .exceptions import ControllerFileError

from ._validation import InputTypeError, as_real_array, check_instance, to_state_space

__all__ = ["ControllerFileError", "save_controller", "load_controller", "read_variables", "CONTROLLER_FORMATS"]

#: File name endings :func:`save_controller` and :func:`load_controller` understand.
CONTROLLER_FORMATS = (".npz", ".mat")
_MATRICES = ("A", "B", "C", "D")


def _format(path: Path) -> str:
    suffix = path.suffix.lower()
    if suffix not in CONTROLLER_FORMATS:
        raise ControllerFileError(
            f"cannot tell the format of {str(path)!r} from its ending {suffix or '(none)'!r}; name the file "
            "'….npz' (NumPy archive) or '….mat' (MATLAB, scipy.io)")
    return suffix


def _dt_to_number(dt) -> float:
    if dt is True:
        return -1.0  # MATLAB: Ts = -1 is an unspecified sample time
    return float(dt or 0.0)


def _dt_from_number(x) -> float | bool:
    x = float(x)
    return True if x == -1.0 else x


def save_controller(path, sys, *, name: str | None = None) -> Path:
    """Write an LTI system (typically a designed controller) to ``.npz`` or ``.mat``.

    Parameters
    ----------
    path : str or pathlib.Path
        Destination; the ending chooses the format: ``.npz`` (``numpy.savez``) or ``.mat``
        (``scipy.io.savemat``, MATLAB 5 format).  An existing file is overwritten.
    sys : control.StateSpace or control.TransferFunction
        The system, e.g. ``design.controller`` (inputs ``[r; y]``, output ``u``).  A transfer
        function is converted to state space first.
    name : str, optional
        Name stored with the system (default: ``sys.name``).

    Returns
    -------
    pathlib.Path
        The file written.

    Raises
    ------
    ControllerFileError
        The ending is neither ``.npz`` nor ``.mat``, or the matrices hold NaN or infinite entries.
    InputTypeError
        ``sys`` is not a python-control LTI system, ``path`` not a ``str`` or path, ``name`` not a ``str``.

    See Also
    --------
    load_controller : read the file back.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> import control, numpy as np
    >>> import synthesis
    >>> K = control.ss([[0.5]], [[1.0, -1.0]], [[2.0]], [[0.1, -0.1]], 0.1, inputs=["r", "y"], outputs=["u"])
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> for ending in (".npz", ".mat"):
    ...     path = synthesis.save_controller(folder / f"K{ending}", K)
    ...     back = synthesis.load_controller(path)
    ...     print(ending, np.array_equal(back.D, K.D), back.dt, back.input_labels, back.output_labels)
    .npz True 0.1 ['r', 'y'] ['u']
    .mat True 0.1 ['r', 'y'] ['u']
    """
    import control

    if isinstance(path, control.InputOutputSystem):  # save_controller(K, "K.npz"): numpy's order is file first
        raise InputTypeError(f"save_controller(path, sys) takes the file first, got a {type(path).__name__} as path; "
                             "call save_controller('K.npz', K)")
    # Path(3) had raised a bare TypeError; a name of another type had been stored as its str() (b'K' as "b'K'")
    path = Path(check_instance(path, (str, os.PathLike), "path", "a file name (str or pathlib.Path) ending in "
                               "'.npz' or '.mat'"))
    if name is not None:
        check_instance(name, str, "name", "a string (e.g. name='K') or None for the system's own name")
    fmt = _format(path)
    sys = to_state_space(sys, "sys")
    if not isinstance(sys, control.StateSpace):
        raise InputTypeError(
            f"save_controller needs a python-control StateSpace or TransferFunction, got {type(sys).__name__}; "
            "pass e.g. design.controller")
    n, m, p = sys.nstates, sys.ninputs, sys.noutputs
    mats = {"A": np.asarray(sys.A, float).reshape(n, n), "B": np.asarray(sys.B, float).reshape(n, m),
            "C": np.asarray(sys.C, float).reshape(p, n), "D": np.asarray(sys.D, float).reshape(p, m)}
    bad = [k for k, v in mats.items() if not np.all(np.isfinite(v))]
    if bad:  # load_controller refuses such a file: do not write one
        raise ControllerFileError(f"the system's {', '.join(bad)} hold NaN or infinite entries: it is no controller "
                                  "to save (a failed design?); check the design's status before saving")
    dt = _dt_to_number(sys.dt)
    labels = {"InputName": list(sys.input_labels), "OutputName": list(sys.output_labels),
              "StateName": list(sys.state_labels)}
    sys_name = str(sys.name if name is None else name)
    if fmt == ".npz":
        with open(path, "wb") as f:  # a file object: numpy would append ".npz" to "K.NPZ"
            np.savez(f, **mats, dt=np.float64(dt), Name=np.str_(sys_name),
                     **{k: np.array(v, dtype=str) for k, v in labels.items()})
    else:
        from scipy.io import savemat

        cells = {k: np.array(v, dtype=object).reshape(-1, 1) if v else np.zeros((0, 1), dtype=object)
                 for k, v in labels.items()}
        with open(path, "wb") as f:
            savemat(f, {**mats, "dt": np.float64(dt), "Ts": np.float64(dt), "Name": sys_name, **cells})
    return path


def _names(raw, key: str, count: int, path: Path) -> list[str] | None:
    if raw is None:
        return None
    arr = np.asarray(raw, dtype=object).ravel()
    names = [str(np.asarray(x).ravel()[0]) if np.asarray(x).size else "" for x in arr] if arr.dtype == object \
        else [str(x) for x in arr]
    if len(names) != count:
        raise ControllerFileError(
            f"{str(path)!r}: {key} has {len(names)} name(s) but the matrices give {count}; fix or remove {key}")
    return names


def read_variables(path, *, error: type = ControllerFileError) -> dict:
    """The variables of a NumPy ``.npz`` archive or a MATLAB ``.mat`` file, by name (MATLAB's ``__header__``-style
    entries left out).

    Object arrays are refused (``allow_pickle=False``: a file of numbers needs no code to load).

    Parameters
    ----------
    path : str or pathlib.Path
        A ``.npz`` or ``.mat`` file (the ending chooses the reader).
    error : type
        The ``DataError`` subclass to raise (:class:`ControllerFileError` by default).

    Returns
    -------
    dict
        Variable name → array.

    Raises
    ------
    error
        An ending other than ``.npz`` or ``.mat``; a file numpy or scipy cannot read (a damaged archive, a MATLAB
        v7.3 file, which is HDF5), with how to save it again.
    FileNotFoundError
        No such file.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> import numpy as np
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "run.npz"
    >>> np.savez(path, u=np.zeros(3), y=np.ones(3))
    >>> sorted(read_variables(path))
    ['u', 'y']
    """
    path = Path(path)
    fmt = path.suffix.lower()
    if fmt not in (".npz", ".mat"):
        raise error(f"cannot read {str(path)!r} as NPZ or MAT: its ending is {fmt or '(none)'!r}")
    if not path.exists():
        raise FileNotFoundError(f"no file {str(path)!r}")
    if fmt == ".npz":
        try:
            with np.load(path, allow_pickle=False) as f:
                return {k: f[k] for k in f.files}
        except (OSError, ValueError, zipfile.BadZipFile, EOFError) as exc:
            raise error(f"cannot read {str(path)!r} as NPZ ({exc}); save numeric arrays with numpy.savez(file, "
                        "name=array, …)") from None
    from scipy.io import loadmat
    from scipy.io.matlab import MatReadError

    try:
        data = loadmat(path)
    except NotImplementedError:  # scipy's answer to MATLAB's HDF5-based format
        raise error(f"{str(path)!r} is a MATLAB v7.3 (HDF5) file, which scipy does not read; save it again from "
                    "MATLAB with save(file, …, '-v7')") from None
    except (MatReadError, OSError, ValueError, TypeError, EOFError) as exc:
        raise error(f"cannot read {str(path)!r} as a MATLAB file ({exc}); save it from MATLAB with "
                    "save(file, …, '-v7')") from None
    return {k: v for k, v in data.items() if not k.startswith("__")}


def load_controller(path):
    """Read a system written by :func:`save_controller` (or by hand: see the module docstring).

    Parameters
    ----------
    path : str or pathlib.Path
        A ``.npz`` or ``.mat`` file with the variables ``A, B, C, D`` and ``dt`` (or MATLAB's ``Ts``);
        optionally ``InputName``, ``OutputName``, ``StateName`` and ``Name``.

    Returns
    -------
    control.StateSpace
        The system, with the stored matrices, sample time (``-1`` → ``True``) and signal names.

    Raises
    ------
    ControllerFileError
        Unknown ending; a file numpy or scipy cannot read (a MATLAB v7.3 file, a damaged archive); a
        missing variable (the message lists what the file has); matrices whose shapes do not fit
        together; NaN/inf entries; a wrong number of signal names.
    FileNotFoundError
        No such file.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> import numpy as np, scipy.io
    >>> import synthesis
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "from_matlab.mat"
    >>> scipy.io.savemat(path, {"A": np.array([[0.9]]), "B": np.array([[1.0]]), "C": np.array([[0.5]]),
    ...                         "D": np.array([[0.0]]), "Ts": 0.01})
    >>> K = synthesis.load_controller(path)
    >>> K.dt, K.nstates
    (0.01, 1)
    """
    import control

    # Path(None) had raised a bare TypeError
    path = Path(check_instance(path, (str, os.PathLike), "path", "a file name (str or pathlib.Path) ending in "
                               "'.npz' or '.mat'"))
    _format(path)  # an ending other than .npz/.mat: ControllerFileError naming both
    data = read_variables(path)  # FileNotFoundError for a missing file
    if "dt" not in data and "Ts" in data:
        data["dt"] = data["Ts"]
    missing = [k for k in (*_MATRICES, "dt") if k not in data]
    if missing:
        raise ControllerFileError(
            f"{str(path)!r} has no {', '.join(missing)} (it has {', '.join(sorted(data)) or 'nothing'}); a "
            "controller file needs A, B, C, D and dt (or Ts): write it with synthesis.save_controller")
    mats = {}
    for k in _MATRICES:
        # as_real_array: a complex matrix had lost its imaginary part (ComplexWarning), text had been parsed
        mats[k] = np.atleast_2d(as_real_array(data[k], f"{str(path)!r}: {k}", error=ControllerFileError))
        if mats[k].ndim != 2 or not np.all(np.isfinite(mats[k])):
            raise ControllerFileError(f"{str(path)!r}: {k} must be a finite 2-D matrix; got shape {mats[k].shape}")
    A, B, C, D = (mats[k] for k in _MATRICES)
    p, m = D.shape
    n = A.shape[0] if A.size else 0
    A, B, C = A.reshape(n, n) if A.size == n * n else A, B.reshape(n, m) if B.size == n * m else B, \
        C.reshape(p, n) if C.size == p * n else C
    if A.shape != (n, n) or B.shape != (n, m) or C.shape != (p, n):
        raise ControllerFileError(
            f"{str(path)!r}: shapes A {A.shape}, B {B.shape}, C {C.shape}, D {D.shape} do not fit together "
            f"(expected A ({n}, {n}), B ({n}, {m}), C ({p}, {n}) for D ({p}, {m})); re-export the controller")
    dt_raw = np.asarray(data["dt"]).ravel()
    real = dt_raw.dtype.kind in "biuf"  # text had raised numpy's bare ValueError ("0.1" been parsed), complex warned
    if not real or dt_raw.size != 1 or not np.isfinite(dt_raw[0]) or (dt_raw[0] < 0 and dt_raw[0] != -1.0):
        raise ControllerFileError(
            f"{str(path)!r}: dt must be one number, a sample time >= 0 (or -1: unspecified), got {data['dt']!r}")
    dt = _dt_from_number(dt_raw[0])
    kwargs = {}
    for key, kw, count in (("InputName", "inputs", m), ("OutputName", "outputs", p), ("StateName", "states", n)):
        names = _names(data.get(key), key, count, path)
        if names is not None:
            kwargs[kw] = names
    if "Name" in data:
        # MATLAB stores '' as an empty array: it is the empty name, not "no name" (python-control's default)
        kwargs["name"] = str(np.asarray(data["Name"]).ravel()[0]) if np.asarray(data["Name"]).size else ""
    return control.ss(A, B, C, D, dt, **kwargs)
