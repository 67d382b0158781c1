"""Least-squares ARX identification with order selection (the textbook identify-then-design baseline).

Model (SISO, delay ``nk ≥ 0``, order ``n``: ``n`` poles and ``n`` input coefficients)::

    y_k + a_1 y_{k−1} + … + a_n y_{k−n} = b_1 u_{k−nk} + … + b_n u_{k−nk−n+1} + e_k

fitted by linear least squares on the record (``N − n − nk`` equations).  Order criteria (``order=``):

``"aic"``
    Akaike's criterion ``AIC(n) = N_n log V_n + 2·(2n)`` (``V_n`` the mean squared one-step residual,
    ``N_n`` the number of equations), minimised over ``1 … max_order``; ``V_n`` below the rounding level
    ``(1000·eps)²·mean(y²)`` counts as that level (an exact fit: the smallest such order wins).
``"validation"``
    The models ``1 … max_order`` are fitted on the first ``1 − validation_fraction`` of the record and
    ``n`` minimises the rms *simulated* output error on the rest (the model run from rest on the hold-out
    input, after a warm-up of ``n + nk`` samples); the model is then refitted on the whole record.
an integer
    A stated order.

The model is returned as a python-control ``StateSpace`` of order ``n + nk − 1`` (``nk ≥ 1``), balanced
by a diagonal similarity (``scipy.linalg.matrix_balance``) so that the companion coefficients of a
lightly damped, fast-sampled plant do not spoil the design.
"""
from __future__ import annotations

import numbers
import warnings
from dataclasses import dataclass

import control
import numpy as np
from scipy.linalg import matrix_balance
from scipy.signal import lfilter

from ._repr import result
from ._validation import DataError, as_signal, check_count, check_sample_time
from .exceptions import PersistenceWarning

__all__ = ["ArxModel", "arx_id"]

#: the order criteria of :func:`arx_id` (besides a stated integer order)
ARX_CRITERIA = ("aic", "validation")
#: AIC counts a mean squared residual below ``(_AIC_ROUNDING·eps)²·mean(y²)`` as that floor (an exact fit)
_AIC_ROUNDING = 1e3


@result
@dataclass(frozen=True, eq=False)
class ArxModel:
    """Result of :func:`arx_id`.

    Attributes
    ----------
    model : control.StateSpace
        ``B(z)/A(z)`` as a discrete state-space model (one input, one output, the data's ``dt``).
    order : int
        ``n``: the number of ``a`` and of ``b`` coefficients.
    delay : int
        ``nk``: the input delay in samples.
    criterion : str
        ``"aic"``, ``"validation"`` or ``"given"``.
    a : ndarray, shape (n + 1,)
        ``[1, a_1, …, a_n]``.
    b : ndarray, shape (n,)
        ``[b_1, …, b_n]`` (the coefficient of ``u_{k−nk}`` first).
    scores : ndarray, shape (max_order,)
        AIC or hold-out rms output error for the orders ``1 … max_order`` (empty for a given order).
    residual_rms : float
        Rms one-step residual of the final fit.
    """

    model: control.StateSpace
    order: int
    delay: int
    criterion: str
    a: np.ndarray
    b: np.ndarray
    scores: np.ndarray
    residual_rms: float


def _fit(u, y, n, nk):
    """Least-squares ``(a, b, residual, rank)``; equations for ``k = n + nk − 1 … N − 1`` (all lags available),
    ``rank`` the regressor's numerical rank (``lstsq``'s)."""
    N = y.size
    k0 = max(n, n + nk - 1)
    rows = np.arange(k0, N)
    Phi = np.column_stack([-y[rows - t] for t in range(1, n + 1)] + [u[rows - nk - t] for t in range(n)])
    theta, _, r, _ = np.linalg.lstsq(Phi, y[rows], rcond=None)
    res = y[rows] - Phi @ theta
    return np.concatenate([[1.0], theta[:n]]), theta[n:], res, int(r)


def _num(b, nk):
    return np.concatenate([np.zeros(nk), b])             # B(z⁻¹) = z^{-nk}(b_1 + b_2 z⁻¹ + …)


def _simulate(a, b, nk, u):
    return lfilter(_num(b, nk), a, u)


