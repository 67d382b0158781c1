"""The behaviour of the toolkit's frozen result dataclasses, for every package that defines results.

``@result`` on top of ``@dataclass(frozen=True)`` gives a short ``repr``, value equality, read-only
arrays and pickling that survives a new process; see :func:`result`.  :mod:`unfalsify` and
:mod:`experiments` decorate their results with it, so all results behave alike.
"""
from ._repr import result

__all__ = ["result"]
