"""Model-based finite-horizon H∞ and LQR laws by Riccati recursions (thesis §4.2).

* :func:`generalized_plant` — the full-information generalized plant of §4.2.1,
  state ``x = [x_p; x_w1; x_w2]``, inputs ``[r; u]``, outputs ``z = [z_w1; z_w2]``.
* :func:`hinf_riccati` — the backward recursion (4.16)–(4.17) and the forward
  recursion (4.18)–(4.19) for the worst-case references and the minimax controls.
* :func:`lqr_riccati` — the finite-horizon LQR (4.21)–(4.24).

Theorems 4.3 and 4.4: on noise-free data from an LTI plant, the subspace laws
(3.6) and (4.2) equal these recursions acting on the true state; the tests check it.

Erratum (4.21): with the cost ``Σ_{t=k}^{k+i-1} y_tᵀQy_t + u_tᵀRu_t`` of (4.3) the
matrix used at the last stage is the cost-to-go *after* it, ``P_{k+i-1} = 0``
(as in (4.16) and in the substitution list of the proof of Thm 4.3), not
``C_pᵀQC_p``; the literal (4.21) adds a terminal term ``y_{k+i}ᵀQy_{k+i}`` and does
not reproduce the batch law (4.20).  :func:`lqr_riccati` uses 0 by default and
accepts ``terminal=`` for the literal form.
Sign (4.29): the stationarity condition gives ``w = −(HᵀH − R_γd)⁻¹HᵀΓx``.
"""
from __future__ import annotations

from dataclasses import dataclass

import control
import numpy as np

from .exceptions import StageSaddleError

from ._validation import DataError, as_discrete_system, as_real_array, check_count, check_horizon, check_level
from .weights import _ss_parts, as_weight, common_dt
from ._repr import result

__all__ = ["GeneralizedPlant", "RiccatiLaw", "StageSaddleError", "generalized_plant", "hinf_riccati", "lqr_riccati"]


