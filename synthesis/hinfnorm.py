"""Certified discrete-time H∞ norm: a bracket ``lower ≤ ‖G‖∞ ≤ upper`` with a proven upper side.

Every robustness claim of the toolkit ends in an H∞ norm (small gain ``δ·‖M‖∞ < 1``, the level
check of :func:`~synthesis.discrete_mixsyn`).  A frequency grid — however dense — only gives a
*lower* bound: it can miss the sharp peak of a lightly damped loop.  Here

* ``lower`` is a gain actually attained, ``σ̄(G(e^{jω}))`` at a reported frequency ``ω``
  (best of a grid containing the pole angles, a local refinement and the iterations below);
* ``upper`` is proven by the discrete bounded-real test: for a Schur-stable ``A`` and
  ``γ > σ̄(D)``, ``‖G‖∞ < γ`` if and only if the pencil

      z·[[I, 0, 0], [0, −Aᵀ, 0], [0, −Bᵀ, 0]] − [[A, 0, B], [CᵀC, −I, CᵀD], [DᵀC, 0, DᵀD − γ²I]]

  (the zeros of ``γ²I − G(1/z)ᵀG(z)``; ``C, D`` scaled by ``1/γ`` here) has no eigenvalue on
  the unit circle.  An eigenvalue on the circle at ``e^{jω}`` means ``γ`` is a singular value of
  ``G(e^{jω})``.  The decision is conservative: an eigenvalue with ``| |z| − 1 | ≤`` ``CIRCLE_TOL``
  counts as *on* the circle (not proven).

The bracket is found by the Boyd–Balakrishnan / Bruinsma–Steinbuch iteration: test
``γ = lower·(1 + tol)``; if the pencil has unit-circle eigenvalues, the gains at their angles
and at the midpoints between them raise ``lower`` (quadratic convergence), and the test is
repeated; when the test passes, ``upper = γ``.  Should the unit-circle eigenvalues not lead to a
higher gain (an eigenvalue within rounding of the circle), ``γ`` is raised geometrically instead,
so the bracket widens but stays proven.

All of it runs in an exactly balanced realisation of the system: ``x̃ = T⁻¹x`` with ``T`` a diagonal of
powers of two balancing ``A`` (:func:`scipy.linalg.matrix_balance`).  The transfer function is the same
and the scaling is exact in floating point; a realisation whose state units spread over decades would
otherwise lose digits in every frequency response and in the pencil (measured: brackets 2–34× wide and
an attained side 1e-7 too high at scalings over 8 decades).

Not used: ``control.norm(sys, 'inf')`` returns ∞ for a stable discrete loop with a pole within
about 1e-5 of the unit circle; ``slycot.ab13dd`` (SLICOT's H∞ norm) is fast but was measured to
return a neighbouring local peak up to 5e-6 (relative) too low on three-disk mixed-sensitivity
loops.  Its result is used only as one more candidate for ``lower`` (its gain is re-evaluated),
for systems of order ≤ ``AB13DD_MAX_ORDER`` where it is cheap.
"""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla

from ._validation import DataError, as_discrete_system, check_count, check_level
from ._repr import result

__all__ = ["NormBracket", "NormTest", "hinf_norm", "norm_below"]

#: Poles at most this close to the unit circle (``1 − |p|``) are listed in :attr:`NormBracket.near_poles`.
NEAR_UNIT_CIRCLE = 1e-6
#: Pencil eigenvalues with ``| |z| − 1 | ≤ CIRCLE_TOL`` count as on the unit circle (not proven below).
CIRCLE_TOL = 1e-10
#: Eigenvalues with ``CIRCLE_TOL < | |z| − 1 | ≤ CHECK_TOL`` are checked by a local search of the gain
#: next to their angle (rounding can push a pair of close crossings this far off the circle).
CHECK_TOL = 1e-5
#: ``slycot.ab13dd`` adds a candidate for ``lower`` up to this order (above it, it costs more than the test).
AB13DD_MAX_ORDER = 60
_EPS = np.finfo(float).eps
_BATCH_ORDER = 40


