"""Model-free subspace based finite-horizon LQG regulator (thesis Thm 4.1, (4.2)–(4.6)).

    u_opt = −(L_uᵀ Q_diag L_u + R_diag)⁻¹ L_uᵀ Q_diag L_w w_p        (4.2)

minimises ``Σ_{t=k}^{k+i-1} y_tᵀQ y_t + u_tᵀR u_t`` over the horizon with ``y`` predicted by
(2.6).  It is computed here as the least-squares problem
``min_u ‖[Q_c L_u; R_c] u + [Q_c L_w; 0] w_p‖`` with ``Q_cᵀQ_c = Q_diag``, ``R_cᵀR_c = R_diag``
(no normal equations).  Theorem 4.2: it is the γ → ∞ limit of the H∞ law with constant
weights ``W1ᵀW1 = Q``, ``W2ᵀW2 = R``.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import control
import numpy as np

from ._validation import DataError, as_real_array, check_predictor_dt, check_sample_time
from .controller import lti_controller
from ._repr import result

__all__ = ["LqgDesign", "lqg_design"]


@result
@dataclass(frozen=True, eq=False)
class LqgDesign:
    """A subspace LQG design (Thm 4.1).

    Attributes
    ----------
    gain : ndarray, shape (i·m, i(m+l))
        ``u_opt = gain @ w_p`` (4.2), columns ordered as ``w_p`` (3.13).
    controller : control.StateSpace
        The LTI form (5.3)–(5.4) with state ``[u_p; y_p]``; inputs ``[r; y]`` for a common
        closed-loop interface with the H∞ designs (the regulator ignores ``r``: its
        columns of ``B`` and ``D`` are 0); sample time :attr:`dt`.
    Q, R : ndarray
        Output and input weights (``l×l`` and ``m×m``, symmetric positive definite).
    columns : tuple
        ``(("w_p", i(m+l)),)``.
    weight_states : tuple
        Empty (no weighting filters).
    """

    predictor: object
    Q: np.ndarray
    R: np.ndarray
    horizon: int
    m: int
    l: int
    dt: float
    gain: np.ndarray
    columns: tuple
    weight_states: tuple = ()
    causal: bool = False
    controller: control.StateSpace | None = None

    @property
    def first_gain(self) -> np.ndarray:
        return self.gain[: self.m]


def _spd(M, n: int, name: str) -> np.ndarray:
    M = np.atleast_2d(as_real_array(M, name))  # numbers only: asarray(float) had parsed "1" (and dropped 0j)
    if M.shape == (1, 1) and n > 1:
        M = M[0, 0] * np.eye(n)
    if M.shape != (n, n):
        raise DataError(f"{name} must be a scalar or a {n}×{n} matrix, got shape {M.shape}")
    if not np.all(np.isfinite(M)):
        raise DataError(f"{name} contains NaN or infinite values")
    if not np.allclose(M, M.T, rtol=1e-10, atol=1e-12 * max(1.0, np.abs(M).max())):
        raise DataError(f"{name} must be symmetric")
    try:
        np.linalg.cholesky(M)
    except np.linalg.LinAlgError as exc:
        raise DataError(f"{name} must be positive definite (Thm 4.1 requires {name} = {name}ᵀ > 0)") from exc
    return M


def lqg_design(pred, Q, R, *, dt=None) -> LqgDesign:
    """Subspace LQG law (4.2) and its LTI controller.

    Parameters
    ----------
    pred : Predictor
    Q : scalar or (l, l) array
        Output weight, ``Q = Qᵀ > 0``.
    R : scalar or (m, m) array
        Input weight, ``R = Rᵀ > 0``.
    dt : float or True, optional
        Sample time of the data, given to the controller.  Default: the predictor's
        (``fit_predictor(u, y, i, dt=...)``, :attr:`Predictor.dt`), else ``True`` (unspecified but
        discrete).  A ``dt`` that differs from the predictor's is refused.

    Returns
    -------
    LqgDesign

    Raises
    ------
    DataError
        Predictor of the wrong shape or with NaN, ``Q``/``R`` not symmetric positive definite or
        of the wrong size, ``dt`` not a positive sample time (0 would make the controller
        continuous-time) or not the predictor's.

    Warns
    -----
    HorizonWarning
        If the data show no effect of the control on the predicted output over the horizon (as
        :func:`~synthesis.hinf_design`).

    Examples
    --------
    >>> import numpy as np
    >>> from synthesis import fit_predictor, hinf_design
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(200)
    >>> y = np.convolve(u, [0.0, 0.5, 0.2])[:200] + 0.01 * rng.standard_normal(200)
    >>> pred = fit_predictor(u, y, 4)
    >>> lqg = lqg_design(pred, 1.0, 0.01, dt=0.1)
    >>> lqg.gain.shape, lqg.controller.nstates, lqg.controller.dt
    ((4, 8), 8, 0.1)

    The gain is (4.2) by the normal equations, and (Thm 4.2) the H∞ law at ``γ = ∞`` with
    ``W1 = √Q``, ``W2 = √R``:

    >>> Lw, Lu = pred.Lw, pred.Lu
    >>> np.allclose(lqg.gain, -np.linalg.solve(Lu.T @ Lu + 0.01 * np.eye(4), Lu.T @ Lw))
    True
    >>> np.allclose(lqg.gain, hinf_design(pred, 1.0, 0.1, gamma=np.inf).gain)
    True
    """
    from .hinf import _predictor_parts, _warn_no_control  # shared validation

    Lw, Lu, i, m, l = _predictor_parts(pred)
    dt = check_predictor_dt(pred, dt)
    dt = check_sample_time(True if dt is None else dt)
    Q = _spd(Q, l, "Q")
    R = _spd(R, m, "R")
    _warn_no_control(pred, stacklevel=2)
    Qc = np.kron(np.eye(i), np.linalg.cholesky(Q).T)  # Q_cᵀ Q_c = Q_diag
    Rc = np.kron(np.eye(i), np.linalg.cholesky(R).T)
    A = np.vstack([Qc @ Lu, Rc])
    b = np.vstack([Qc @ Lw, np.zeros((i * m, Lw.shape[1]))])
    gain = -np.linalg.lstsq(A, b, rcond=None)[0]
    design = LqgDesign(predictor=pred, Q=Q, R=R, horizon=i, m=m, l=l, dt=dt, gain=gain,
                       columns=(("w_p", i * (m + l)),))
    return dataclasses.replace(design, controller=lti_controller(design))
