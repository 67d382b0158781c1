"""Shared behaviour of the frozen result dataclasses: short ``repr``, value equality, read-only arrays.

Decorate a frozen dataclass with :func:`result` (on top of ``@dataclass``)::

    @result
    @dataclass(frozen=True, eq=False)
    class Design:
        gain: np.ndarray
        gamma: float

and it gets

* a ``repr`` that shows array *shapes* and key scalars instead of array dumps
  (``Design(gain=<array (10, 30) float64>, gamma=0.957)``), in the manner of
  python-control's and cvxpy's objects;
* value equality: ``a == b`` when both are the same class and every field is equal (except the
  fields declared ``dataclasses.field(compare=False)``: by-products such as a cvxpy problem), arrays
  compared with ``numpy.array_equal`` (NaN equal to NaN), python-control systems by their
  matrices and sample time, anything else with ``==`` (identity for objects without it);
* read-only arrays: every ``numpy.ndarray`` field (also inside a tuple field) is replaced by a
  copy with ``flags.writeable = False``, so a result cannot be changed behind its back;
* pickling that survives a new process: python-control 0.10's ``StateSpace`` holds a lambda and
  does not pickle, so a ``StateSpace`` anywhere in a result's fields (also inside tuples, lists,
  dicts, plain dataclasses such as :class:`~synthesis.Additive` and deferred recipes) is stored
  as its matrices ``A, B, C, D``, its sample time, its signal names and its name, and rebuilt with
  ``control.ss`` on load (the matrices bit for bit); a ``cvxpy.Problem`` (it holds a solver
  object) is stored as ``None``.  Nested result objects pickle themselves the same way.
"""
from __future__ import annotations

import dataclasses
import functools
import numbers

import numpy as np

from ._lazy import _Deferred, _LazyField, _readonly

__all__ = ["result", "short_repr", "values_equal"]

_MAX_SEQ = 4  # items of a tuple/list shown before "…"


def short_repr(value, depth: int = 0) -> str:
    """A one-line description of ``value``: shapes for arrays and systems, short scalars."""
    if isinstance(value, np.ndarray):
        return f"<array {value.shape} {value.dtype}>"
    if isinstance(value, (bool, np.bool_)) or value is None:
        return repr(value if not isinstance(value, np.bool_) else bool(value))
    if isinstance(value, numbers.Integral):
        return str(int(value))
    if isinstance(value, numbers.Real):
        return format(float(value), ".4g")
    if isinstance(value, str):
        return repr(value) if len(value) <= 60 else repr(value[:57] + "...")
    if isinstance(value, (tuple, list)):
        if depth >= 1:
            return f"<{type(value).__name__} of {len(value)}>"
        items = [short_repr(v, depth + 1) for v in value[:_MAX_SEQ]]
        if len(value) > _MAX_SEQ:
            items.append(f"… ({len(value)} items)")
        open_, close = ("(", ")") if isinstance(value, tuple) else ("[", "]")
        return open_ + ", ".join(items) + ("," if isinstance(value, tuple) and len(value) == 1 else "") + close
    if isinstance(value, dict):
        return f"<dict of {len(value)}>"
    lti = _lti_shape(value)
    if lti is not None:
        return lti
    if getattr(type(value), "__result_class__", False):
        return f"<{type(value).__name__}>" if depth >= 1 else repr(value)
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return f"<{type(value).__name__}>"
    text = repr(value)
    if len(text) <= 60 and "\n" not in text:
        return text
    return f"<{type(value).__module__.split('.')[0]}.{type(value).__name__}>"


def _lti_shape(value) -> str | None:
    A = getattr(value, "A", None)
    if A is None or not hasattr(value, "dt") or not hasattr(value, "ninputs"):
        return None
    try:
        return (f"<{type(value).__name__}: {value.noutputs} output(s), {value.ninputs} input(s), "
                f"{np.shape(A)[0]} state(s), dt={value.dt}>")
    except Exception:  # pragma: no cover - defensive: never fail a repr
        return None


def values_equal(a, b) -> bool:
    """Equality used by result objects: arrays by value (NaN == NaN), LTI systems by matrices and dt."""
    if a is b:
        return True
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        if not (isinstance(a, np.ndarray) and isinstance(b, np.ndarray)) or a.shape != b.shape:
            return False
        try:
            return bool(np.array_equal(a, b, equal_nan=True))
        except TypeError:  # non-numeric dtypes
            return bool(np.array_equal(a, b))
    if isinstance(a, (tuple, list)) and isinstance(b, (tuple, list)):
        return type(a) is type(b) and len(a) == len(b) and all(values_equal(x, y) for x, y in zip(a, b))
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(values_equal(a[k], b[k]) for k in a)
    if _lti_shape(a) is not None and _lti_shape(b) is not None:
        return (type(a) is type(b) and a.dt == b.dt
                and all(values_equal(np.asarray(getattr(a, k)), np.asarray(getattr(b, k))) for k in "ABCD"))
    if isinstance(a, float) and isinstance(b, float) and np.isnan(a) and np.isnan(b):
        return True
    if (dataclasses.is_dataclass(a) and not isinstance(a, type) and type(a) is type(b)
            and not getattr(type(a), "__result_class__", False)):
        # a plain dataclass (e.g. synthesis.Additive holding StateSpace weights): field by field, as above
        return all(values_equal(getattr(a, f.name), getattr(b, f.name)) for f in dataclasses.fields(a) if f.compare)
    try:
        eq = a == b
        return bool(eq) if isinstance(eq, (bool, np.bool_)) else False
    except Exception:
        return False


