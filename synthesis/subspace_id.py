"""Subspace identification of a state-space model from the predictor's ``L_w`` (N4SID/MOESP style).

The identify-then-design baseline of the model-free method uses the same Hankel data and the same
least-squares predictor (2.5): the part of the future outputs explained by the past,
``O_i = L_w W_p`` (the N4SID oblique projection), equals ``Γ_i X_f`` on noise-free data — the extended
observability matrix times the state sequence.  Its SVD ``O_i / √j = U Σ Vᵀ`` gives

* the **order** ``n`` from the singular values (criterion below);
* ``Γ_i = U_n Σ_n^{1/2}``, hence ``C`` (its first block row) and ``A`` (shift invariance,
  ``Γ_i[:-l] A = Γ_i[l:]`` by least squares);
* ``B``, ``D`` and the initial state by linear least squares on the whole record, the outputs being
  linear in them once ``A`` and ``C`` are fixed (as MOESP and ``n4sid``'s "simulation" focus do).

Order criteria (``order=``):

``"floor"`` (default)
    The stated singular-value criterion: ``n`` is the number of ``σ_k`` (``k ≤ max_order``) above
    ``floor_ratio`` (default 5) times the *noise floor*, the median of the lower half of the singular
    values (``k > i·l/2``: on data from a plant of order ``< i·l/2`` these are noise alone), and at
    least ``1000·eps·σ₁`` (rounding).  On noise-free data the floor is that rounding level and ``n`` is
    exact.  Measured on PRBS data with
    noise (``experiments compare``): the physical order on the 10 Hz catalogue plants, 6–7 on the
    three-disk plant (order 6).
``"gap"``
    The classical alternative: ``n = argmax_{1 ≤ k ≤ max_order} σ_k / σ_{k+1}``, the largest drop of
    the (log) singular values; exact on noise-free data, but it stops at the first big drop when one
    mode dominates (the servo's integrator: order 1 instead of 2; the three-disk plant: 1 instead of 6).
``"validation"``
    The alternative: the SVD and every candidate model ``1 … max_order`` are fitted on the first
    ``1 − validation_fraction`` of the record and ``n`` minimises the rms simulated output error on the
    rest (initial state fitted there, as a ``compare`` would); the model is then refitted on the
    whole record at that order.
an integer
    A stated order (e.g. the physical one).
"""
from __future__ import annotations

import numbers
import warnings
from dataclasses import dataclass

import control
import numpy as np
from scipy.signal import fftconvolve

from ._repr import result
from ._validation import DataError, as_signal, check_flag, check_horizon, check_sample_time
from .exceptions import OrderWarning
from .predictor import _power_of_two_rms, block_hankel, fit_predictor

__all__ = ["SubspaceModel", "subspace_id"]

#: the order criteria of :func:`subspace_id` (besides a stated integer order)
ORDER_CRITERIA = ("floor", "gap", "validation")


@result
@dataclass(frozen=True, eq=False)
class SubspaceModel:
    """Result of :func:`subspace_id`.

    Attributes
    ----------
    model : control.StateSpace
        The identified discrete model ``(A, B, C, D)``, ``m`` inputs, ``l`` outputs, the data's ``dt``.
    order : int
        Its state dimension ``n``.
    criterion : str
        How ``order`` was chosen: ``"floor"``, ``"gap"``, ``"validation"`` or ``"given"``.
    singular_values : ndarray
        Singular values of ``L_w W_p / √j`` (on the whole record), largest first, for the data with each
        ``u`` and ``y`` channel scaled to unit rms by a power of two (so that the order criteria do not depend
        on the units; the model is scaled back).
    scores : ndarray, shape (max_order,)
        The criterion's value for the orders ``1 … max_order``: ``σ_k / floor`` for ``"floor"``,
        ``log(σ_k/σ_{k+1})`` for ``"gap"``,
        the hold-out rms output error for ``"validation"``, empty for a given order.
    horizon : int
        The predictor's horizon ``i``.
    fit_rms : float
        Rms of ``y − ŷ`` on the record, ``ŷ`` the model's simulated output (initial state fitted).
    """

    model: control.StateSpace
    order: int
    criterion: str
    singular_values: np.ndarray
    scores: np.ndarray
    horizon: int
    fit_rms: float


