"""Where the column split of (7.5) used to live; it is the solver ``"split"`` of :mod:`unfalsify.solvers` now.

Kept so that ``from unfalsify.split import split_solve`` (and the task functions a Dask worker imports)
keeps working.
"""
from .solvers.split import solve_column, solve_columns, split_solve

__all__ = ["split_solve"]  # solve_columns (the task) and solve_column stay importable from here
