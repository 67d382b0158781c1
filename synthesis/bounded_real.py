"""Bounded-real (KYP) certificate of ``‖G‖∞ < γ`` for a discrete system: a matrix anyone can check.

The discrete bounded-real lemma: for ``G(z) = C(zI − A)⁻¹B + D``, ``A`` is Schur stable and
``‖G‖∞ < γ`` if and only if some ``P = Pᵀ ≻ 0`` makes

    M(P) = [[AᵀPA − P + CᵀC,  AᵀPB + CᵀD],
            [BᵀPA + DᵀC,      BᵀPB + DᵀD − γ²I]]  ≺ 0.

(``P ≻ 0`` and the leading block ``AᵀPA − P ≺ −CᵀC ⪯ 0`` make ``A`` stable; a Schur complement and
the KYP lemma give the norm.)  Such a ``P`` is a certificate that needs no trust in the code that
found it: two symmetric eigenvalue computations check it.  It is a second route to the proof of
:func:`~synthesis.norm_below` (the Hamiltonian-pencil test on the unit circle): different algebra, a
different LAPACK path, a different way to fail.

Finding ``P``.  With ``C, D`` scaled by ``1/γ`` and a small ``ε > 0``, the stabilising solution ``X``
of the discrete Riccati equation with ``Q = CᵀC + εI``, ``S = CᵀD``, ``R = DᵀD − (1 − ε)I``
(:func:`scipy.linalg.solve_discrete_are`) zeroes the Schur complement of ``M(X) + εI`` with
``BᵀXB + R ≺ 0``, so ``M(X) ⪯ −εI``; ``P = γ²X`` then gives ``M(P) ⪯ −εγ²I`` for the unscaled data.
It exists when ``ε`` is small against the gap ``1 − (‖G‖∞/γ)²`` (the Riccati equation is the
bounded-real one of ``[G; √ε(zI − A)⁻¹B]`` at level ``√(1 − ε)``, so ``ε < (1 − ‖G/γ‖²∞)/(1 +
‖(zI − A)⁻¹B‖²∞)`` suffices); fractions of that estimate (from a grid) are tried, from the largest
(the widest margin against rounding) down.

Scaling.  The search and the check run in the coordinates ``x̃ = T⁻¹x`` of a diagonal ``T`` of powers
of two that balances ``A`` (:func:`scipy.linalg.matrix_balance`): ``Ã = T⁻¹AT``, ``B̃ = T⁻¹B``,
``C̃ = CT`` and ``P̃ = TᵀPT`` are then *exact* in floating point, and ``M(P) = diag(T, I)⁻ᵀ M̃(P̃)
diag(T, I)⁻¹`` is a congruence, so ``M̃(P̃) ≺ 0`` and ``P̃ ≻ 0`` prove the statement for the system as
given.  Without it a badly scaled realisation (state units spanning orders of magnitude) gives a ``P``
whose check is swamped by its own rounding allowance.  When that fails, a common power of two ``c`` near the
state gain ``f = max ‖(e^{jω}I − Ã)⁻¹B̃‖`` is tried as well (``T·c``: ``Ã`` unchanged, ``B̃/c``, ``C̃c``, exact): the
Riccati perturbation is sized against ``1 + f²``, and a system in units that make ``f`` huge (a loop on a plant of
gain 1e-6: ``f`` = 3e6) otherwise gets an ``ε`` far below the check's rounding.

Checking ``P``.  The certificate holds the system's matrices, ``P`` (exactly symmetric) and the
numbers of the check: ``λ_max`` of the computed ``M(P)`` must lie below ``−allowance`` and
``λ_min(P)`` above its own allowance.  The allowances bound the rounding of forming ``M(P)`` in
floating point (componentwise, ``|fl(XᵀPY) − XᵀPY| ≤ c·eps·|X|ᵀ|P||Y|``, summed over the blocks, in
the Frobenius norm) and of the symmetric eigensolver (backward stable: ``4N·eps·‖M‖_F``).  This is
the same first-order standard as the rounding allowance of the pencil test, not interval arithmetic.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from ._repr import result
from ._validation import DataError, check_count, check_level
from .hinfnorm import _grid, _Sys

__all__ = ["BoundedRealCertificate", "bounded_real_certificate"]

_EPS = np.finfo(float).eps
#: Riccati perturbations tried, as fractions of ``(1 − (ℓ/γ)²)/(1 + f²)`` (``ℓ``: the largest gain found,
#: ``f``: the largest ``σ̄((e^{jω}I − A)⁻¹B)`` on the grid; module docstring), largest margin first.
EPSILON_FRACTIONS = (0.5, 1e-2, 1e-4, 1e-6)


#: the largest γ whose square (in the LMI) and its rounding allowance stay finite (the allowance
#: takes Frobenius norms of γ²-sized blocks, whose squares overflowed from about 2**250)
_GAMMA_MAX = 2.0 ** 200


def _state_gain(s: _Sys, w) -> float:
    """Largest ``σ̄((e^{jω}I − Ã)⁻¹B̃)`` over ``w``, in the balanced realisation of ``s``.

    Solved on the Schur form ``Ã = Z T_s Zᴴ``: ``(zI − Ã)⁻¹B̃ = Z (zI − T_s)⁻¹ Zᴴ B̃``.
    """
    Tm = -s.T
    diag = np.diag_indices(s.n)
    d0 = Tm[diag].copy()
    best = 0.0
    for wk in w:
        Tm[diag] = d0 + np.exp(1j * wk)
        X = sla.solve_triangular(Tm, s.Bt, check_finite=False)  # Z is unitary: same norm
        best = max(best, float(np.linalg.norm(X, 2)))
    return best


def _scaled(A, B, C, t):
    """``(T⁻¹AT, T⁻¹B, CT)`` for ``T = diag(t)`` (exact: ``t`` holds powers of two)."""
    return A * (t[None, :] / t[:, None]), B / t[:, None], C * t[None, :]


def _lmi(A, B, C, D, P, gamma):
    """The bounded-real matrix ``M(P)`` (symmetrised), computed as written in the module docstring."""
    m = B.shape[1]
    PA, PB = P @ A, P @ B
    M = np.block([[A.T @ PA - P + C.T @ C, A.T @ PB + C.T @ D],
                  [B.T @ PA + D.T @ C, B.T @ PB + D.T @ D - (gamma * gamma) * np.eye(m)]])
    return 0.5 * (M + M.T)


def _lmi_allowance(A, B, C, D, P, gamma, M) -> float:
    """Bound on ``‖fl(M(P)) − M(P)‖₂`` plus the eigensolver's error on ``M`` (module docstring)."""
    n, m = B.shape
    aA, aB, aC, aD, aP = (np.abs(X) for X in (A, B, C, D, P))
    E = np.block([[aA.T @ aP @ aA + aP + aC.T @ aC, aA.T @ aP @ aB + aC.T @ aD],
                  [aB.T @ aP @ aA + aD.T @ aC, aB.T @ aP @ aB + aD.T @ aD + (gamma * gamma) * np.eye(m)]])
    c = (2 * n + C.shape[0] + 4) * _EPS
    return float(1.01 * c * np.linalg.norm(E) + 4 * (n + m) * _EPS * np.linalg.norm(M))