def _past_projection(u, y, i, method):
    """``(singular values, U)`` of ``L_w W_p / √j`` from the predictor of horizon ``i``."""
    pred = fit_predictor(u, y, i, method=method)
    j = u.shape[0] - 2 * i + 1
    Wp = np.vstack([block_hankel(u, i, j, 0), block_hankel(y, i, j, 0)])
    R = np.linalg.qr(Wp.T, mode="r")                     # Wp = Rᵀ Qᵀ: the SVD of L_w Rᵀ is that of L_w W_p
    U, s, _ = np.linalg.svd(np.asarray(pred.Lw) @ R.T / np.sqrt(j), full_matrices=False)
    return s, U


def _ac_from_gamma(U, s, n, l):
    G = U[:, :n] * np.sqrt(s[:n])
    C = G[:l]
    A = np.linalg.lstsq(G[:-l], G[l:], rcond=None)[0]
    return A, C


def _regressors(A, C, u, feedthrough):
    """Columns of ``y`` linear in ``[vec B; vec D; x0]`` for fixed ``(A, C)``; shape ``(N·l, p)``."""
    N, m = u.shape
    n, l = A.shape[0], C.shape[0]
    CA = np.empty((N, l, n))                             # CA[k] = C A^k
    M = C.copy()
    for k in range(N):
        CA[k] = M
        M = M @ A
    cols = []
    for b in range(m):                                   # B[a, b]: y_k = Σ_t C A^{k-1-t} e_a u_t
        for a in range(n):
            g = np.concatenate([np.zeros((1, l)), CA[:-1, :, a]])          # impulse response of (A, e_a, C)
            cols.append(fftconvolve(u[:, b][:, None], g, axes=0)[:N].reshape(-1))
    if feedthrough:
        for b in range(m):
            for c in range(l):
                col = np.zeros((N, l))
                col[:, c] = u[:, b]
                cols.append(col.reshape(-1))
    for a in range(n):                                   # x0
        cols.append(CA[:, :, a].reshape(-1))
    return np.column_stack(cols) if cols else np.zeros((N * l, 0))


def _channel_units(x: np.ndarray) -> np.ndarray:
    """Power-of-two scale of each channel (column) of ``x``: ``2^round(log2(rms))``, 1 for an all-zero channel.

    :func:`subspace_id` identifies from the channels divided by it (exactly) and scales the model back, so that
    the order it finds does not depend on the units of the outputs: the singular values of ``L_w W_p`` mix the
    output channels, and one output in a unit 100 times smaller than the natural one (its modes and noise 100
    times weaker) had put the noise floor of the lower half at that channel's noise, so that the floor criterion
    took the largest order (8 instead of 3: a model with rms output error 2.6 on data with noise 0.01), and at
    ``1e-5`` the fit of ``B``, ``D`` and ``x0`` raised ``LinAlgError``.
    """
    return _power_of_two_rms(np.mean(x * x, axis=0))


def _bd_x0(A, C, u, y, feedthrough, y_units=None):
    """``B``, ``D``, ``x0`` by least squares and the rms output error (of ``y * y_units`` when given)."""
    n, l, m = A.shape[0], C.shape[0], u.shape[1]
    Phi = _regressors(A, C, u, feedthrough)
    theta = np.linalg.lstsq(Phi, y.reshape(-1), rcond=None)[0]
    B = theta[: n * m].reshape(m, n).T
    k = n * m
    D = np.zeros((l, m))
    if feedthrough:
        D = theta[k: k + l * m].reshape(m, l).T
        k += l * m
    x0 = theta[k:]
    res = (y.reshape(-1) - Phi @ theta).reshape(-1, l)
    rms = float(np.sqrt(np.mean((res if y_units is None else res * y_units) ** 2)))
    return B, D, x0, rms


def _output_error(A, B, C, D, u, y):
    """Rms simulated output error on ``(u, y)``, the initial state fitted by least squares."""
    N, l = y.shape
    y0 = control.forced_response(control.ss(A, B, C, D, True), U=u.T, squeeze=False).outputs.T
    # initial-state part: C A^k x0
    n = A.shape[0]
    CA = np.empty((N, l, n))
    M = C.copy()
    for k in range(N):
        CA[k] = M
        M = M @ A
    Phi = CA.reshape(N * l, n)
    r = (y - y0).reshape(-1)
    if n:
        r = r - Phi @ np.linalg.lstsq(Phi, r, rcond=None)[0]
    err = float(np.sqrt(np.mean(r ** 2)))
    return err if np.isfinite(err) else float("inf")


