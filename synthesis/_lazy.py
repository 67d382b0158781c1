"""Deferred fields of frozen dataclasses (computed on first access, then cached).

Some results carry a by-product that is expensive and rarely needed in a hot loop — the
singular values of the regressor factor of a :class:`~synthesis.Predictor` (an SVD, 3× the
cost of the fast predictor itself at i = 64), or the ``control.StateSpace`` of a
:class:`~synthesis.HinfDesign` (python-control object construction).  Such a field is a
:class:`_LazyField` descriptor: the constructor accepts either the value or a
:class:`_Deferred` recipe, and the first read evaluates the recipe once and stores the result.
To callers the field reads like any other attribute.
"""
from __future__ import annotations

from dataclasses import FrozenInstanceError

import numpy as np

__all__: list[str] = []

_MISSING = object()


class _Deferred:
    """Recipe ``fn(*args)`` for a :class:`_LazyField` value (picklable when ``fn`` is a module-level function).

    With ``with_owner=True`` the recipe is ``fn(owner, *args)``, ``owner`` being the instance whose
    field is read: a value computed from the result itself needs no reference to it (a reference
    cycle would keep every result alive until the cyclic garbage collector runs).
    """

    __slots__ = ("fn", "args", "with_owner")

    def __init__(self, fn, *args, with_owner: bool = False):
        self.fn = fn
        self.args = args
        self.with_owner = with_owner

    def __call__(self, owner=None):
        return self.fn(owner, *self.args) if self.with_owner else self.fn(*self.args)

    def __repr__(self) -> str:
        return f"<deferred {getattr(self.fn, '__name__', self.fn)!s}>"


class _LazyField:
    """Data descriptor for a frozen-dataclass field whose value may be a :class:`_Deferred`.

    ``default``: the field's default (omit for a required field).
    """

    def __init__(self, default=_MISSING):
        self._default = default

    def __set_name__(self, owner, name):
        self._name = name
        self._slot = f"_lazy_{name}"

    def __get__(self, obj, objtype=None):
        if obj is None:
            if self._default is _MISSING:
                raise AttributeError(self._name)  # dataclasses: no default, the field is required
            return self._default
        try:
            value = obj.__dict__[self._slot]
        except KeyError:  # an object pickled before the field existed: its default, as the class attribute reads
            if self._default is _MISSING:
                raise AttributeError(self._name) from None
            return self._default
        if isinstance(value, _Deferred):
            value = _readonly(value(obj))  # as the eager fields of a @result class
            obj.__dict__[self._slot] = value
        return value

    def __set__(self, obj, value):
        if self._slot in obj.__dict__:
            raise FrozenInstanceError(f"cannot assign to field {self._name!r}")
        obj.__dict__[self._slot] = value


def _is_pending(obj, name: str) -> bool:
    """True while the field ``name`` of ``obj`` still holds an unevaluated recipe."""
    return isinstance(obj.__dict__.get(f"_lazy_{name}"), _Deferred)


def _readonly(value):
    """A read-only copy of an array (also inside a tuple), as every field of a ``@result`` class is stored
    (:mod:`synthesis._repr`, which imports it from here: the lazy fields freeze their value the same way)."""
    if isinstance(value, np.ndarray):
        arr = np.array(value, copy=True)
        arr.flags.writeable = False
        return arr
    if isinstance(value, tuple) and any(isinstance(v, np.ndarray) for v in value):
        return tuple(_readonly(v) for v in value)
    return value