def _check(A, B, C, D, P, gamma):
    """``(lmi_max, lmi_allowance, p_min, p_allowance)`` of a candidate ``P``."""
    M = _lmi(A, B, C, D, P, gamma)
    lmi_max = float(np.linalg.eigvalsh(M)[-1])
    p_min = float(np.linalg.eigvalsh(P)[0]) if P.size else float("inf")
    p_allow = float(4 * P.shape[0] * _EPS * np.linalg.norm(P))
    return lmi_max, _lmi_allowance(A, B, C, D, P, gamma, M), p_min, p_allow


def _holds(lmi_max, lmi_allow, p_min, p_allow) -> bool:
    return bool(lmi_max < -lmi_allow and p_min > p_allow)


@result
@dataclass(frozen=True, eq=False)
class BoundedRealCertificate:
    """Result of :func:`bounded_real_certificate`; truthy iff ``‖G‖∞ < gamma`` is proven by ``P``.

    Attributes
    ----------
    proven : bool
        ``P ≻ 0`` and ``M(P) ≺ 0`` hold with the rounding allowances (module docstring).
    gamma : float
    reason : str
        Why (in words).
    P : ndarray, shape (n, n), or None
        The certificate (exactly symmetric); None when no candidate was found.
    lmi_max, lmi_allowance : float
        ``λ_max`` of the computed ``M(P)`` and its rounding allowance: proven needs
        ``lmi_max < −lmi_allowance`` (NaN without ``P``).
    p_min, p_allowance : float
        ``λ_min(P)`` and its allowance: proven needs ``p_min > p_allowance``.
    epsilon : float
        The Riccati perturbation that gave ``P`` (``M̃(P̃) ≈ −ε γ² I`` at best).
    A, B, C, D : ndarray
        The system the certificate refers to (checked by :meth:`verify`).
    scaling : ndarray, shape (n,)
        Diagonal of the power-of-two state scaling ``T``; the eigenvalues and allowances above are
        those of ``P̃ = TᵀPT`` and ``M̃(P̃)`` (module docstring: an exact congruence).
    """

    proven: bool
    gamma: float
    reason: str
    P: np.ndarray | None
    lmi_max: float
    lmi_allowance: float
    p_min: float
    p_allowance: float
    epsilon: float
    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    scaling: np.ndarray | None = None

    def __bool__(self) -> bool:
        return bool(self.proven)

    def verify(self, sys=None) -> bool:
        """Check the certificate again from its matrices (or from ``sys``'s).

        Recomputes ``M(P)``, both extreme eigenvalues and the allowances; needs nothing of the
        search that produced ``P``.  ``P`` belongs to one state-space realisation: ``sys`` must be
        that realisation (the same ``A, B, C, D``, e.g. the ``StateSpace`` that was certified),
        not merely the same transfer function.  False when there is no ``P`` or the sizes differ.
        """
        if self.P is None:
            return False
        if sys is None:
            A, B, C, D = self.A, self.B, self.C, self.D
        else:
            s = _Sys(sys, "sys")
            (A, B, C), D = s.given, s.D
            if A.shape != self.P.shape or B.shape != self.B.shape or C.shape != self.C.shape:
                return False
        P = np.asarray(self.P, float)
        t = np.ones(P.shape[0]) if self.scaling is None else np.asarray(self.scaling, float)
        if not (np.array_equal(P, P.T) and t.shape == (P.shape[0],) and np.all(t > 0)
                and np.array_equal(np.frexp(t)[0], np.full(t.shape, 0.5))):  # powers of two only: exact
            return False
        As, Bs, Cs = _scaled(A, B, C, t)
        return _holds(*_check(As, Bs, Cs, D, P * np.outer(t, t), self.gamma))


