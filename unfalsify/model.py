"""The data-based nominal model P̂ that the §7.4 pipeline certifies its loop on.

The subspace predictor ``ŷ = L_w w_p + L_u u_f`` (2.6) says, in its first block row, how the
next output follows from the last ``i`` inputs and outputs and the current input:

    ŷ_k = L_w[:l] w_p(k) + L_u[:l, :m] u_k,      w_p(k) = [u_{k−i} … u_{k−1}; y_{k−i} … y_{k−1}]  (3.13).

That is an ARX model of order ``i``, ``A(q) y_k = B(q) u_k``.  :func:`predictor_model`
realises it in the delay-line state ``x_k = w_p(k)`` -- the same state the LTI controller
(5.3)–(5.4) keeps -- so the model has order ``i(m + l)``: the poles are the roots of
``det A(z)`` plus ``i·m`` poles at ``z = 0`` from the input delay line (harmless for stability).

On noise-free data of a plant of order ``≤ i`` with persistent excitation, the predictor
reproduces the plant's Markov parameters (2.10)–(2.12) and the model's frequency response
equals the plant's (a common factor of ``A`` and ``B`` may appear; it cancels in ``B/A``).
With noisy data it is the least-squares one-step-ahead model.
"""
from __future__ import annotations

import control
import numpy as np

from synthesis.validation import DataError, check_predictor_dt, check_sample_time

__all__ = ["predictor_model"]


def predictor_model(pred, dt=None) -> control.StateSpace:
    """ARX model ``P̂`` of the predictor's first block row, in the delay-line state ``w_p``.

    Parameters
    ----------
    pred : synthesis.Predictor
        Any object with ``Lw`` (``il × i(m+l)``), ``Lu`` (``il × im``), ``horizon``, ``m``, ``l``.
    dt : float or True, optional
        The data's sample time.  Default: the predictor's (``fit_predictor(u, y, i, dt=...)``,
        :attr:`synthesis.Predictor.dt`); required when the predictor carries none, refused when it
        differs from the predictor's.

    Returns
    -------
    control.StateSpace
        Discrete model, ``m`` inputs ``u``, ``l`` outputs ``y``, order ``i(m + l)``:
        ``x_{k+1} = A x_k + B u_k``, ``y_k = C x_k + D u_k`` with ``x_k = w_p(k)``,
        ``C = L_w[:l]``, ``D = L_u[:l, :m]``.

    Raises
    ------
    DataError
        A predictor with NaN entries or inconsistent shapes, or a bad sample time (none, or not the
        predictor's).

    Examples
    --------
    >>> import numpy as np
    >>> import control
    >>> import synthesis as sy
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(60)
    >>> y = np.convolve(u, [0.0, 1.0, 0.5])[:60]                     # y_k = u_{k−1} + 0.5 u_{k−2}
    >>> P = predictor_model(sy.fit_predictor(u, y, 2), 1.0)
    >>> P.ninputs, P.noutputs, P.nstates, P.dt                       # order i(m + l) = 4
    (1, 1, 4, 1.0)
    >>> g = np.ravel(control.impulse_response(P, T=np.arange(4)).outputs)
    >>> bool(np.allclose(g, [0.0, 1.0, 0.5, 0.0], atol=1e-6))          # the plant's impulse response
    True
    """
    try:
        i, m, l = int(pred.horizon), int(pred.m), int(pred.l)
        Lw, Lu = np.asarray(pred.Lw, dtype=float), np.asarray(pred.Lu, dtype=float)
    except (AttributeError, TypeError, ValueError) as exc:
        raise DataError(f"predictor_model needs a synthesis.Predictor (Lw, Lu, horizon, m, l): {exc}") from None
    nu, ny = i * m, i * l
    if Lw.shape != (ny, nu + ny) or Lu.shape != (ny, nu):
        raise DataError(f"predictor has Lw {Lw.shape} and Lu {Lu.shape}; expected ({ny}, {nu + ny}) and ({ny}, {nu}) "
                        f"for i = {i}, m = {m}, l = {l}")
    if not (np.all(np.isfinite(Lw)) and np.all(np.isfinite(Lu))):
        raise DataError("predictor contains NaN or infinite entries; refit it on finite data")
    dt = check_predictor_dt(pred, dt)
    if dt is None:
        raise DataError("the predictor carries no sample time: pass dt= (the data's), or fit it with "
                        "synthesis.fit_predictor(u, y, i, dt=...)")
    dt = check_sample_time(dt, "dt")
    return _delay_line(Lw[:l], Lu[:l, :m], i, m, l, dt)


def _delay_line(C, D, i: int, m: int, l: int, dt: float, disturbance: bool = False) -> control.StateSpace:
    """The delay-line realisation of ``y_k = C w_p(k) + D u_k`` (+ ``v_k`` with ``disturbance``: inputs ``[u; v]``).

    ``v`` enters the equation ``y_k = C w_p(k) + D u_k + v_k`` itself, so it reaches the state like ``y_k`` does:
    that is the input of the coprime factors' equation ``M̂ y = N̂ u + v`` (:mod:`unfalsify.coprime`).
    """
    nu, ny = i * m, i * l
    n = nu + ny
    A = np.zeros((n, n))
    B = np.zeros((n, m + (l if disturbance else 0)))
    A[: nu - m, m:nu] = np.eye(nu - m)          # u_{k-i+1} … u_{k-1} move up
    B[nu - m: nu, :m] = np.eye(m)               # u_k enters last
    A[nu: n - l, nu + l:] = np.eye(ny - l)      # y_{k-i+1} … y_{k-1} move up
    A[n - l:] = C                               # y_k = C x_k + D u_k (+ v_k) enters last
    B[n - l:, :m] = D
    Dfull = np.asarray(D, float)
    inputs = [f"u[{c}]" for c in range(m)]
    if disturbance:
        B[n - l:, m:] = np.eye(l)
        Dfull = np.hstack([Dfull, np.eye(l)])
        inputs += [f"v[{c}]" for c in range(l)]
    return control.ss(A, B, np.asarray(C, float), Dfull, dt, inputs=inputs,
                      outputs=[f"y[{c}]" for c in range(l)], name="predictor_model")