@result
@dataclass(frozen=True)
class NormBracket:
    """Result of :func:`hinf_norm`: ``lower ≤ ‖G‖∞ ≤ upper``.

    Attributes
    ----------
    lower : float
        Attained gain ``σ̄(G(e^{j·frequency}))`` (0 for the zero system; ``inf`` when not stable).
        A lower bound of the norm, never above it.
    upper : float
        Proven upper bound: the bounded-real pencil at level ``upper`` has no eigenvalue on the
        unit circle (``inf`` when not stable).
    frequency : float
        Frequency (rad/sample, in ``[0, π]``) at which ``lower`` is attained (``nan`` when not stable).
    tol : float
        Requested relative gap: ``upper = lower·(1 + tol)`` unless the test needed a larger level
        (see :attr:`gap`).
    stable : bool
        ``A`` Schur stable (spectral radius below 1, not within rounding of 1).
    spectral_radius : float
        Largest pole modulus.
    reason : str
        ``''`` when ``upper`` is finite; otherwise why it is ``inf`` (unstable, pole on the unit
        circle within rounding).
    near_poles : tuple of complex
        Poles with ``1 − |p| ≤ near_distance`` (stable but lightly damped: the norm is huge and
        sensitive to the model).  Reported, never hidden; the bracket is still proven.
    near_distance : float
        The distance used for :attr:`near_poles` (``NEAR_UNIT_CIRCLE``).
    tests : int
        Number of pencil tests made.
    """

    lower: float
    upper: float
    frequency: float
    tol: float
    stable: bool
    spectral_radius: float
    reason: str
    near_poles: tuple = field(default=())
    near_distance: float = NEAR_UNIT_CIRCLE
    tests: int = 0

    @property
    def gap(self) -> float:
        """Relative width ``(upper − lower)/lower`` (0 for the zero system, ``inf`` when not finite)."""
        if not math.isfinite(self.upper):
            return float("inf")
        if self.lower == 0:
            return 0.0 if self.upper == 0 else float("inf")
        return float((self.upper - self.lower) / self.lower)

    def __str__(self) -> str:
        if not math.isfinite(self.upper):
            return f"inf ({self.reason})"
        return f"[{self.lower:.10g}, {self.upper:.10g}]"


@result
@dataclass(frozen=True)
class NormTest:
    """Result of :func:`norm_below`; truthy iff ``‖G‖∞ < gamma`` is proven.

    Attributes
    ----------
    below : bool
        ``True`` only with a proof (stable ``A``, ``γ > σ̄(D)``, no pencil eigenvalue on the unit
        circle at level ``γ``).  ``False`` means *not proven*: either disproved (a gain ``≥ γ`` is
        attained, see :attr:`lower`) or undecidable within rounding (see :attr:`reason`).
    gamma : float
    reason : str
        Why (in words).
    lower : float
        Largest gain found on the way (attained at :attr:`frequency`); ``≥ gamma`` disproves.
    frequency : float
    """

    below: bool
    gamma: float
    reason: str
    lower: float = float("nan")
    frequency: float = float("nan")

    def __bool__(self) -> bool:
        return bool(self.below)


# ---------------------------------------------------------------------------------------------
def _balancing(A) -> np.ndarray:
    """Diagonal of a power-of-two ``T`` balancing ``A`` (:func:`scipy.linalg.matrix_balance`); ones when empty."""
    if not A.size:
        return np.ones(A.shape[0])
    _, (scale, _) = sla.matrix_balance(A, permute=False, separate=True)
    return np.asarray(scale, float)


