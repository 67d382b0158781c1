"""
Former routes of the structured solvers, kept as measured references
====================================================================

``python -m experiments bench-unfalsify --backend structured`` times every structured solve twice in the
same child process: by today's route and by the route it replaced (issue 27: every speed-up measured in the
same run against the former route).  This module gives the former routes a public name, so that the
benchmark needs no private name of the library.  They give the same numbers to rounding; they are not the
routes to use, and they may go with the benchmark that measures them.

   former_corr_hessian  -- the barrier Hessian by the former 2-D FFT route (zero-padded and flipped copies)
   former_hessian       -- context manager: every solve inside it uses ``former_corr_hessian``
   former_routes        -- context manager: ``former_hessian`` and, in ``arx_barrier``, the former dense
                           algebra of a Newton step (K⁻¹ by solves against I, general products, both bounds
                           at every centring): the ARX route before issue 27 in full; in ``column_barrier``
                           the FFT Hessian and the path steps before issue 27 (the subspace route then)
   fft_barrier_hessian  -- context manager: ``arx_barrier``'s one-channel Hessian by the 2-D FFT instead of
                           the displacement generators (the route before ``displacement_hessian``)
   dense_inverse_blocks -- context manager: ``arx_barrier``'s blocks of F⁻¹ by potri and trmm (2⅔n³) instead
                           of displacement generators (the route before ``inverse_blocks``)

>>> import numpy as np
>>> from unfalsify.solvers import baselines
>>> from unfalsify.solvers.toeplitz import corr_hessian
>>> rng = np.random.default_rng(0)
>>> S11, S21, S22 = (rng.standard_normal((2, 5, 5)) for _ in range(3))
>>> bool(np.allclose(baselines.former_corr_hessian(S11, S21, S22, 5), corr_hessian(S11, S21, S22, 5)))
True
"""
from __future__ import annotations

from contextlib import contextmanager

from . import arx_barrier, column_barrier, toeplitz

__all__ = ["former_corr_hessian", "former_hessian", "former_routes", "fft_barrier_hessian", "dense_inverse_blocks"]


def former_corr_hessian(S11, S21, S22, m):
    """The barrier Hessian of :func:`unfalsify.solvers.toeplitz.corr_hessian` by the former route.

    Each of the three forward 2-D transforms pads its input with zeros by copying (scipy's padding of
    the column axis), S11 and S22 are flipped by copies, and the rows of lags read are gathered after a
    full inverse transform.  Kept to time today's route against it in the same run.

    Parameters
    ----------
    S11, S21, S22 : ndarray, shape (j, m, m)
        Blocks of ``F⁻¹`` per column (S11, S22 symmetric).
    m : int
        The size of the blocks.

    Returns
    -------
    ndarray, shape (j, m, m)
        The Hessian ``tr(F⁻¹E_aF⁻¹E_b)`` of each column.

    Examples
    --------
    >>> import numpy as np
    >>> from unfalsify.solvers.baselines import former_corr_hessian
    >>> from unfalsify.solvers.toeplitz import corr_hessian
    >>> S = np.eye(4)[None]
    >>> bool(np.allclose(former_corr_hessian(S, 0 * S, S, 4), corr_hessian(S, 0 * S, S, 4)))
    True
    """
    return toeplitz._former_corr_hessian(S11, S21, S22, m)


@contextmanager
def former_hessian():
    """Inside this context every structured solve forms its barrier Hessians by :func:`former_corr_hessian`.

    A process-wide switch (not thread-safe: the benchmark runs one solve per child process); the former
    route is restored on leaving, also after an exception.

    Examples
    --------
    >>> import numpy as np
    >>> from unfalsify.solvers import baselines
    >>> from unfalsify.solvers.toeplitz import corr_hessian
    >>> S = np.eye(3)[None]
    >>> with baselines.former_hessian():
    ...     H = corr_hessian(S, 0 * S, S, 3)
    >>> bool(np.allclose(H, corr_hessian(S, 0 * S, S, 3)))
    True
    """
    with _switched(toeplitz._HESSIAN_ROUTE, "route", "former"):
        yield


@contextmanager
def former_routes():
    """Inside this context the structured solvers run their former routes: the Hessians of
    :func:`former_hessian` and, in ``arx_barrier``, the former Newton-step algebra (``K⁻¹`` by two triangular
    solves against I, general matrix products with the triangular T(h), the certificate's bounds at every
    centring); in ``column_barrier`` the FFT Hessian and the former path steps (t × 5 from the centred point
    itself).  The same δ to the certified gap; a process-wide switch, restored on leaving.

    Examples
    --------
    >>> import numpy as np, unfalsify as uf
    >>> from unfalsify.solvers import baselines
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(40)
    >>> y = np.convolve(u, [0.0, 1.0, 0.5])[:40] + 0.05 * rng.standard_normal(40)
    >>> a = uf.arx_unfalsify(u, y, 1, 2, 0.02, backend="structured", progress=False)
    >>> with baselines.former_routes():
    ...     b = uf.arx_unfalsify(u, y, 1, 2, 0.02, backend="structured", progress=False)
    >>> bool(abs(a.delta - b.delta) <= 1e-6 * a.delta)
    True
    """
    with _switched(arx_barrier._STEP_ROUTE, "route", "former"), \
            _switched(column_barrier._STEP_ROUTE, "route", "former"), former_hessian():
        yield


@contextmanager
def fft_barrier_hessian():
    """Inside this context ``arx_barrier`` forms its one-channel Hessian (and the h–δ column) by the 2-D FFT of
    :func:`unfalsify.solvers.toeplitz.corr_hessian`, the route before
    :func:`unfalsify.solvers.displacement.displacement_hessian`; everything else as today.  The same δ to the
    certified gap (``tests/test_unfalsify_displacement.py``); a process-wide switch, restored on leaving.

    Examples
    --------
    >>> from unfalsify.solvers import arx_barrier, baselines
    >>> with baselines.fft_barrier_hessian():
    ...     inside = arx_barrier._STEP_ROUTE["hessian"]
    >>> inside, arx_barrier._STEP_ROUTE["hessian"]
    ('fft', 'displacement')
    """
    with _switched(arx_barrier._STEP_ROUTE, "hessian", "fft"):
        yield


@contextmanager
def dense_inverse_blocks():
    """Inside this context ``arx_barrier`` forms the blocks of F⁻¹ densely from the Cholesky factor of K (LAPACK
    potri for K⁻¹, trmm for the products with T(h)), the route before
    :func:`unfalsify.solvers.displacement.inverse_blocks`; everything else as today.  A process-wide switch,
    restored on leaving.

    Examples
    --------
    >>> from unfalsify.solvers import arx_barrier, baselines
    >>> with baselines.dense_inverse_blocks():
    ...     inside = arx_barrier._STEP_ROUTE["blocks"]
    >>> inside, arx_barrier._STEP_ROUTE["blocks"]
    ('dense', 'generators')
    """
    with _switched(arx_barrier._STEP_ROUTE, "blocks", "dense"):
        yield


@contextmanager
def _switched(table: dict, key: str, value: str):
    """``table[key] = value`` inside the context, the former value restored on leaving (also after an error)."""
    former = table[key]
    table[key] = value
    try:
        yield
    finally:
        table[key] = former