def _common_scalings(f: float) -> tuple:
    """The common state scalings tried: 1 (the balanced realisation as it is, first), then the power of two nearest
    the state gain ``f`` when that is at least 4 away from 1 (module docstring, "Scaling")."""
    if not (np.isfinite(f) and f > 0):
        return (1.0,)
    c = float(2.0 ** np.round(np.log2(f)))
    return (1.0,) if 0.25 <= c <= 4.0 else (1.0, c)


def _riccati_candidate(A, B, C, D, gamma: float, eps: float):
    """``P = γ² X`` from the perturbed bounded-real Riccati equation (module docstring), or None."""
    n, m = B.shape
    Cs, Ds = C / gamma, D / gamma
    Q = Cs.T @ Cs + eps * np.eye(n)
    R = Ds.T @ Ds - (1.0 - eps) * np.eye(m)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            X = sla.solve_discrete_are(A, B, Q, R, s=Cs.T @ Ds)
    except (np.linalg.LinAlgError, ValueError):
        return None
    if not np.all(np.isfinite(X)):
        return None
    return (gamma * gamma) * (0.5 * (X + X.T))


def bounded_real_certificate(sys, gamma: float, *, lower: float | None = None,
                             n_grid: int = 16) -> BoundedRealCertificate:
    """Prove ``‖G‖∞ < gamma`` for a discrete system by a bounded-real (KYP) matrix ``P``, or say why not.

    An independent second route to :func:`~synthesis.norm_below`: ``P ≻ 0`` with ``M(P) ≺ 0``
    (the discrete bounded-real lemma, module docstring), found by a perturbed discrete Riccati
    equation and checked with rounding allowances.  The result can be re-checked by
    :meth:`BoundedRealCertificate.verify` without trusting the search.

    Parameters
    ----------
    sys : control.StateSpace or control.TransferFunction
        Discrete-time system, any number of inputs and outputs.
    gamma : float
        Level, finite and > 0.
    lower : float, optional
        A gain known to be attained (e.g. :attr:`NormBracket.lower <synthesis.NormBracket>`): a
        better estimate of the norm than the grid's sets the Riccati perturbations closer to the
        gap.  It only steers the search; the proof is the check of ``P``.
    n_grid : int
        Points of the frequency grid (pole angles added) whose largest gain sets the Riccati
        perturbations (with ``lower``) and disproves levels at or below an attained gain; ≥ 2.

    Returns
    -------
    BoundedRealCertificate
        Truthy only when ``P`` passes the check.  Not proven: unstable or marginally stable
        ``A``, ``γ ≤ σ̄(D)``, a gain ``≥ γ`` attained on the grid, or no perturbation gave a
        ``P`` that passes (``γ`` within rounding of the norm, or the Riccati solver failed).

    Raises
    ------
    DataError
        Continuous-time system, NaN/inf entries, an improper transfer function, ``gamma`` not a
        finite number > 0, or above ``2**200`` (the LMI's rounding allowance would overflow).

    Examples
    --------
    >>> import control
    >>> G = control.tf([1], [1, -0.5], 1)          # ‖G‖∞ = 2
    >>> bool(bounded_real_certificate(G, 2.01)), bool(bounded_real_certificate(G, 1.99))
    (True, False)
    """
    gamma = check_level(gamma, "gamma")
    if not gamma <= _GAMMA_MAX:  # the LMI holds γ²: beyond this it overflows (it had raised LinAlgError)
        raise DataError(f"gamma = {gamma:g} is too large to certify in double precision (the bounded-real LMI holds "
                        f"γ², finite only below {_GAMMA_MAX:g}); certify the scaled system G/s against gamma/s, with s "
                        "a power of two near gamma")
    n_grid = check_count(n_grid, "n_grid", 2)
    s = _Sys(sys, "sys")
    none = dict(P=None, lmi_max=float("nan"), lmi_allowance=float("nan"), p_min=float("nan"),
                p_allowance=float("nan"), epsilon=float("nan"), A=s.given[0], B=s.given[1], C=s.given[2], D=s.D)
    stable, why = s.stability()
    if not stable:
        return BoundedRealCertificate(False, gamma, why, **none)
    if s.m == 0 or s.p == 0:  # had been called a static gain "with no state" even when it has states
        return BoundedRealCertificate(True, gamma, "empty system (no inputs or outputs): the norm is 0", **none)
    if s.n == 0:
        ok = s.dnorm < gamma
        return BoundedRealCertificate(ok, gamma, (
            f"static gain: ‖D‖₂ = {s.dnorm:.12g} {'<' if ok else '>='} gamma (no state, nothing to certify by P)"),
            **none)
    w = _grid(s, n_grid)
    g = s.gains(w)
    k = int(np.argmax(g))
    known = 0.0 if lower is None else check_level(lower, "lower", minimum=-1.0)
    lower = max(float(g[k]), s.dnorm)
    if lower >= gamma:
        return BoundedRealCertificate(False, gamma, (
            f"disproved: gain {lower:.12g} >= gamma is attained (w = {float(w[k]):.6g} rad/sample or at w = ∞ by D)"),
            **none)
    if known >= gamma:
        return BoundedRealCertificate(False, gamma, (
            f"not proven: the given attained gain lower = {known:.12g} is not below gamma"), **none)
    (A, B, C), D = s.given, s.D
    f = _state_gain(s, w)
    last = None
    for c in _common_scalings(f):
        # T·c: the balancing scaling times a common power of two c, which leaves Ã as it is and brings the state
        # gain f to about 1 -- the Riccati perturbation ε is sized against 1 + f², and a loop in units that make f
        # 3e6 (a plant of gain 1e-6, a controller of gain 1e6) had left ε = 5e-20, below the check's rounding
        t, As, Bs, Cs = s.scaling * c, s.A, s.B / c, s.C * c  # = _scaled(A, B, C, t), exactly (powers of two)
        gap = (1.0 - (max(lower, known) / gamma) ** 2) / (1.0 + (f / c) ** 2)
        for frac in EPSILON_FRACTIONS:
            eps = frac * gap
            Pt = _riccati_candidate(As, Bs, Cs, D, gamma, eps)
            if Pt is None:
                continue
            checks = _check(As, Bs, Cs, D, Pt, gamma)
            P = Pt / np.outer(t, t)  # T⁻ᵀ P̃ T⁻¹, exact
            last = (P, checks, eps, t)
            if _holds(*checks):
                lmi_max, lmi_allow, p_min, p_allow = checks
                return BoundedRealCertificate(True, gamma, (
                    f"proven: P ≻ 0 (λ_min {p_min:.3g}) and M(P) ≺ 0 (λ_max {lmi_max:.3g}, rounding allowance "
                    f"{lmi_allow:.3g}; balanced coordinates) with Riccati perturbation ε = {eps:.3g}"),
                    P, lmi_max, lmi_allow, p_min, p_allow, eps, A, B, C, D, t)
    if last is None:
        return BoundedRealCertificate(False, gamma, (
            "not proven: the perturbed bounded-real Riccati equation has no stabilising solution for any ε tried "
            f"(largest gain found {lower:.12g}; gamma may be within rounding of the norm)"), **none)
    P, (lmi_max, lmi_allow, p_min, p_allow), eps, t = last
    return BoundedRealCertificate(False, gamma, (
        f"not proven: the best candidate P has λ_max(M(P)) = {lmi_max:.3g} against the allowance {lmi_allow:.3g} "
        f"and λ_min(P) = {p_min:.3g} (ε = {eps:.3g}); gamma may be within rounding of the norm"),
        P, lmi_max, lmi_allow, p_min, p_allow, eps, A, B, C, D, t)