class _Sys:
    """A checked discrete system with the complex Schur form of ``A`` (cheap frequency responses).

    ``A, B, C`` are the exactly balanced realisation (``given`` holds the one passed, ``scaling``
    the power-of-two ``T`` with ``A = T⁻¹ A_given T``); ``D`` is unchanged.
    """

    def __init__(self, sys, name: str):
        import control

        if isinstance(sys, control.TransferFunction):
            if not control.isdtime(sys, strict=True):
                raise DataError(f"{name} is continuous-time (dt = 0); discretise it first (e.g. "
                                "control.c2d(sys, dt, 'zoh')); use control.norm(sys, 'inf') for continuous time")
            try:
                sys = control.ss(sys)
            except ValueError as exc:
                raise DataError(
                    f"{name} is a transfer function that is not proper (numerator degree above the "
                    "denominator's); its H∞ norm on the unit circle is not that of a causal system: "
                    "add poles (e.g. multiply by z^-k) or pass a proper system") from exc
        sys = as_discrete_system(sys, name, hint="use control.norm(sys, 'inf') for continuous time")
        n, m, p = sys.nstates, sys.ninputs, sys.noutputs
        A = np.asarray(sys.A, float).reshape(n, n)
        B = np.asarray(sys.B, float).reshape(n, m)
        C = np.asarray(sys.C, float).reshape(p, n)
        self.given = (A, B, C)  # the realisation as passed
        # Work in the realisation x̃ = T⁻¹x of a power-of-two diagonal T balancing A: the scaling is
        # exact in floating point and leaves the transfer function unchanged, while a badly scaled
        # realisation (state units over decades) loses digits in every frequency response and pencil.
        self.scaling = _balancing(A)
        t = self.scaling
        self.A, self.B, self.C = A * (t[None, :] / t[:, None]), B / t[:, None], C * t[None, :]
        self.D = np.asarray(sys.D, float).reshape(p, m)
        self.n, self.m, self.p = n, m, p
        if n:
            T, Z = sla.schur(self.A.astype(complex), output="complex")
            self.T, self.Z, self.Bt, self.Ct = T, Z, Z.conj().T @ self.B, self.C @ Z
            self.poles = np.diag(T).copy()
        else:
            self.poles = np.zeros(0, complex)
        self.rho = float(np.max(np.abs(self.poles))) if n else 0.0
        self.dnorm = float(np.linalg.norm(self.D, 2)) if self.D.size else 0.0

    def stability(self) -> tuple[bool, str]:
        """``(stable, reason)``; a pole within rounding of the unit circle counts as not stable."""
        if not self.n:
            return True, ""
        # backward-stable eigenvalues: a pole within a few ulps·‖A‖ of the circle may lie on it
        fuzz = 100 * _EPS * max(1.0, float(np.linalg.norm(self.A, 1)))
        k = int(np.argmax(np.abs(self.poles)))
        pole = complex(self.poles[k])
        if self.rho >= 1.0 + fuzz:
            return False, f"unstable: pole {pole:.6g} outside the unit circle (spectral radius {self.rho:.12g})"
        if self.rho >= 1.0 - fuzz:
            return False, (f"marginally stable: pole {pole:.6g} on the unit circle within rounding "
                           f"(spectral radius {self.rho:.17g}); the H∞ norm is infinite or not decidable")
        return True, ""

    def gains(self, w) -> np.ndarray:
        """``σ̄(G(e^{jω}))`` at each ``ω`` (rad/sample)."""
        w = np.atleast_1d(np.asarray(w, float))
        if not self.n:
            return np.full(w.shape, self.dnorm)
        z = np.exp(1j * w)
        if self.n <= _BATCH_ORDER:  # small: one batched dense solve (less Python overhead)
            M = z[:, None, None] * np.eye(self.n)[None] - self.T[None]
            H = self.Ct[None] @ np.linalg.solve(M, np.broadcast_to(self.Bt, (w.size,) + self.Bt.shape)) + self.D[None]
        else:  # large: triangular solves on the Schur form, O(n²) each
            Tm = -self.T
            diag = np.diag_indices(self.n)
            d0 = Tm[diag].copy()
            H = np.empty((w.size, self.p, self.m), complex)
            for k, zk in enumerate(z):
                Tm[diag] = d0 + zk
                H[k] = self.Ct @ sla.solve_triangular(Tm, self.Bt, check_finite=False) + self.D
        if self.p == 1 or self.m == 1:
            return np.sqrt(np.sum(np.abs(H) ** 2, axis=(1, 2)))
        return np.linalg.svd(H, compute_uv=False)[:, 0]

    def allowance(self, w) -> np.ndarray:
        """Rounding allowance: how much ``σ̄(G)`` can move at each frequency of ``w`` under backward errors.

        Perturbations ``δA, δB, δC, δD`` of relative size ``c·eps`` (``c = 4(n + m + p)``) change
        ``G(e^{jω})`` by at most ``c·eps·(‖A‖‖CR‖‖RB‖ + ‖B‖‖CR‖ + ‖C‖‖RB‖ + ‖D‖)`` to first order,
        ``R = (e^{jω}I − A)⁻¹``.  Large near a pole close to the unit circle.
        """
        c = 4.0 * (self.n + self.m + self.p) * _EPS
        nd = self.dnorm
        w = np.atleast_1d(np.asarray(w, float))
        if not self.n:
            return np.full(w.shape, c * nd)
        nA, nB, nC = (float(np.linalg.norm(M, 2)) for M in (self.A, self.B, self.C))
        Tm = -self.T
        diag = np.diag_indices(self.n)
        d0 = Tm[diag].copy()
        out = np.empty(w.shape)
        for k, wk in enumerate(w):
            Tm[diag] = d0 + np.exp(1j * wk)
            RB = sla.solve_triangular(Tm, self.Bt, check_finite=False)
            CR = sla.solve_triangular(Tm, self.Ct.conj().T, trans="C", check_finite=False).conj().T
            nrb = float(np.linalg.norm(RB, 2)) if RB.size else 0.0
            ncr = float(np.linalg.norm(CR, 2)) if CR.size else 0.0
            out[k] = c * (nA * ncr * nrb + nB * ncr + nC * nrb + nd)
        return out

    def pencil(self, gamma: float) -> tuple[np.ndarray, np.ndarray, float]:
        """Eigenvalues of the bounded-real pencil at level ``gamma`` near the unit circle.

        Returns the angles (in ``[0, π]``) and relative distances ``| |z| − 1 |`` of the finite
        eigenvalues with distance ``≤ CHECK_TOL``, and the smallest distance overall.
        """
        n, m = self.n, self.m
        A, B = self.A, self.B
        C, D = self.C / gamma, self.D / gamma
        I, Z = np.eye(n), np.zeros((n, n))
        F = np.block([[A, Z, B],
                      [C.T @ C, -I, C.T @ D],
                      [D.T @ C, np.zeros((m, n)), D.T @ D - np.eye(m)]])
        E = np.block([[I, Z, np.zeros((n, m))],
                      [Z, -A.T, np.zeros((n, m))],
                      [np.zeros((m, n)), -B.T, np.zeros((m, m))]])
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            alpha, beta = sla.eig(F, E, right=False, homogeneous_eigvals=True, check_finite=False)
        aa, bb = np.abs(alpha), np.abs(beta)
        scale = np.maximum(aa, bb)
        finite = (scale > 0) & (bb > 1e-14 * scale)
        dist = np.abs(aa[finite] - bb[finite]) / scale[finite]
        z = alpha[finite] / beta[finite]
        close = dist <= CHECK_TOL
        return np.abs(np.angle(z[close])), dist[close], float(dist.min()) if dist.size else float("inf")