def _hash_key(value):
    # equal objects must hash equal: use only what values_equal compares exactly (no floats: NaN)
    if isinstance(value, np.ndarray):
        return ("array", value.shape)
    if isinstance(value, (bool, int, str, np.integer, np.bool_)) or value is None:
        return value
    if isinstance(value, tuple):
        return ("tuple", len(value))
    return type(value).__name__


class _SystemRecipe:
    """Stand-in for a python-control ``StateSpace`` in a pickle: unpickles *as* a ``StateSpace``."""

    __slots__ = ("state",)

    def __init__(self, sys):
        self.state = (np.array(sys.A), np.array(sys.B), np.array(sys.C), np.array(sys.D), sys.dt,
                      tuple(sys.input_labels), tuple(sys.output_labels), tuple(sys.state_labels), sys.name)

    def __reduce__(self):
        return _rebuild_system, self.state


def _rebuild_system(A, B, C, D, dt, inputs, outputs, states, name):
    import control

    return control.ss(A, B, C, D, dt, inputs=list(inputs), outputs=list(outputs), states=list(states),
                      name=name)


class _DataclassRecipe:
    """Stand-in for a plain (non-``@result``) dataclass whose fields need :func:`_picklable`."""

    __slots__ = ("cls", "state")

    def __init__(self, cls, state):
        self.cls, self.state = cls, state

    def __reduce__(self):
        return _rebuild_instance, (self.cls, self.state)


def _rebuild_instance(cls, state):
    obj = object.__new__(cls)
    obj.__dict__.update(state)
    return obj


def _is_cvxpy_problem(value) -> bool:
    import sys

    cp = sys.modules.get("cvxpy")
    return cp is not None and isinstance(value, cp.Problem)


def _picklable(value):
    """``value`` with every ``StateSpace`` replaced by a recipe and every cvxpy Problem by None."""
    import sys


    control = sys.modules.get("control")
    if control is not None and isinstance(value, control.StateSpace):
        return _SystemRecipe(value)
    if _is_cvxpy_problem(value):
        return None
    if isinstance(value, tuple) and not hasattr(value, "_fields"):
        return tuple(_picklable(v) for v in value)
    if isinstance(value, list):
        return [_picklable(v) for v in value]
    if isinstance(value, dict):
        return {k: _picklable(v) for k, v in value.items()}
    if isinstance(value, _Deferred):
        return _Deferred(value.fn, *_picklable(value.args), with_owner=value.with_owner)
    if (dataclasses.is_dataclass(value) and not isinstance(value, type)
            and not getattr(type(value), "__result_class__", False) and hasattr(value, "__dict__")
            and "__reduce__" not in type(value).__dict__):
        return _DataclassRecipe(type(value), {k: _picklable(v) for k, v in value.__dict__.items()})
    return value


def _rebuild_result(cls, state):
    obj = object.__new__(cls)
    obj.__dict__.update({k: _readonly(v) for k, v in state.items()})  # arrays read-only again
    return obj


def result(cls):
    """Class decorator for a frozen result dataclass: short ``repr``, value ``==``, read-only arrays, pickling.

    Examples
    --------
    A design with a python-control controller pickles and loads equal (also in another process):

    >>> import pickle
    >>> import numpy as np
    >>> import synthesis
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(200)
    >>> y = np.convolve(u, [0.0, 0.5, 0.2])[:200] + 0.01 * rng.standard_normal(200)
    >>> design = synthesis.hinf_design(synthesis.fit_predictor(u, y, 4), 1.0, 0.1)
    >>> again = pickle.loads(pickle.dumps(design))
    >>> again == design, np.array_equal(again.controller.A, design.controller.A)
    (True, True)
    >>> again.gain.flags.writeable
    False
    """
    if not dataclasses.is_dataclass(cls):
        raise TypeError(f"@result must be applied on top of @dataclass, got {cls!r}")
    names = [f.name for f in dataclasses.fields(cls)]
    compared = [f.name for f in dataclasses.fields(cls) if f.compare]  # field(compare=False): a by-product
    original_init = cls.__init__


    # deferred fields are made read-only when they are computed (reading them here would compute them)
    eager = [n for n in names if not isinstance(cls.__dict__.get(n), _LazyField)]

    @functools.wraps(original_init)
    def __init__(self, *args, **kwargs):
        original_init(self, *args, **kwargs)
        for name in eager:
            value = getattr(self, name)
            frozen = _readonly(value)
            if frozen is not value:
                object.__setattr__(self, name, frozen)

    def __repr__(self):
        parts = [f"{f.name}={short_repr(getattr(self, f.name))}" for f in dataclasses.fields(self) if f.repr]
        return f"{type(self).__name__}(" + ", ".join(parts) + ")"

    def __eq__(self, other):
        if other.__class__ is not self.__class__:
            return NotImplemented
        return all(values_equal(getattr(self, n), getattr(other, n)) for n in compared)

    def __hash__(self):
        return hash((type(self).__name__, *(_hash_key(getattr(self, n)) for n in compared)))

    def __reduce__(self):
        # StateSpace -> matrices and names, cvxpy Problem -> None (see the module docstring)
        return _rebuild_result, (type(self), {k: _picklable(v) for k, v in self.__dict__.items()})

    cls.__init__ = __init__
    cls.__reduce__ = __reduce__
    cls.__repr__ = __repr__
    cls.__eq__ = __eq__
    cls.__hash__ = __hash__
    cls.__result_class__ = True
    return cls
