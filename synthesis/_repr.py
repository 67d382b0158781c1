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
* value equality: ``a == b`` when both are the same class and every field is equal, arrays
  compared with ``numpy.array_equal`` (NaN equal to NaN), python-control systems by their
  matrices and sample time, anything else with ``==`` (identity for objects without it);
* read-only arrays: every ``numpy.ndarray`` field (also inside a tuple field) is replaced by a
  copy with ``flags.writeable = False``, so a result cannot be changed behind its back.
"""
from __future__ import annotations

import dataclasses
import functools
import numbers

import numpy as np

__all__ = ["result", "short_repr", "values_equal"]

_MAX_SEQ = 4  # items of a tuple/list shown before "…"


def _readonly(value):
    if isinstance(value, np.ndarray):
        arr = np.array(value, copy=True)
        arr.flags.writeable = False
        return arr
    if isinstance(value, tuple) and any(isinstance(v, np.ndarray) for v in value):
        return tuple(_readonly(v) for v in value)
    return value


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


def result(cls):
    """Class decorator for a frozen result dataclass: short ``repr``, value ``==``, read-only arrays."""
    if not dataclasses.is_dataclass(cls):
        raise TypeError(f"@result must be applied on top of @dataclass, got {cls!r}")
    names = [f.name for f in dataclasses.fields(cls)]
    original_init = cls.__init__

    from ._lazy import _LazyField

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
        return all(values_equal(getattr(self, n), getattr(other, n)) for n in names)

    def __hash__(self):
        return hash((type(self).__name__, *(_hash_key(getattr(self, n)) for n in names)))

    cls.__init__ = __init__
    cls.__repr__ = __repr__
    cls.__eq__ = __eq__
    cls.__hash__ = __hash__
    cls.__result_class__ = True
    return cls