def _local_max(s: _Sys, lo: float, hi: float, x0: float) -> tuple[float, float]:
    """Largest gain found on ``[lo, hi]`` (bounded Brent search plus the ends and ``x0``)."""
    from scipy.optimize import minimize_scalar

    pts = np.array([lo, x0, hi])
    g = s.gains(pts)
    k = int(np.argmax(g))
    best, wbest = float(g[k]), float(pts[k])
    if hi > lo:
        # on t in [0, 1]: fminbound's relative x-tolerance (sqrt(eps)·|x|) would be far too coarse
        # for a narrow window at a large frequency
        wid = hi - lo
        res = minimize_scalar(lambda t: -s.gains([lo + t * wid])[0], bounds=(0.0, 1.0), method="bounded",
                              options={"xatol": 1e-12})
        if -res.fun > best:
            best, wbest = float(-res.fun), float(lo + res.x * wid)
    return best, wbest


def _test(s: _Sys, gamma: float):
    """One bounded-real test at ``gamma``: ``(proven, on_angles, gain, w, min_distance)``.

    ``on_angles`` are the angles of the eigenvalues counted as on the unit circle: those within
    ``CIRCLE_TOL``, and those within ``CHECK_TOL`` next to which a local search finds a gain
    ``≥ γ(1 − 1e-12)`` (a pair of close crossings that rounding pushed off the circle).
    ``gain, w`` is the largest gain seen in those local searches (``-1`` if none).
    """
    ang, dist, dmin = s.pencil(gamma)
    on = list(ang[dist <= CIRCLE_TOL])
    best, wbest = -1.0, float("nan")
    for th, d in zip(ang[dist > CIRCLE_TOL], dist[dist > CIRCLE_TOL]):
        h = max(50.0 * d, 1e-9)
        gl, wl = _local_max(s, max(th - h, 0.0), min(th + h, np.pi), min(max(th, 0.0), np.pi))
        if gl > best:
            best, wbest = gl, wl
        if gl >= gamma * (1 - 1e-12):
            on.append(th)
    on = np.unique(np.asarray(on, float))
    return on.size == 0, on, best, wbest, dmin