@result
@dataclass(frozen=True, eq=False)
class GeneralizedPlant:
    """Full-information generalized plant of §4.2.1.

    ``x⁺ = A x + B [r; u]``, ``z = C x + D [r; u]`` with ``x = [x_p; x_w1; x_w2]``::

        A = [[A_p, 0, 0], [−B_1C_p, A_1, 0], [0, 0, A_2]]     B = [[0, B_p], [B_1, −B_1D_p], [0, B_2]]
        C = [[−D_1C_p, C_1, 0], [0, 0, C_2]]                  D = [[D_1, −D_1D_p], [0, D_2]]

    Attributes
    ----------
    A, B, C, D : ndarray
    n_p, n_w1, n_w2 : int
        State partition.
    l, m : int
        Number of references (= plant outputs) and controls (= plant inputs).
    dt : float or True
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    n_p: int
    n_w1: int
    n_w2: int
    l: int
    m: int
    dt: float

    @property
    def system(self) -> control.StateSpace:
        """The plant as a discrete ``StateSpace`` (inputs ``[r; u]``, outputs ``[z_w1; z_w2]``)."""
        return control.ss(self.A, self.B, self.C, self.D, self.dt,
                          inputs=[f"r[{c}]" for c in range(self.l)] + [f"u[{c}]" for c in range(self.m)])

    def state(self, x_p, x_w1, x_w2) -> np.ndarray:
        """Stack ``[x_p; x_w1; x_w2]`` (checking sizes)."""
        parts = []
        for v, n, name in ((x_p, self.n_p, "x_p"), (x_w1, self.n_w1, "x_w1"), (x_w2, self.n_w2, "x_w2")):
            a = as_real_array(v, name).reshape(-1)
            if a.size != n:
                raise DataError(f"{name} must have {n} entries, got {a.size}")
            parts.append(a)
        return np.concatenate(parts)


@result
@dataclass(frozen=True, eq=False)
class RiccatiLaw:
    """A finite-horizon law from a Riccati recursion.

    Attributes
    ----------
    X : ndarray, shape (i, n, n)
        ``X[t]`` is the matrix used at stage ``k + t`` ((4.17)/(4.22): ``X_{k+t}``),
        ``X[i-1]`` the terminal one.
    value : ndarray, shape (n, n)
        ``X_{k-1}``: the optimal (saddle) cost from ``x_k`` is ``x_kᵀ value x_k``.
    gains : ndarray, shape (i, p, n)
        Stage feedback: ``w_t = gains[t] @ x_t`` with ``w_t = [r_t; u_t]`` (H∞, (4.18))
        or ``u_t`` (LQR, (4.23)).
    A, B : ndarray
        Dynamics used by :meth:`rollout`.
    gamma : float or None
        Level (None for LQR).
    n_disturbances : int
        Leading entries of ``w_t`` that are disturbances (``l`` for H∞, 0 for LQR).
    """

    X: np.ndarray
    value: np.ndarray
    gains: np.ndarray
    A: np.ndarray
    B: np.ndarray
    gamma: float | None
    n_disturbances: int

    @property
    def horizon(self) -> int:
        return self.gains.shape[0]

    def rollout(self, x0) -> tuple[np.ndarray, np.ndarray]:
        """Forward recursion (4.18)–(4.19) / (4.23)–(4.24) from ``x_k = x0``.

        Returns
        -------
        w : ndarray, shape (i, p)
            ``[r_t; u_t]`` (H∞) or ``u_t`` (LQR) for ``t = k … k+i-1``.
        x : ndarray, shape (i + 1, n)
            States ``x_k … x_{k+i}``.
        """
        x = as_real_array(x0, "x0").reshape(-1)  # text or complex had raised numpy's ValueError/TypeError
        if x.size != self.A.shape[0] or not np.all(np.isfinite(x)):
            raise DataError(f"x0 must be {self.A.shape[0]} finite values")
        ws, xs = [], [x]
        for F in self.gains:
            w = F @ x
            x = self.A @ x + self.B @ w
            ws.append(w)
            xs.append(x)
        return np.array(ws), np.array(xs)

    def controls(self, x0) -> np.ndarray:
        """The control part of :meth:`rollout`, stacked as ``u_opt`` (3.9), shape ``(i·m,)``."""
        w, _ = self.rollout(x0)
        return w[:, self.n_disturbances:].reshape(-1)


# ---------------------------------------------------------------------------------------------
def generalized_plant(P, W1, W2) -> GeneralizedPlant:
    """Build the §4.2.1 generalized plant from a discrete plant and weights.

    Parameters
    ----------
    P : control.StateSpace or TransferFunction
        Discrete plant (``m`` inputs, ``l`` outputs), state ``x_p`` in its realisation.
    W1, W2 : control.StateSpace, TransferFunction, scalar or matrix
        Discrete weights on ``e = r − y`` (``l`` inputs) and on ``u`` (``m`` inputs),
        relative degree 0, same sample time as ``P``.

    Returns
    -------
    GeneralizedPlant

    Examples
    --------
    A first-order plant, a first-order W1 and a static W2: the state is ``[x_p; x_w1]``.

    >>> import control, numpy as np
    >>> from synthesis import makeweight
    >>> P = control.ss([[0.8]], [[1.0]], [[0.5]], [[0.0]], 0.1)
    >>> W1 = makeweight(10.0, (0.5, 1.0), 0.5, 0.1)
    >>> gp = generalized_plant(P, W1, 0.1)
    >>> (gp.n_p, gp.n_w1, gp.n_w2), (gp.l, gp.m), gp.A.shape, gp.dt
    ((1, 1, 0), (1, 1), (2, 2), 0.1)

    Its transfer function from ``[r; u]`` to ``z`` is ``[[W1, −W1 P], [0, W2]]``:

    >>> z = np.exp(0.3j)
    >>> np.allclose(gp.system(z), [[W1(z), -W1(z) * P(z)], [0.0, 0.1]])
    True
    """
    P = as_discrete_system(P, "P")
    m, l = P.ninputs, P.noutputs
    W1 = as_weight(W1, "W1", inputs=l, dt=P.dt)
    W2 = as_weight(W2, "W2", inputs=m, dt=P.dt)
    dt = common_dt(P, W1, W2)
    Ap, Bp, Cp, Dp = _ss_parts(P)
    A1, B1, C1, D1 = _ss_parts(W1)
    A2, B2, C2, D2 = _ss_parts(W2)
    npl, n1, n2 = Ap.shape[0], A1.shape[0], A2.shape[0]
    q1, q2 = C1.shape[0], C2.shape[0]
    Z = np.zeros
    A = np.block([[Ap, Z((npl, n1)), Z((npl, n2))],
                  [-B1 @ Cp, A1, Z((n1, n2))],
                  [Z((n2, npl)), Z((n2, n1)), A2]])
    B = np.block([[Z((npl, l)), Bp],
                  [B1, -B1 @ Dp],
                  [Z((n2, l)), B2]])
    C = np.block([[-D1 @ Cp, C1, Z((q1, n2))],
                  [Z((q2, npl)), Z((q2, n1)), C2]])
    D = np.block([[D1, -D1 @ Dp],
                  [Z((q2, l)), D2]])
    return GeneralizedPlant(A, B, C, D, npl, n1, n2, l, m, dt)


def _matrices(A, B, C, D):
    # as_real_array: a complex plant had lost its imaginary part (ComplexWarning) or raised a bare TypeError
    A, B, C, D = (np.atleast_2d(as_real_array(M, name)) for M, name in zip((A, B, C, D), "ABCD"))
    n = A.shape[0]
    if A.shape != (n, n) or B.shape[0] != n or C.shape[1] != n or D.shape != (C.shape[0], B.shape[1]):
        raise DataError(f"inconsistent state-space shapes A {A.shape}, B {B.shape}, C {C.shape}, D {D.shape}")
    for name, M in (("A", A), ("B", B), ("C", C), ("D", D)):
        if not np.all(np.isfinite(M)):
            raise DataError(f"{name} contains NaN or infinite values")
    return A, B, C, D


#: Relative tolerance of the stage saddle tests of :func:`hinf_riccati` (about 1e4 eps: the recursion's rounding).
_STAGE_TOL = 1e-12


def _check_symmetric(M: np.ndarray, name: str) -> None:
    """Refuse a non-symmetric weight: the recursion's cross term ``CᵀQD`` and stage matrix ``DᵀQD + R`` assume
    ``Q = Qᵀ``.

    The cost ``yᵀQy`` sees only the symmetric part of ``Q``, but the recursion (4.21)–(4.22) uses ``Q`` itself, so a
    non-symmetric ``Q`` (with a feedthrough ``D``), ``R`` or ``terminal`` gave the gains of another cost, silently.
    """
    if not np.allclose(M, M.T, rtol=1e-10, atol=1e-12 * max(1.0, float(np.abs(M).max(initial=0.0)))):
        raise DataError(f"{name} must be symmetric (the cost sees only its symmetric part); pass ({name} + {name}ᵀ)/2")


def _recursion(A, B, CtC, CtD, DtD_plus, horizon, terminal, check=None):
    n = A.shape[0]
    X = np.empty((horizon, n, n))
    gains = np.empty((horizon, B.shape[1], n))
    Xt = terminal
    for t in range(horizon - 1, -1, -1):
        X[t] = Xt
        M = B.T @ Xt @ B + DtD_plus
        N = A.T @ Xt @ B + CtD
        if not (np.all(np.isfinite(M)) and np.all(np.isfinite(N))):
            # a plant that grows beyond floating point over the horizon (it had raised LinAlgError from the checks)
            raise DataError(f"stage {t}: the Riccati recursion overflowed (X grows beyond floating point over the "
                            f"{horizon}-step horizon): scale the state, or shorten the horizon")
        if check is not None:
            check(M, t)
        F = -np.linalg.solve(M, N.T)
        gains[t] = F
        Xt = A.T @ Xt @ A + CtC + N @ F
        Xt = 0.5 * (Xt + Xt.T)
    return X, Xt, gains


def hinf_riccati(A, B=None, C=None, D=None, *, gamma: float, horizon: int,
                 n_disturbances: int | None = None) -> RiccatiLaw:
    """Model-based finite-horizon full-information H∞ law (4.15)–(4.19).

    Parameters
    ----------
    A, B, C, D : array_like
        Generalized plant with inputs ``w = [r; u]`` (first ``n_disturbances`` entries are
        ``r``); or pass a :class:`GeneralizedPlant` as ``A`` alone (then ``n_disturbances``
        defaults to its ``l``).
    gamma : float
        Level, ``R_γ = diag(γ²I_l, 0)`` (4.15).
    horizon : int
        ``i``; ``X_{k+i-1} = 0`` (4.16).
    n_disturbances : int
        ``l`` (an integer; ``1 ≤ l <`` the number of inputs).

    Returns
    -------
    RiccatiLaw

    Raises
    ------
    DataError
        Inconsistent shapes, NaN/inf entries, ``n_disturbances`` missing, not an integer (``1.5``, ``True``,
        ``"1"``) or out of range, a bad ``gamma`` or ``horizon``.
    StageSaddleError
        (an ``InfeasibleGammaError``) If at some stage ``M_t = BᵀX_tB + DᵀD − R_γ`` is not a saddle, i.e. its ``u`` block is
        not positive definite or the Schur complement in ``r`` is not negative definite
        (γ at or below the finite-horizon γ_min).  Within about ``1e-5`` (relative) above γ_min the stage
        test is decided by rounding (``X`` grows like ``1/(γ − γ_min)``): levels up to ``1.6e-6`` above the batch
        γ_min were refused in a random audit of 60 plants, which exact arithmetic accepts.  The batch
        :func:`synthesis.minimax_gamma_min` of the Markov Toeplitz map (example below) decides exactly.

    Examples
    --------
    The generalized plant of a first-order plant and weights (:func:`generalized_plant`), horizon 5:

    >>> import control, numpy as np
    >>> from synthesis import makeweight, markov_toeplitz, observability, minimax_gamma_min, solve_minimax
    >>> P = control.ss([[0.8]], [[1.0]], [[0.5]], [[0.0]], 0.1)
    >>> gp = generalized_plant(P, makeweight(10.0, (0.5, 1.0), 0.5, 0.1), 0.1)
    >>> i = 5
    >>> H, Gam = markov_toeplitz(gp.system, i), observability(gp.system, i)
    >>> Md, Mu = H[:, 0::2], H[:, 1::2]             # w_t = [r_t; u_t]: references, then controls
    >>> gmin = minimax_gamma_min(Md, Mu)
    >>> law = hinf_riccati(gp, gamma=1.5 * gmin, horizon=i)
    >>> law.horizon, law.gains.shape
    (5, (5, 2, 2))

    The recursion gives the controls of the batch minimax problem on ``z = Md r + Mu u + Γ x``:

    >>> x0 = np.array([1.0, -0.5])
    >>> np.allclose(law.controls(x0), solve_minimax(Md, Mu, Gam, 1.5 * gmin).u_gain @ x0)
    True

    Below the batch γ_min some stage has no saddle point:

    >>> hinf_riccati(gp, gamma=0.9 * gmin, horizon=i)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    synthesis.exceptions.StageSaddleError: stage 4: no saddle point ... at or below the finite-horizon gamma_min, ...
    """
    if isinstance(A, GeneralizedPlant):
        gp = A
        A, B, C, D = gp.A, gp.B, gp.C, gp.D
        n_disturbances = gp.l if n_disturbances is None else n_disturbances
    if n_disturbances is None:
        raise DataError("n_disturbances (the number of references l) is required with plain matrices")
    A, B, C, D = _matrices(A, B, C, D)
    i = check_horizon(horizon)
    # check_count: int() had read 1.5 as 1, True as 1 and "1" as 1, splitting w = [r; u] where the caller did not ask
    l = check_count(n_disturbances, "n_disturbances", 1)
    if not 0 < l < B.shape[1]:
        raise DataError(f"n_disturbances must be in [1, {B.shape[1] - 1}], got {n_disturbances!r}")
    gamma = check_level(gamma, "gamma")
    if not gamma <= 2.0 ** 500:  # R_γ holds γ² (it had raised OverflowError)
        raise DataError(f"gamma = {gamma:g} is too large: R_γ = diag(γ²I, 0) overflows; for the limit γ → ∞ use "
                        "lqr_riccati, or scale the performance outputs")
    p = B.shape[1]
    Rg = np.zeros((p, p))
    Rg[:l, :l] = gamma**2 * np.eye(l)

    def check(M, t):
        # the inertia is tested on the diagonally scaled M̃ = S M S, S = diag(|M_kk|^(-1/2)) (a congruence, so the
        # same inertia): tolerances relative to max|M| had mixed channels of very different scales, refusing a
        # diagonal control block diag(0.26, 1e14) as "not positive definite" (W2 = diag(0.1, 1e7))
        d = np.sqrt(np.abs(np.diagonal(M)))
        d[d == 0] = 1.0
        Ms = M / np.outer(d, d)
        Muu, Mur, Mrr = Ms[l:, l:], Ms[l:, :l], Ms[:l, :l]
        eu = np.linalg.eigvalsh(0.5 * (Muu + Muu.T))
        if eu.min() <= _STAGE_TOL * np.abs(Muu).max():
            raise StageSaddleError(
                gamma, f"stage {t}: control block of B'XB + D'D - R_gamma is not positive definite "
                f"(min eigenvalue {eu.min() * d[l:].min() ** 2:.3g}); gamma = {gamma:.6g} is too small, increase it")
        T2 = Mur.T @ np.linalg.solve(Muu, Mur)
        S = Mrr - T2
        es = np.linalg.eigvalsh(0.5 * (S + S.T))
        # the tolerance is relative to the terms S is formed from (B_rᵀXB_r + D_rᵀD_r, γ² and T2)
        Gr = np.diag(gamma**2 / d[:l] ** 2)
        tol = _STAGE_TOL * max(np.abs(Mrr + Gr).max(), np.abs(Gr).max(), np.abs(T2).max())
        if es.max() >= -tol:
            # near gamma_min X grows like 1/(gamma - gamma_min) and the Schur complement shrinks: the recursion's
            # rounding then decides its sign (a level 1.6e-6 above the batch gamma_min was refused, exact
            # rational arithmetic accepting it), so the message names the exact batch route
            raise StageSaddleError(
                gamma, f"stage {t}: no saddle point (Schur complement in r, diagonally scaled, has eigenvalue "
                f"{es.max():.3g} >= {-tol:.3g}, the rounding tolerance); gamma = {gamma:.6g} is at or below the "
                "finite-horizon gamma_min, increase it; a level within about 1e-5 (relative) above it can be refused "
                "by this recursion's rounding: synthesis.minimax_gamma_min on the batch map z = H w + Γ x decides "
                "exactly")

    X, value, gains = _recursion(A, B, C.T @ C, C.T @ D, D.T @ D - Rg, i, np.zeros((A.shape[0],) * 2), check)
    return RiccatiLaw(X=X, value=value, gains=gains, A=A, B=B, gamma=float(gamma), n_disturbances=l)


def lqr_riccati(A, B, C, D, Q, R, *, horizon: int, terminal=None) -> RiccatiLaw:
    """Model-based finite-horizon LQR (4.21)–(4.24) for ``Σ_{t=k}^{k+i-1} y_tᵀQy_t + u_tᵀRu_t``.

    Parameters
    ----------
    A, B, C, D : array_like
        Plant ``x⁺ = Ax + Bu``, ``y = Cx + Du``.
    Q, R : scalar or array_like
        Output and input weights, symmetric (``R`` may be indefinite as long as every stage matrix
        ``BᵀP_tB + DᵀQD + R`` is invertible; Thm 4.3 uses ``R = −R_γ``).
    horizon : int
    terminal : array_like, optional
        ``P_{k+i-1}`` (symmetric); default 0, which matches the cost (4.3) and the batch law (4.20)
        (the thesis's (4.21) prints ``C_pᵀQC_p``: see the module note).

    Returns
    -------
    RiccatiLaw

    Raises
    ------
    DataError
        Inconsistent shapes, NaN/inf in the plant, ``Q``, ``R`` or ``terminal``, a non-symmetric ``Q``, ``R`` or
        ``terminal``, a bad horizon, or a singular stage matrix ``BᵀP_tB + DᵀQD + R``.

    Examples
    --------
    ``x⁺ = 0.9 x + u``, ``y = x``, ``Q = 1``, ``R = 0.1``, horizon 4, from ``x_k = 2``:

    >>> import control, numpy as np
    >>> from synthesis import markov_toeplitz, observability
    >>> law = lqr_riccati([[0.9]], [[1.0]], [[1.0]], [[0.0]], 1.0, 0.1, horizon=4)
    >>> x0 = np.array([2.0])
    >>> u, x = law.rollout(x0)
    >>> u.shape, x.shape, round(float(u[0, 0]), 4)
    ((4, 1), (5, 1), -1.6467)

    The same controls and cost as the batch least-squares law (4.20) on ``y = Γ x_k + H u``:

    >>> G = control.ss([[0.9]], [[1.0]], [[1.0]], [[0.0]], 1)
    >>> H, Gam = markov_toeplitz(G, 4), observability(G, 4)
    >>> u_batch = -np.linalg.solve(H.T @ H + 0.1 * np.eye(4), H.T @ Gam @ x0)
    >>> np.allclose(law.controls(x0), u_batch)
    True
    >>> y = Gam @ x0 + H @ u_batch
    >>> bool(np.isclose(x0 @ law.value @ x0, y @ y + 0.1 * u_batch @ u_batch))
    True
    """
    A, B, C, D = _matrices(A, B, C, D)
    i = check_horizon(horizon)
    l, m, n = C.shape[0], B.shape[1], A.shape[0]
    Q = np.atleast_2d(as_real_array(Q, "Q"))  # text had been parsed ("1"), complex had raised a TypeError
    R = np.atleast_2d(as_real_array(R, "R"))
    if Q.shape == (1, 1) and l > 1:
        Q = Q[0, 0] * np.eye(l)
    if R.shape == (1, 1) and m > 1:
        R = R[0, 0] * np.eye(m)
    if Q.shape != (l, l) or R.shape != (m, m):
        raise DataError(f"Q must be {l}x{l} and R {m}x{m}; got {Q.shape} and {R.shape}")
    P0 = np.zeros((n, n)) if terminal is None else as_real_array(terminal, "terminal")
    if P0.shape != (n, n):
        raise DataError(f"terminal must be {n}x{n}")
    for name, M in (("Q", Q), ("R", R), ("terminal", P0)):
        if not np.all(np.isfinite(M)):
            raise DataError(f"{name} contains NaN or infinite values")
        _check_symmetric(M, name)

    def check(M, t):
        if np.linalg.cond(M) > 1e14:
            raise DataError(f"stage {t}: B'PB + D'QD + R is singular; check R")

    X, value, gains = _recursion(A, B, C.T @ Q @ C, C.T @ Q @ D, D.T @ Q @ D + R, i, P0, check)
    return RiccatiLaw(X=X, value=value, gains=gains, A=A, B=B, gamma=None, n_disturbances=0)