def arx_id(u, y, *, order="aic", max_order: int = 10, delay: int = 1, dt=None,
           validation_fraction: float = 1 / 3) -> ArxModel:
    """Least-squares ARX model of a SISO record with the order chosen by AIC, hold-out error or given.

    Parameters
    ----------
    u, y : array_like, shape (N,) or (N, 1)
        Input and output records (one channel each; for several channels use
        :func:`~synthesis.subspace_id`).
    order : {"aic", "validation"} or int
        Order criterion (module docstring), default AIC.
    max_order : int
        Largest order tried by the criteria (default 10).
    delay : int
        Input delay ``nk`` in samples (default 1: a strictly proper, ZOH-sampled plant; 0 estimates a
        feedthrough).
    dt : float, optional
        Sample time of the model (default ``True``, unspecified).
    validation_fraction : float
        Share of the record held out by ``order="validation"`` (in ``(0, 0.9]``).

    Returns
    -------
    ArxModel

    Raises
    ------
    DataError
        Bad or multichannel data, bad ``order``, ``max_order``, ``delay``, ``dt``, too few samples.

    Warns
    -----
    PersistenceWarning
        The chosen order's regressor is rank deficient: the data do not determine the coefficients.

    Examples
    --------
    Noise-free data of a second-order plant: AIC picks order 2 (higher orders do not lower the
    residual below rounding) and the coefficients are recovered.

    >>> import numpy as np
    >>> from scipy.signal import lfilter
    >>> u = np.random.default_rng(0).standard_normal(300)
    >>> y = lfilter([0, 0.5, 0.3], [1, -1.2, 0.5], u)
    >>> m = arx_id(u, y, order=2, dt=0.1)
    >>> print(np.round(m.a, 6), np.round(m.b, 6))
    [ 1.  -1.2  0.5] [0.5 0.3]
    """
    u = as_signal(u, "u")
    y = as_signal(y, "y", n=u.shape[0])
    if u.shape[1] != 1 or y.shape[1] != 1:
        raise DataError(f"arx_id is single-input single-output; got {u.shape[1]} input(s) and {y.shape[1]} output(s): "
                        "use synthesis.subspace_id for several channels")
    u, y = u[:, 0], y[:, 0]
    N = u.size
    dt = True if dt is None else check_sample_time(dt, "dt")
    max_order, delay = check_count(max_order, "max_order", 1), check_count(delay, "delay", 0)
    if isinstance(order, str):
        if order not in ARX_CRITERIA:
            raise DataError(f"order must be one of {ARX_CRITERIA} or a positive integer, got {order!r}")
        top = max_order
    elif isinstance(order, bool) or not isinstance(order, numbers.Integral) or order < 1:
        raise DataError(f"order must be 'aic', 'validation' or an integer >= 1, got {order!r}")
    else:
        top = int(order)
    if not (isinstance(validation_fraction, numbers.Real) and 0 < validation_fraction <= 0.9):
        raise DataError(f"validation_fraction must lie in (0, 0.9], got {validation_fraction!r}")
    need = 4 * (2 * top + delay) + 10
    if N < need:
        raise DataError(f"{N} samples are too few for ARX orders up to {top}: collect at least {need} or lower "
                        "max_order")

    if order == "aic":
        scores = np.empty(max_order)
        # residuals at rounding level are all "zero": below this floor log V would rank them by rounding noise
        # (noise-free data of a second-order plant had given AIC orders 2, 3 or 4 with the seed of the data)
        floor = max((_AIC_ROUNDING * np.finfo(float).eps) ** 2 * float(np.mean(y ** 2)), 1e-300)
        for n in range(1, max_order + 1):
            _, _, res, _ = _fit(u, y, n, delay)
            V = max(float(np.mean(res ** 2)), floor)
            scores[n - 1] = res.size * np.log(V) + 2 * (2 * n)
        n, criterion = int(np.argmin(scores)) + 1, "aic"
    elif order == "validation":
        N_est = int(round(N * (1 - validation_fraction)))
        if N_est < need or N - N_est < 2 * (max_order + delay) + 10:
            raise DataError(f"too few samples to hold out {validation_fraction:.3g} of {N}: collect more data or use "
                            "order='aic'")
        scores = np.full(max_order, np.inf)
        warm = max_order + delay
        for n in range(1, max_order + 1):
            a, b, _, _ = _fit(u[:N_est], y[:N_est], n, delay)
            if np.max(np.abs(np.roots(a))) >= 1.05:
                continue                                   # diverges on the hold-out: not a candidate
            # run over the whole record (no reset at the split), score on the hold-out only
            y_sim = _simulate(a, b, delay, u)
            err = float(np.sqrt(np.mean((y[N_est + warm:] - y_sim[N_est + warm:]) ** 2)))
            scores[n - 1] = err if np.isfinite(err) else np.inf
        n, criterion = int(np.argmin(scores)) + 1, "validation"
    else:
        n, scores, criterion = int(order), np.zeros(0), "given"
    a, b, res, r = _fit(u, y, n, delay)
    if r < 2 * n:
        warnings.warn(
            f"the ARX regressor of order {n} has rank {r} of {2 * n}: the record does not determine a and b (an input "
            "that is zero, constant or a single sine, or an output that a lower order already explains exactly), so "
            "the model is one of many that fit; excite more frequencies (a PRBS or a multisine) or lower the order",
            PersistenceWarning, stacklevel=2)
    num = _num(b, delay)
    den = np.concatenate([a, np.zeros(max(num.size - a.size, 0))])   # polynomials in z⁻¹ → in z (same length)
    num = np.concatenate([num, np.zeros(max(den.size - num.size, 0))])
    sys = control.ss(control.tf(num, den, dt))
    A, B, C, D = (np.asarray(M, float) for M in control.ssdata(sys))
    if A.size:
        _, T = matrix_balance(A, permute=False, separate=False)      # diagonal similarity (powers of 2)
        Ti = np.linalg.inv(T)
        A, B, C = Ti @ A @ T, Ti @ B, C @ T
    model = control.ss(A, B, C, D, dt, inputs=["u[0]"], outputs=["y[0]"], name="arx_id")
    return ArxModel(model=model, order=n, delay=delay, criterion=criterion, a=a, b=b, scores=np.asarray(scores),
                    residual_rms=float(np.sqrt(np.mean(res ** 2))))