def _poles_closest(s: _Sys, k: int = 4) -> np.ndarray:
    """The ``k`` poles closest to the unit circle."""
    if not s.n:
        return np.zeros(0, complex)
    return s.poles[np.argsort(1.0 - np.abs(s.poles))[:k]]


def _allowance(s: _Sys, lower: float, freq: float) -> float:
    """Rounding allowance added to a level that passed the test (first order, see ``_Sys.allowance``).

    ``sup_ω σ̄(G + δG) ≤ sup_ω (σ̄(G) + a(ω))``; ``a`` is evaluated at the peak and at the angles
    of the poles closest to the unit circle (where it is largest), with the gain there.
    """
    near = np.abs(np.angle(_poles_closest(s)))
    a_peak = float(s.allowance([freq])[0])
    if not near.size:
        return a_peak
    excess = s.gains(near) + s.allowance(near) - lower
    return max(a_peak, float(excess.max()), 0.0)


def _grid(s: _Sys, n_grid: int) -> np.ndarray:
    ang = np.abs(np.angle(s.poles)) if s.n else np.zeros(0)
    return np.unique(np.concatenate([np.linspace(0.0, np.pi, n_grid), ang]))


def _refine(s: _Sys, w: np.ndarray, g: np.ndarray, top: int = 3) -> tuple[float, float]:
    """Best ``(gain, ω)`` after a bounded local search around the ``top`` highest grid points."""
    k0 = int(np.argmax(g))
    best, wbest = float(g[k0]), float(w[k0])
    for k in np.argsort(g)[::-1][:top]:
        gl, wl = _local_max(s, float(w[max(k - 1, 0)]), float(w[min(k + 1, w.size - 1)]), float(w[k]))
        if gl > best:
            best, wbest = gl, wl
    return best, wbest


def _ab13dd(s: _Sys) -> float | None:
    """Frequency of slycot's peak (its gain is re-evaluated by the caller), or None."""
    import slycot

    try:
        _, f = slycot.ab13dd("D", "I", "S", "D", s.n, s.m, s.p, s.A, np.eye(s.n), s.B, s.C, s.D)
    except Exception:  # noqa: BLE001 - a failed candidate is simply not used
        return None
    f = abs(float(f))
    return f if math.isfinite(f) and f <= np.pi + 1e-12 else None


