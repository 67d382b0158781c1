"""A test helper shared by the unfalsification solver tests: call a solve with its expected warnings silenced."""
import warnings

import unfalsify as uf


def quiet(fn, *args, **kw):
    """``fn(*args, **kw)`` with the warnings a solve on random data may raise (a non-optimal status, an ill-conditioned
    T(u), a short window) ignored: the tests assert on the returned status and certificate instead."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", uf.SolverWarning)
        warnings.simplefilter("ignore", uf.IllConditionedWarning)
        warnings.simplefilter("ignore", uf.FewDataWarning)
        return fn(*args, **kw)