def _warn_capped(n: int, criterion: str, i: int, l: int) -> None:
    """Warn that the criterion took the largest order it was allowed: it cannot say whether the plant's is higher
    (measured: a fifth-order plant at i = 8, one output, came out of order 4, the default cap ⌊i·l/2⌋, rms output
    error 0.56 on noise-free data, without a word)."""
    room = "the horizon" if criterion == "floor" else "max_order (up to i·l − 1) or the horizon"
    warnings.warn(f"the '{criterion}' criterion chose order {n} = max_order, the largest it considered: the plant's "
                  f"order may be higher; raise {room} (i = {i}, l = {l}; the default max_order is "
                  "min(⌊i·l/2⌋, 20))", OrderWarning, stacklevel=3)


def subspace_id(u, y, horizon: int, *, order="floor", floor_ratio: float = 5.0, max_order: int | None = None, dt=None,
                feedthrough: bool = False, validation_fraction: float = 1 / 3,
                method: str = "qr") -> SubspaceModel:
    """Identify a state-space model from ``(u, y)`` through the SVD of the predictor's ``L_w W_p``.

    Parameters
    ----------
    u : array_like, shape (N,) or (N, m)
        Input record, time along axis 0.
    y : array_like, shape (N,) or (N, l)
        Output record.
    horizon : int
        Predictor horizon ``i`` (:func:`~synthesis.fit_predictor`); must exceed the order
        (``i·l > max_order``).
    order : {"floor", "gap", "validation"} or int
        Order criterion (module docstring): singular values above the noise floor (default), the
        largest singular-value gap, the hold-out simulated output error, or a stated order.
    floor_ratio : float
        ``"floor"``: how many times the noise floor a singular value must exceed (default 5).
    max_order : int, optional
        Largest order considered, default ``min(⌊i·l/2⌋, 20)``.
    dt : float or True, optional
        The data's sample time in seconds, stored in the model.  Default (None): ``True``,
        python-control's discrete time with an unspecified sample time, as :func:`~synthesis.arx_id`
        gives and :func:`~synthesis.validation.check_sample_time` accepts: the model combines with
        systems of any sample time and takes theirs; ``dt=1`` would state one second.  Pass the
        data's sample time before designing with :func:`~synthesis.discrete_mixsyn`, which needs a
        number and says so.
    feedthrough : bool
        Estimate ``D`` (default False: ``D = 0``, as for every ZOH-sampled physical plant).
    validation_fraction : float
        Share of the record held out by ``order="validation"`` (in ``(0, 0.9]``).
    method : str
        :func:`~synthesis.fit_predictor` method (default ``"qr"``: the small singular values the
        order criterion reads are accurate to rounding).

    Returns
    -------
    SubspaceModel

    Raises
    ------
    DataError
        Bad data, horizon, order, ``max_order``, ``dt`` or ``validation_fraction`` (the message names
        the fix).

    Warns
    -----
    OrderWarning
        The criterion chose ``max_order``, the largest order it considered: the plant's may be higher.
    PersistenceWarning
        From the predictor fit on noise-free data (the regressor is rank deficient; the part
        ``L_w W_p`` used here is still determined).

    Examples
    --------
    Noise-free data of a second-order plant: the noise-floor criterion finds order 2 and the transfer
    function is recovered.

    >>> import warnings
    >>> import control, numpy as np
    >>> P = control.tf([0.5, 0.3], [1, -1.2, 0.5], 0.1)
    >>> u = np.random.default_rng(0).standard_normal(400)
    >>> y = control.forced_response(P, U=u).outputs
    >>> with warnings.catch_warnings():
    ...     warnings.simplefilter("ignore")             # noise-free: rank-deficient regressor
    ...     sid = subspace_id(u, y, 6, dt=0.1)
    >>> sid.order, sid.criterion
    (2, 'floor')
    >>> G = control.tf(sid.model)
    >>> print(np.round(G.num[0][0] / G.den[0][0][0], 6), np.round(G.den[0][0] / G.den[0][0][0], 6))
    [0.5 0.3] [ 1.  -1.2  0.5]

    Without ``dt`` the model is discrete with an unspecified sample time, which a product with a
    system sampled at 0.1 s takes on:

    >>> with warnings.catch_warnings():
    ...     warnings.simplefilter("ignore")
    ...     free = subspace_id(u, y, 6).model
    >>> free.dt, (free * control.tf(1, [1, -0.5], 0.1)).dt
    (True, 0.1)
    """
    u = as_signal(u, "u")
    y = as_signal(y, "y", n=u.shape[0])
    N, m = u.shape
    l = y.shape[1]
    i = check_horizon(horizon, N)
    dt = True if dt is None else check_sample_time(dt, "dt")
    feedthrough = check_flag(feedthrough, "feedthrough")
    if max_order is None:
        max_order = max(1, min(i * l // 2, 20))
    if isinstance(max_order, bool) or not isinstance(max_order, numbers.Integral) or not 1 <= max_order < i * l:
        raise DataError(f"max_order must be an integer in [1, i·l − 1] = [1, {i * l - 1}], got {max_order!r}; "
                        "raise the horizon to consider higher orders")
    max_order = int(max_order)
    if isinstance(order, str):
        if order not in ORDER_CRITERIA:
            raise DataError(f"order must be one of {ORDER_CRITERIA} or a positive integer, got {order!r}")
    elif isinstance(order, bool) or not isinstance(order, numbers.Integral) or not 1 <= order < i * l:
        raise DataError(f"order must be 'floor', 'gap', 'validation' or an integer in [1, i·l − 1] = [1, {i * l - 1}], "
                        f"got {order!r}; raise the horizon for a higher order")
    if not (isinstance(validation_fraction, numbers.Real) and 0 < validation_fraction <= 0.9):
        raise DataError(f"validation_fraction must lie in (0, 0.9], got {validation_fraction!r}")
    if N - 2 * i + 1 < i * (2 * m + l):
        raise DataError(f"{N} samples give j = {N - 2 * i + 1} Hankel columns for {i * (2 * m + l)} regressors "
                        f"at horizon {i}: collect at least {i * (2 * m + l) + 2 * i - 1} samples or lower the horizon")

    if isinstance(floor_ratio, bool) or not isinstance(floor_ratio, numbers.Real) or not floor_ratio > 1:
        raise DataError(f"floor_ratio must be a number > 1, got {floor_ratio!r}")
    u_units, y_units = _channel_units(u), _channel_units(y)
    u, y = u / u_units, y / y_units  # channels of unit rms (exact): the order does not depend on the units
    s, U = _past_projection(u, y, i, method)
    if order == "floor":
        if i * l < 2 * max_order:
            raise DataError(f"order='floor' needs i·l ≥ 2·max_order (the lower half of the {i * l} singular values "
                            f"is the noise floor): raise the horizon above {2 * max_order // l} or lower max_order")
        floor = max(float(np.median(s[i * l // 2:])), 1e3 * np.finfo(float).eps * float(s[0]), 1e-300)
        scores = s[:max_order] / floor
        n, criterion = max(1, int(np.sum(scores > floor_ratio))), "floor"
    elif order == "gap":
        ratios = np.log(np.maximum(s[:max_order], 1e-300) / np.maximum(s[1:max_order + 1], 1e-300))
        n, scores, criterion = int(np.argmax(ratios)) + 1, ratios, "gap"
    elif order == "validation":
        N_est = int(round(N * (1 - validation_fraction)))
        if N_est - 2 * i + 1 < i * (2 * m + l) or N - N_est < 2 * max_order + 2:
            raise DataError(f"too few samples to hold out {validation_fraction:.3g} of {N} for validation at horizon "
                            f"{i}: collect more data, lower the horizon or use order='gap'")
        s_e, U_e = _past_projection(u[:N_est], y[:N_est], i, method)
        scores = np.full(max_order, np.inf)
        for k in range(1, max_order + 1):
            A, C = _ac_from_gamma(U_e, s_e, k, l)
            B, D, _, _ = _bd_x0(A, C, u[:N_est], y[:N_est], feedthrough)
            if np.all(np.isfinite(A)) and np.max(np.abs(np.linalg.eigvals(A))) < 1.05:
                scores[k - 1] = _output_error(A, B, C, D, u[N_est:], y[N_est:])
        n, criterion = int(np.argmin(scores)) + 1, "validation"
    else:
        n, scores, criterion = int(order), np.zeros(0), "given"
    if criterion != "given" and n == max_order:
        _warn_capped(n, criterion, i, l)
    A, C = _ac_from_gamma(U, s, n, l)
    B, D, _, rms = _bd_x0(A, C, u, y, feedthrough, y_units)
    B, C, D = B / u_units, y_units[:, None] * C, y_units[:, None] * D / u_units  # back to the data's units
    model = control.ss(A, B, C, D, dt, inputs=[f"u[{c}]" for c in range(m)],
                       outputs=[f"y[{c}]" for c in range(l)], name="subspace_id")
    return SubspaceModel(model=model, order=n, criterion=criterion, singular_values=s, scores=np.asarray(scores),
                         horizon=i, fit_rms=rms)