def _bracket(s: _Sys, tol: float, n_grid: int, use_ab13dd: bool = True):
    """``(lower, ω, upper, tests)`` for a stable system (BBBS iteration on the pencil)."""
    w = _grid(s, n_grid)
    g = s.gains(w)
    lower, freq = _refine(s, w, g, top=1)  # the BBBS iteration below finds any higher peak
    if use_ab13dd and 0 < s.n <= AB13DD_MAX_ORDER:
        f = _ab13dd(s)
        if f is not None:
            gf = float(s.gains([min(f, np.pi)])[0])
            if gf > lower:
                lower, freq = gf, min(f, np.pi)
    if lower == 0.0 and not (np.any(s.D) or (np.any(s.Bt) and np.any(s.Ct))):
        return 0.0, 0.0, 0.0, 0  # the zero system
    floor = np.finfo(float).tiny
    step = tol
    gamma = max(lower * (1 + tol), lower + floor, floor)
    tests = 0
    for _ in range(200):
        proven, ang, gl, wl, _ = _test(s, gamma)
        tests += 1
        if gl > lower:
            lower, freq = gl, wl
        if proven:
            return lower, freq, gamma + _allowance(s, lower, freq), tests
        cand = np.concatenate([ang, 0.5 * (ang[1:] + ang[:-1])])
        gc = s.gains(cand)
        k = int(np.argmax(gc))
        if gc[k] > lower:
            lower, freq = float(gc[k]), float(cand[k])
        if lower * (1 + tol) > gamma:  # progress: BBBS step
            gamma = lower * (1 + tol)
            step = tol
            continue
        # the eigenvalues "on" the circle did not show a higher gain: look closer, then raise gamma
        for th in ang:
            g2, w2 = _local_max(s, max(th - 1e-6, 0.0), min(th + 1e-6, np.pi), th)
            if g2 > lower:
                lower, freq = g2, w2
        step *= 4.0
        gamma = max(lower * (1 + tol), gamma * (1 + step))
    return lower, freq, float("inf"), tests


def _as_tol(tol) -> float:
    tol = check_level(tol, "tol")
    if tol < 1e-14 or tol >= 1:
        raise DataError(f"tol must lie in [1e-14, 1) (relative gap of the bracket), got {tol!r}")
    return tol


def hinf_norm(sys, *, tol: float = 1e-8, n_grid: int = 64) -> NormBracket:
    """H∞ norm of a discrete system as a bracket ``lower ≤ ‖G‖∞ ≤ upper`` with a proven ``upper``.

    Parameters
    ----------
    sys : control.StateSpace or control.TransferFunction
        Discrete-time system (``dt > 0`` or ``True``), any number of inputs and outputs.
    tol : float
        Relative gap aimed at: ``upper = lower·(1 + tol)`` when the bounded-real test passes at
        that level (default 1e-8; within ``[1e-14, 1)``).
    n_grid : int
        Points of the uniform starting grid on ``[0, π]`` (the pole angles are always added), ≥ 2.
        Only the starting value depends on it, not the proof.

    Returns
    -------
    NormBracket
        ``lower`` attained at ``frequency``, ``upper`` proven; both ``inf`` (with ``reason``) when
        a pole lies on or outside the unit circle (within rounding).

    Raises
    ------
    DataError
        Continuous-time system, NaN/inf entries, a transfer function that is not proper, not a
        python-control system, ``tol`` outside ``[1e-14, 1)``, ``n_grid`` not an integer ≥ 2.

    Examples
    --------
    >>> import control
    >>> b = hinf_norm(control.tf([1], [1, -0.5], 1))
    >>> b.lower <= 2.0 <= b.upper
    True
    """
    tol = _as_tol(tol)
    n_grid = check_count(n_grid, "n_grid", 2)  # int() had parsed "5" and cut 10.5; 0 and -5 became 2
    s = _Sys(sys, "sys")
    stable, reason = s.stability()
    near = tuple(complex(p) for p in s.poles if 1.0 - abs(p) <= NEAR_UNIT_CIRCLE * (1 + 1e-6))
    if not stable:
        return NormBracket(lower=float("inf"), upper=float("inf"), frequency=float("nan"), tol=tol, stable=False,
                           spectral_radius=s.rho, reason=reason, near_poles=near)
    if s.m == 0 or s.p == 0:
        return NormBracket(0.0, 0.0, 0.0, tol, True, s.rho, "", near)
    lower, freq, upper, tests = _bracket(s, tol, n_grid)
    reason = "" if math.isfinite(upper) else "the bounded-real test did not pass at any level tried"
    return NormBracket(lower=float(lower), upper=float(upper), frequency=float(freq), tol=tol, stable=True,
                       spectral_radius=s.rho, reason=reason, near_poles=near, tests=tests)


