"""Suite-wide setting: BLAS on one thread, unless the environment says otherwise.

The suite's problems are small (a few hundred unknowns at most), where a second OpenBLAS thread costs more in
synchronisation than it brings, and several tests run process pools or a Dask cluster whose workers would
each start their own BLAS threads on a 2-core machine.  Measured on 2 cores: three of the slowest tests
(``test_quick_run[sweep]``, the premise's slow-dynamics refusal, the demo CLI) took 71 s with one thread and
108 s with two (the same commit, nothing else running).

Child processes (CLI runs, process pools, Dask workers) inherit the environment variables; this process is
limited through threadpoolctl, because OpenBLAS read its variable when numpy was imported.  Set
``OPENBLAS_NUM_THREADS`` yourself to run the suite with another count.
"""
import os

import pytest
from threadpoolctl import threadpool_limits

_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")

if not any(v in os.environ for v in _VARIABLES):
    for _v in _VARIABLES:
        os.environ[_v] = "1"
    _LIMITS = threadpool_limits(limits=1, user_api="blas")


@pytest.fixture
def one_second_clock(monkeypatch):
    """The structured solvers' wall clock (``unfalsify.solvers.barrier._clock``) replaced by one that advances one
    second per reading: a time limit then expires after a fixed number of readings, whatever the machine's speed."""
    import unfalsify.solvers.barrier as barrier

    clock = [0.0]

    def tick():
        clock[0] += 1.0
        return clock[0]

    monkeypatch.setattr(barrier, "_clock", tick)
    return clock