def norm_below(sys, gamma: float, *, n_grid: int = 16) -> NormTest:
    """Prove ``‖G‖∞ < gamma`` for a discrete system, or say why not.

    One bounded-real pencil test at level ``gamma`` (no iteration), preceded by the cheap
    necessary conditions (Schur stability, ``γ > σ̄(D)``, no attained gain ``≥ γ`` on a small grid
    with the pole angles).

    Parameters
    ----------
    sys : control.StateSpace or control.TransferFunction
        Discrete-time system.
    gamma : float
        Level, finite and > 0.
    n_grid : int
        Points of the uniform grid checked first (pole angles are added), ≥ 2.

    Returns
    -------
    NormTest
        Truthy only when proven: stable ``A`` and no pencil eigenvalue within ``CIRCLE_TOL`` of the
        unit circle.  When not proven, ``reason`` says why and ``lower``/``frequency`` give the
        largest gain found.

    Raises
    ------
    DataError
        As :func:`hinf_norm`; ``gamma`` not a finite number > 0; ``n_grid`` not an integer ≥ 2.

    Examples
    --------
    ``‖1/(z − 0.5)‖∞ = 2``, attained at DC:

    >>> import control
    >>> G = control.tf([1], [1, -0.5], 1)
    >>> bool(norm_below(G, 2.01)), bool(norm_below(G, 1.99))
    (True, False)
    >>> test = norm_below(G, 1.99)
    >>> round(test.lower, 6), test.frequency
    (2.0, 0.0)
    >>> print(norm_below(control.tf([1], [1, -1.5], 1), 10.0).reason)
    unstable: pole 1.5+0j outside the unit circle (spectral radius 1.5)
    """
    return _norm_below(sys, gamma, n_grid=n_grid, allowance=True)


def _norm_below(sys, gamma: float, *, n_grid: int = 16, allowance: bool = True) -> NormTest:
    """:func:`norm_below`; ``allowance=False`` skips the rounding allowance (about half the cost).

    Without the allowance the answer is the pencil test's own verdict at ``gamma``, not a proof:
    only for the inner decisions of a search whose final answer is proven with the allowance
    (the bisection of :func:`~synthesis.discrete_mixsyn`).
    """
    gamma = check_level(gamma, "gamma")
    n_grid = check_count(n_grid, "n_grid", 2)
    s = _Sys(sys, "sys")
    stable, reason = s.stability()
    if not stable:
        return NormTest(False, gamma, reason, float("inf"), float("nan"))
    if s.m == 0 or s.p == 0:
        return NormTest(True, gamma, "empty system (no inputs or outputs): the norm is 0", 0.0, 0.0)
    w = _grid(s, n_grid)
    g = s.gains(w)
    k = int(np.argmax(g))
    lower, freq = float(g[k]), float(w[k])
    if lower >= gamma:
        return NormTest(False, gamma, f"gain {lower:.12g} >= gamma is attained at w = {freq:.6g} rad/sample",
                        lower, freq)
    allow = _allowance(s, lower, freq) if allowance else 0.0
    level = gamma - allow
    if level <= lower:
        return NormTest(False, gamma, (
            f"not proven: gain {lower:.12g} (attained at w = {freq:.6g} rad/sample) is within the rounding "
            f"allowance {allow:.3g} of gamma"), lower, freq)
    proven, ang, gl, wl, dmin = _test(s, level)
    if gl > lower:
        lower, freq = gl, wl
    if ang.size:
        cand = np.concatenate([ang, 0.5 * (ang[1:] + ang[:-1])])
        gc = s.gains(cand)
        j = int(np.argmax(gc))
        if gc[j] > lower:
            lower, freq = float(gc[j]), float(cand[j])
    if lower >= gamma:
        return NormTest(False, gamma, f"gain {lower:.12g} >= gamma is attained at w = {freq:.6g} rad/sample",
                        lower, freq)
    if not proven:
        return NormTest(False, gamma, (
            f"not proven: the bounded-real pencil has eigenvalue(s) on the unit circle within rounding "
            f"at w = {', '.join(f'{a:.6g}' for a in ang[:4])} rad/sample (gamma is at or within rounding of "
            "a singular value there)"), lower, freq)
    return NormTest(True, gamma, (
        f"proven: stable (spectral radius {s.rho:.6g}) and the bounded-real pencil has no eigenvalue on the "
        f"unit circle (closest at relative distance {dmin:.3g})"), lower, freq)
