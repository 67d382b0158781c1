"""Left coprime factors of the data-based model P̂, and the uncertainty they carry.

The predictor's first block row is an ARX model (:mod:`unfalsify.model`),

    y_k + Σ_{d=1..i} M_d y_{k−d} = Σ_{d=0..i} N_d u_{k−d},

that is ``P̂ = M̂⁻¹N̂`` with the polynomial matrices ``M̂(q) = I + Σ M_d q^{−d}`` (l × l) and
``N̂(q) = Σ N_d q^{−d}`` (l × m).  Both are FIR, hence stable, *whatever the poles of P̂*: for a plant
with an integrator ``‖P − P̂‖∞`` is infinite (P̂'s pole never sits exactly at 1), so no additive
certificate can hold, while the factors stay bounded.  The uncertainty model of this module is

    P = (M̂ + Δ_M)⁻¹ (N̂ + Δ_N),    [Δ_N  Δ_M] stable,  ‖[Δ_N  Δ_M]‖∞ ≤ ε.

**Robust stability** (small gain).  With ``u = C_y y`` (the controller's feedback part, inputs
``[r; y]`` as everywhere in :mod:`unfalsify`), ``M̂ y = N̂ u + v`` with ``v = Δ_N u − Δ_M y``: the
perturbation sees the map ``v ↦ [u; y]``,

    H = [C_y; I] (M̂ − N̂ C_y)⁻¹,

which is stable exactly when the nominal loop is (the factors are coprime FIR).  The loop is stable for
every plant of the family when ``ε ‖H‖∞ < 1`` (:func:`unfalsify.coprime_channel`,
:func:`unfalsify.certify_loop` with ``factors=``).

**Unfalsification** (Theorem 7.1).  On a record the *equation error* ``e = M̂y − N̂u`` equals
``[Δ_N  −Δ_M] [u; y] + ξ`` for the true perturbation and the noise ξ: that is Theorem 7.1 with input
``w = [u; y]`` (m + l channels) and output ``e`` (l channels), solved with its two-sided certificate by
:func:`unfalsify.arx_unfalsify` (:func:`coprime_unfalsify`).  The residual is the record's whole
input–output relation in the form the certificate uses (no simulation of P̂ is needed: the factors are
FIR, the equation holds sample by sample).

**The premise and its second route.**  At each frequency a plant ``G`` needs a perturbation of norm at
least ``‖(M̂G − N̂)(I + GᴴG)^{−1/2}‖₂`` (the least-norm ``X`` with ``X [I; G] = M̂G − N̂``): the
*pointwise coprime distance* (:func:`coprime_gap`).  Over a confidence region ``‖G − Ĝ‖₂ ≤ r`` of a
nonparametric estimate it is at least ``(σ̄(M̂Ĝ − N̂) − r σ̄(M̂))₊ / √(1 + (σ̄(Ĝ) + r)²)``;
:func:`check_coprime_premise` bounds it from an estimate of ``R = M̂P − N̂`` instead (:func:`error_gap`; for one
channel the least distance over R's confidence disk) and refuses where that exceeds ε.  The distance is finite where
``|P| → ∞`` (it tends to ``σ̄`` of ``M̂``'s part there), so an integrator is judged by how well P̂
places its pole, not by an infinite gain difference.

What no finite record proves: that ε also bounds the perturbation at frequencies and in directions the
input did not excite; :func:`unfalsify.check_excitation` checks the loop there.
"""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import control
import numpy as np

from synthesis.results import result
from synthesis.validation import (DataError, as_discrete_system, check_count, check_flag, check_inputs_move,
                                  check_instance, check_level, check_nonnegative, check_output_moves)

from ._common import channel_pair, check_sigma
from .arx import ArxResult, arx_unfalsify
from .factors import CoprimeFactors, _factors, coprime_factors
from .frequency_response import (FrequencyResponseEstimate, LowBandEstimate, _bands, _check_estimate_dt, _inverse_root,
                                 _step, _unit, frequency_response_estimate, low_band_estimate)
from .premise import (PremiseOptions, _fir_sigma, _floor_note, _low_bins, _model_gap, _premise_options,
                      _region_reach, _residual_low_band, _times)

__all__ = ["CoprimeFactors", "coprime_factors", "coprime_gap", "coprime_distance", "error_gap",
           "CoprimeUnfalsification", "coprime_unfalsify", "CoprimePremise", "check_coprime_premise",
           "unconfirmed_coprime_premise"]


#: largest number of Markov parameters n·l·(m + l) of Δ in one coprime solve (measured on 2 cores: a 2 × 2
#: output-error solve with 1200 takes about 26 s)
_MAX_VARIABLES = 1200


def _nyquist(dt) -> float:
    """π/dt in rad/s; π (rad/sample) for an unspecified sample time (``dt=True``)."""
    return float(np.pi / _step(dt))


def coprime_gap(factors: CoprimeFactors, frequency, response, radius=None) -> np.ndarray:
    """Pointwise lower bound of the coprime perturbation ``‖[Δ_N Δ_M]‖₂`` a plant near ``response`` needs.

    Parameters
    ----------
    factors : CoprimeFactors
    frequency : array_like, shape (F,)
        rad/s.
    response : array_like, complex, shape (F,) or (F, l, m)
        A plant's frequency response ``G``, or an estimate ``Ĝ``.
    radius : array_like, shape (F,), optional
        A confidence radius ``‖G − Ĝ‖₂ ≤ r`` around ``response``.  None or 0: the exact least norm
        ``‖(M̂G − N̂)(I + GᴴG)^{−1/2}‖₂``; otherwise ``(σ̄(M̂Ĝ − N̂) − r σ̄(M̂))₊ / √(1 + (σ̄(Ĝ) + r)²)``, a lower
        bound over the whole region (``‖X‖ ≥ ‖XZ‖/‖Z‖`` for any ``X`` with ``X Z = M̂G − N̂``).

    Returns
    -------
    ndarray, shape (F,)
        NaN where the response is not finite; 0 where the radius is infinite.

    Raises
    ------
    InputTypeError
        ``factors`` is not a :class:`CoprimeFactors`.
    DataError
        Frequencies that are not finite or lie outside ``[0, π/dt]``; a response that is not numeric or whose shape
        is not ``(F,)`` (one channel) or ``(F, l, m)``; a radius that is negative, NaN or not of length F.

    Examples
    --------
    >>> import numpy as np
    >>> F = CoprimeFactors(N=np.array([[[0.0]], [[0.1]]]), M=np.array([[[1.0]], [[-1.0]]]), dt=1.0)
    >>> w = np.array([0.01, 0.1, 1.0])
    >>> G = 0.1 / (np.exp(1j * w) - 1.0)                         # the plant itself: distance 0
    >>> bool(np.allclose(coprime_gap(F, w, G), 0.0, atol=1e-12))
    True
    >>> G2 = 0.2 / (np.exp(1j * w) - 1.0)                        # twice the gain: M̂G₂ − N̂ = 0.1 z⁻¹
    >>> np.round(coprime_gap(F, w, G2), 4).tolist()             # 0.1/√(1 + |G₂|²): finite, small near DC
    [0.005, 0.0447, 0.0979]
    """
    _factors(factors)
    w = _gap_frequencies(frequency, factors.dt)
    G = _numeric(response, "response").astype(complex)
    l, m = factors.outputs, factors.inputs
    siso = G.shape == (w.size,) and l == m == 1
    if not (siso or G.shape == (w.size, l, m)):
        raise DataError(f"response has shape {G.shape} for {w.size} frequencies; the factors are {l} × {m} (outputs × "
                        f"inputs): pass ({w.size}, {l}, {m})" + (f" or ({w.size},)" if l == m == 1 else "")
                        + ", one response per frequency")
    G = G.reshape(w.size, l, m)
    r = None
    if radius is not None:
        r = _numeric(radius, "radius")
        if r.shape not in ((), (w.size,)):
            raise DataError(f"radius has shape {r.shape}; pass one number or {w.size} (one per frequency)")
        bad = np.isnan(r) | (r < 0)
        if np.any(bad):
            raise DataError(f"radius must be ≥ 0 (inf: nothing known), got {float(r[bad].flat[0]):g}; a confidence "
                            "radius of the response is a distance")
        r = np.broadcast_to(r.astype(float), w.shape)
    Nw, Mw = factors.response(w)
    out = np.full(w.size, np.nan)
    ok = np.all(np.isfinite(G), axis=(1, 2))
    if not np.any(ok):
        return out
    R = Mw[ok] @ G[ok] - Nw[ok]
    r = None if r is None else r[ok]
    if r is None or not np.any(r > 0):
        if siso:
            out[ok] = np.abs(R[:, 0, 0]) / np.sqrt(1.0 + np.abs(G[ok, 0, 0]) ** 2)
        else:
            gram = np.eye(factors.inputs) + np.conj(np.swapaxes(G[ok], 1, 2)) @ G[ok]
            inv_sqrt = _inverse_root(gram, np.ones(gram.shape[0], bool))  # I + GᴴG ≻ 0
            out[ok] = np.linalg.norm(R @ inv_sqrt, ord=2, axis=(1, 2))
        return out
    norm = (lambda X: np.abs(X[:, 0, 0])) if siso else (lambda X: np.linalg.norm(X, ord=2, axis=(1, 2)))
    with np.errstate(invalid="ignore"):
        low = np.maximum(norm(R) - r * norm(Mw[ok]), 0.0) / np.sqrt(1.0 + (norm(G[ok]) + r) ** 2)
    out[ok] = np.where(np.isfinite(r), low, 0.0)
    return out


def _numeric(x, name: str) -> np.ndarray:
    """``x`` as a numeric array (real or complex), DataError otherwise (a string had reached numpy's conversion)."""
    arr = np.asarray(x)
    if arr.dtype.kind not in "biufc":
        raise DataError(f"{name} must be a numeric array, got {type(x).__name__} {x!r:.40}")
    return arr


def _gap_frequencies(frequency, dt) -> np.ndarray:
    """Frequencies (rad/s) as a 1-D float array, each finite and in ``[0, π/dt]`` (DataError otherwise): the factors'
    response is periodic in ω with period 2π/dt, so a frequency above Nyquist is another frequency's, and a NaN one
    had given a NaN gap without a word."""
    w = np.atleast_1d(_numeric(frequency, "frequency"))
    if np.iscomplexobj(w) or w.ndim != 1:
        raise DataError(f"frequency must be a 1-D array of real frequencies in rad/s, got shape {w.shape}"
                        + (" (complex)" if np.iscomplexobj(w) else ""))
    w = w.astype(float)
    nyq = _nyquist(dt)
    bad = ~(np.isfinite(w) & (w >= 0.0) & (w <= nyq * (1.0 + 1e-12)))
    if np.any(bad):
        k = int(np.flatnonzero(bad)[0])
        raise DataError(f"frequency[{k}] = {w[k]:g} lies outside [0, π/dt] = [0, {nyq:.6g}] rad/s (dt = {dt}); pass "
                        "finite frequencies in rad/s up to the Nyquist frequency (a normalised frequency in "
                        "rad/sample is ω·dt)")
    return w


def coprime_distance(factors: CoprimeFactors, plant, points: int = 512) -> tuple[float, float]:
    """``(distance, frequency)``: the largest pointwise coprime distance of ``plant`` from ``(N̂, M̂)`` on a grid.

    A lower bound of the least ``‖[Δ_N Δ_M]‖∞`` with ``plant = (M̂ + Δ_M)⁻¹(N̂ + Δ_N)`` (every admissible
    perturbation has at least this norm at each frequency); what a study reports as the premise ratio
    ``distance/ε`` of a coprime certificate (above 1: the premise is false).  The grid is logarithmic from
    ``10⁻⁴`` of Nyquist to Nyquist.

    Parameters
    ----------
    factors : CoprimeFactors
    plant : control.StateSpace or control.TransferFunction
        A discrete-time plant at the factors' sample time, with their numbers of inputs and outputs.
    points : int
        Number of grid frequencies, ≥ 2 (the grid's two ends).

    Raises
    ------
    DataError
        A continuous-time plant, another sample time or shape, ``points`` not an integer ≥ 2.

    Examples
    --------
    >>> import control, numpy as np
    >>> F = CoprimeFactors(N=np.array([[[0.0]], [[0.1]]]), M=np.array([[[1.0]], [[-1.0]]]), dt=1.0)
    >>> d, w = coprime_distance(F, control.tf([0.1], [1.0, -1.0], 1.0))
    >>> bool(d < 1e-12)
    True
    """
    _factors(factors)
    points = check_count(points, "points", 2)
    sys = control.ss(as_discrete_system(plant, "plant"))  # a continuous plant was read as if discrete
    # True (unspecified) on either side matches any sample time, as in synthesis.validation.check_same_dt
    if sys.dt is not True and factors.dt is not True and not np.isclose(float(sys.dt), factors.dt, rtol=1e-9,
                                                                        atol=0.0):
        raise DataError(f"plant has sample time {sys.dt} but the factors {factors.dt}; compare systems at one sample "
                        "time")
    if (sys.noutputs, sys.ninputs) != (factors.outputs, factors.inputs):
        raise DataError(f"plant is {sys.noutputs} × {sys.ninputs} but the factors {factors.outputs} × "
                        f"{factors.inputs} (outputs × inputs)")
    dt = _step(factors.dt)
    nyq = _nyquist(dt)
    w = np.concatenate([np.geomspace(1e-4 * nyq, nyq, points)])
    with np.errstate(divide="ignore", invalid="ignore"):
        G = np.moveaxis(np.asarray(sys.horner(np.exp(1j * w * dt)), complex), -1, 0)
    gap = coprime_gap(factors, w, G.reshape(w.size, factors.outputs, factors.inputs))
    k = int(np.nanargmax(gap)) if np.any(np.isfinite(gap)) else 0
    return float(gap[k]), float(w[k])


@result
@dataclass(frozen=True, eq=False)
class CoprimeUnfalsification:
    """Theorem 7.1 on the equation error ``e = M̂y − N̂u`` with input ``w = [u; y]`` (module docstring).

    Attributes
    ----------
    epsilon : float
        The certified upper end of the smallest unfalsified ``‖[Δ_N Δ_M]‖∞`` (NaN when the solve certified
        nothing).
    unfalsification : ArxResult
        The program (7.4) with no ARX parameters on ``(w, e)``, with its two-sided ``certificate``.
    residual : ndarray
        ``e`` on the segment (rows after the horizon).
    sigma : float
        Admissible rms noise of the equation (pooled over the outputs).
    sigma_rule : str
    held_out : bool
        The record was not used to fit P̂.
    burn_in : int
        Free rows at the start (Δ's own transient from the unknown past of ``w``).
    """

    epsilon: float
    unfalsification: ArxResult | None
    residual: np.ndarray
    sigma: float
    sigma_rule: str
    held_out: bool
    burn_in: int


def coprime_unfalsify(factors: CoprimeFactors, u, y, *, held_out: bool, sigma=None,
                      options: PremiseOptions | None = None) -> CoprimeUnfalsification:
    """The smallest coprime-factor uncertainty ``‖[Δ_N Δ_M]‖∞`` that explains the record (Theorem 7.1).

    Parameters
    ----------
    factors : CoprimeFactors
    u, y : array_like, shape (n,) or (n, m) and (n, l)
        A record of the plant, best one not used to fit P̂ (``held_out``).
    held_out : bool
    sigma : float, optional
        Admissible rms noise of the equation ``M̂y = N̂u + v`` (per output sample).  Default
        ``options.sigma``, else estimated: the residual rms, per degree of freedom, of a least-squares fit of
        ``e`` on the input's last ``taps`` samples and the output's *past* ``taps`` samples -- what no linear
        causal map of the past explains is called noise.  (The output's current sample holds the noise
        itself, so it is left out of the fit; Theorem 7.1 still lets Δ act on it.)
    options : PremiseOptions, optional
        ``coprime_samples`` (largest segment beyond the burn-in, default 200), ``burn_in``, ``taps``, ``tol``,
        ``time_limit``.  Several channels use at most ``1200/(l(m + l))`` rows beyond the burn-in (Δ's Markov
        parameters are the program's variables).

    Returns
    -------
    CoprimeUnfalsification

    Examples
    --------
    >>> import numpy as np, synthesis as sy
    >>> rng = np.random.default_rng(2)
    >>> u = np.sign(rng.standard_normal(700))
    >>> y = np.zeros(700)
    >>> for k in range(1, 700):
    ...     y[k] = y[k - 1] + 0.1 * u[k - 1]                            # an integrator
    >>> y += 0.02 * rng.standard_normal(700)
    >>> F = coprime_factors(sy.fit_predictor(u[:400], y[:400], 4), 1.0)
    >>> cu = coprime_unfalsify(F, u[400:560], y[400:560], held_out=True)
    >>> bool(0 <= cu.epsilon < 0.05), cu.unfalsification.certificate.verify()
    (True, True)
    """
    _factors(factors)
    opts = _premise_options(options)
    held_out = check_flag(held_out, "held_out")
    if sigma is not None:
        sigma = check_sigma(sigma)  # a string had reached float() below, and 0 or a negative σ the solver
    u, y = channel_pair(u, y)
    # a zero input or a dead sensor's constant output had given an ε, as the output-error test refuses them
    check_inputs_move(u, "the record", each_channel=False)
    check_output_moves(y, "the record")
    i = factors.horizon
    burn = i if opts.burn_in is None else int(opts.burn_in)
    e_all = factors.residual(u, y).reshape(u.shape[0] - i, factors.outputs)
    # Δ has n·l·(m + l) Markov parameters; the structured solve grows like their cube, so several channels
    # get fewer rows
    width = factors.inputs + factors.outputs
    n = min(e_all.shape[0], burn + int(opts.coprime_samples), burn + _MAX_VARIABLES // (factors.outputs * width))
    if sigma is None and opts.sigma is not None:
        sigma = opts.sigma
    # an estimated σ needs rows for its fit (4 per coefficient); a given one only a few rows beyond the burn-in
    rows = max(4 * i, 16 * width) if sigma is None else 2 * width
    if n < burn + rows or n < 2 * burn:
        raise DataError(f"the record has {u.shape[0]} samples; the coprime test needs at least "
                        f"{i + max(burn + rows, 2 * burn)} (horizon {i}, burn-in {burn}): pass a longer record")
    U = u.reshape(u.shape[0], -1)[i:i + n]
    Y = y.reshape(y.shape[0], -1)
    w = np.hstack([U, Y[i:i + n]])
    e = e_all[:n]
    if sigma is not None:
        rule = "given"
    else:
        taps = opts.taps if opts.taps is not None else min((n - burn) // (4 * width), max(4 * i, 20))
        past = np.hstack([U, Y[i - 1:i - 1 + n]])  # u_k … and y_{k−1} …: the current output is left out
        sigma, floored = _fir_sigma(past, e, int(taps), burn)
        rule = (f"residual rms of a least-squares fit of the equation error on the input's last {taps} samples and "
                f"the output's past {taps}, per degree of freedom (rows {burn}…{n - 1})" + _floor_note(floored))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a non-optimal status is read from the result below
        res = arx_unfalsify(w, e, 0, 0, sigma, backend="structured", tol=opts.tol, time_limit=opts.time_limit,
                            progress=False, free_rows=burn)
    eps = float(res.delta) if math.isfinite(res.delta) else float("nan")
    residual = e_all[:, 0] if factors.outputs == 1 and np.ndim(y) == 1 else e_all
    return CoprimeUnfalsification(epsilon=eps, unfalsification=res, residual=residual, sigma=float(sigma),
                                  sigma_rule=rule, held_out=bool(held_out), burn_in=burn)


@result
@dataclass(frozen=True, eq=False)
class CoprimePremise:
    """The premise of a coprime-factor certificate, tested on the data (module docstring).

    Attributes
    ----------
    factors : CoprimeFactors
        ``(N̂, M̂)`` of P̂.
    in_sample : CoprimeUnfalsification or None
        Theorem 7.1 on the window P̂ was fitted on, at the admissible noise of (7.5).
    held_out : CoprimeUnfalsification or None
        Theorem 7.1 on the held-out record (``validation=``), noise estimated; without one, on the window itself
        (its ``held_out`` is then False: in sample, optimistic).
    epsilon : float
        The larger of the two: what the loop is certified for.
    decided_by : str
        ``"in sample"``, ``"held out"`` or ``"in sample, noise estimated"`` (no held-out record).
    inconsistency : float
        ``max gap/ε`` of :func:`coprime_gap` over the excited Welch frequencies and the low band (> 1: the
        data place the plant outside the ε-family).
    reason : str
        ``''`` when the premise survived; otherwise why not, and the fix.
    error_frf, error_low_band : FrequencyResponseEstimate, LowBandEstimate or None
        Nonparametric estimates of ``R = M̂P − N̂`` (from ``u`` to the equation error ``e``) on the held-out
        record (the window without one), which the gap was measured with (:func:`error_gap`) and which
        :func:`unfalsify.check_excitation` takes with ``factors=``.
    record_low_band : LowBandEstimate or None
        The low band of ``R`` over the longest contiguous record given (``record`` of :func:`check_coprime_premise`;
        None without one).  In sample, so it only refutes: a gap beyond ε there refuses the premise.
    """

    factors: CoprimeFactors
    in_sample: CoprimeUnfalsification | None
    held_out: CoprimeUnfalsification | None
    epsilon: float
    decided_by: str
    inconsistency: float
    reason: str
    error_frf: FrequencyResponseEstimate | None = None
    error_low_band: LowBandEstimate | None = None
    record_low_band: LowBandEstimate | None = None

    @property
    def ok(self) -> bool:
        """The premise survived the tests."""
        return not self.reason


def _solve_or_reason(factors, data, held_out: bool, sigma, opts, what: str, reasons: list):
    try:
        cu = coprime_unfalsify(factors, *data, held_out=held_out, sigma=sigma, options=opts)
    except DataError as exc:
        reasons.append(f"the coprime test on the {what} cannot run ({exc})")
        return None
    if not math.isfinite(cu.epsilon):
        st = cu.unfalsification.status if cu.unfalsification is not None else "none"
        reasons.append(f"Theorem 7.1 on the {what}'s equation error certified no ε (status {st!r}); use a longer "
                       "record or a looser tolerance")
    return cu


def error_gap(factors: CoprimeFactors, est) -> np.ndarray:
    """Lower bound of the pointwise coprime distance from an estimate of the equation error's response.

    ``est`` estimates ``R = M̂P − N̂`` (the response from ``u`` to ``e = M̂y − N̂u``) with radius ``r``.  Since
    ``P = M̂⁻¹(N̂ + R)`` has ``σ̄(P) ≤ σ̄(N̂ + R)/μ`` and every ``R`` in the region has
    ``σ̄(N̂ + R) ≤ b = min(ν + σ̄(R), σ̄(N̂ + R̂) + r)``, the least perturbation
    ``‖R(I + PᴴP)^{−1/2}‖₂ ≥ σ̄(R)/√(1 + σ̄(P)²)`` is at least ``x μ/√(μ² + b²)`` at ``σ̄(R) = x = (σ̄(R̂) − r)₊``
    (increasing in σ̄(R)), ``μ = σ_min(M̂)``, ``ν = σ̄(N̂)``; several inputs read ``x`` in the region's directions,
    the largest ``‖R̂v‖ − ‖Qv‖`` over a few unit ``v`` (``Q`` the region's factor), at least ``σ̄(R̂) − r``.  The
    second term of b matters where P̂ misses a slow mode that cancels its gain: there ``N̂ + R = M̂P`` is small
    while ``ν + x`` is not.  One channel: the least distance over the disk itself (:func:`_disc_gap`; measured on a
    plant whose DC gain the slow mode flips to −0.1: 0.088 with ``ν + x``, 0.12 over the disk, the true distance
    0.29 at the record's lowest frequency).  No estimate of P itself is used: a Welch estimate
    of an integrating plant is biased near DC (the window's main lobe averages a response that changes
    within a bin), while R is smooth there.  Where ``M̂`` vanishes (P̂'s integrator) the bound is 0: the data
    cannot show a coprime error at a pole.

    Raises
    ------
    InputTypeError
        ``factors`` or ``est`` of another type.
    DataError
        ``est`` estimated with another sample time than the factors' (its frequencies would name other points).

    Examples
    --------
    >>> import numpy as np
    >>> from unfalsify import LowBandEstimate
    >>> F = CoprimeFactors(N=np.array([[[0.0]], [[0.1]]]), M=np.array([[[1.0]], [[-1.0]]]), dt=1.0)
    >>> w = np.array([0.0, 1.0])                                # at DC M̂ = 0: no evidence there
    >>> est = LowBandEstimate(frequency=w, response=np.array([0.1, 0.1]), radius=np.array([0.02, 0.02]),
    ...                       confidence=0.99, window=16, degree=2, samples=100, dt=1.0)
    >>> np.round(error_gap(F, est), 4).tolist()
    [0.0, 0.0789]
    """
    _factors(factors)
    check_instance(est, (FrequencyResponseEstimate, LowBandEstimate), "est",
                   "a FrequencyResponseEstimate or LowBandEstimate of the equation error (CoprimePremise.error_frf)")
    _check_estimate_dt(est, factors.dt, "est", "the factors")
    w = np.asarray(est.frequency, float)
    Nw, Mw = factors.response(w)
    R = np.asarray(est.response, complex).reshape(w.size, factors.outputs, factors.inputs)
    r = np.asarray(est.radius, float)
    if factors.outputs == factors.inputs == 1:
        return np.where(np.isfinite(r), _disc_gap(R[:, 0, 0], r, Nw[:, 0, 0], Mw[:, 0, 0]), 0.0)
    reach = np.full(w.size, np.nan)
    ok = np.all(np.isfinite(R), axis=(1, 2))
    reach[ok] = np.linalg.norm(Nw[ok] + R[ok], ord=2, axis=(1, 2))
    mu = np.linalg.svd(Mw, compute_uv=False)[:, -1]
    nu = np.linalg.norm(Nw, ord=2, axis=(1, 2))
    with np.errstate(invalid="ignore"):
        # σ̄(R) ≥ ‖R̂v‖ − ‖Qv‖ for unit v (the region's directions, premise._model_gap; at least σ̄(R̂) − r): the
        # isotropic r took the least-excited input direction's confidence for every direction
        x = np.maximum(np.where(ok, _model_gap(est), np.nan), 0.0)
        b = np.minimum(nu + x, reach + r)  # two bounds on σ̄(N̂ + R) over the region
        return np.where(np.isfinite(r), x * mu / np.sqrt(mu ** 2 + b ** 2), 0.0)


def _disc_gap(R: np.ndarray, r: np.ndarray, N: np.ndarray, M: np.ndarray, steps: int = 60) -> np.ndarray:
    """One channel: the least ``g(X) = |X||M|/√(|M|² + |N + X|²)`` over each disk ``|X − R| ≤ r``, from below.

    ``g(X)² < c`` reads ``(|M|² − c)|X|² − 2c Re(N̄X) < c(|M|² + |N|²)``: for ``c < |M|²`` the inside of a circle
    about ``cN/(|M|² − c)``, for ``c > |M|²`` the outside of one (or the whole plane), and these sets grow with c.
    The disk misses the set exactly when the least value is at least √c, so bisection on c keeps a value the disk
    is proven to miss: a lower bound within 2⁻⁶⁰ of the range ``(|R| + r)²`` of the exact one.  0 where the disk
    holds ``X = 0``; NaN rows give 0."""
    m2, n2 = np.abs(M) ** 2, np.abs(N) ** 2
    known = np.isfinite(R) & np.isfinite(r)
    R, r = np.where(known, R, 0.0), np.where(known, r, 0.0)
    lo, hi = np.zeros(r.shape), (np.abs(R) + r) ** 2
    with np.errstate(divide="ignore", invalid="ignore"):
        for _ in range(steps):
            c = 0.5 * (lo + hi)
            a = m2 - c
            rho = np.sqrt(np.maximum((c / a) ** 2 * n2 + c * (m2 + n2) / a, 0.0))
            d = np.abs(R - (c / a) * N)
            missed = np.where(a > 0, d >= r + rho, (rho > 0) & (d + r <= rho))
            lo, hi = np.where(missed, c, lo), np.where(missed, hi, c)
    return np.where(known & (np.abs(R) > r), np.sqrt(lo), 0.0)


def _gap_reason(factors, est, eps: float, where: str) -> tuple[float, str]:
    """``max gap/ε`` over an estimate's usable frequencies and, where the gap exceeds ε, why."""
    usable = np.isfinite(est.radius)
    if isinstance(est, FrequencyResponseEstimate):
        usable &= est.excited
    if not np.any(usable):
        return float("nan"), ""
    gap = np.nan_to_num(np.where(usable, error_gap(factors, est), -np.inf), nan=-np.inf)
    k = int(np.argmax(gap))
    worst = gap[k] / eps if eps > 0 else (float("inf") if gap[k] > 0 else 0.0)
    if not gap[k] > eps:
        return float(worst), ""
    unit = _unit(est.dt)
    return float(worst), (f"{where} the data place the plant outside the coprime-factor family of P̂ (a perturbation "
                          f"of at least {gap[k]:.3g} > ε = {eps:.4g} at {est.frequency[k]:.3g} {unit}; "
                          f"{_bands(est.frequency, gap > eps, unit)}): P̂ is biased there; fit it on a longer or "
                          "richer record (white PRBS), or raise the horizon")


def check_coprime_premise(factors: CoprimeFactors, u, y, sigma_window: float, *, validation=None,
                          options: PremiseOptions | None = None, record=None) -> CoprimePremise:
    """Test the premise of a coprime-factor certificate on the data (module docstring).

    ε is the larger of Theorem 7.1 on the window's equation error at the admissible noise of (7.5)
    (``sigma_window``: the same residual, the predictor's first row, in the same units) and on the held-out
    record's with the noise estimated (:func:`coprime_unfalsify`).  The plant's Welch estimate and its
    low-band estimate on the held-out record (the window without one) must then lie within ε of the family
    (:func:`error_gap`: the estimates of ``R = M̂P − N̂`` from the input to the equation error, with their
    confidence radii) at every excited frequency.

    Parameters
    ----------
    factors : CoprimeFactors
    u, y : array_like
        The window P̂ was fitted on.
    sigma_window : float
        Admissible rms noise of (7.5).
    validation : tuple of array_like, optional
        ``(u_v, y_v)``, a record not used to fit P̂.
    options : PremiseOptions, optional
    record : tuple of array_like, optional
        ``(u_r, y_r)``: the longest contiguous record that holds the window (the pipeline's whole record in record
        mode).  The low band of its equation error reaches below the held-out record's lowest frequency; in sample,
        so it only refutes (``record_low_band``).  None: not used.

    Returns
    -------
    CoprimePremise

    Examples
    --------
    >>> import numpy as np, synthesis as sy
    >>> rng = np.random.default_rng(3)
    >>> u = np.sign(rng.standard_normal(1200))
    >>> y = np.zeros(1200)
    >>> for k in range(1, 1200):
    ...     y[k] = y[k - 1] + 0.1 * u[k - 1]                            # an integrator
    >>> y += 0.02 * rng.standard_normal(1200)
    >>> F = coprime_factors(sy.fit_predictor(u[:700], y[:700], 4), 1.0)
    >>> p = check_coprime_premise(F, u[:60], y[:60], 0.01, validation=(u[700:900], y[700:900]))
    >>> p.ok, p.epsilon >= p.held_out.epsilon, p.decided_by in ("in sample", "held out")
    (True, True, True)
    """
    # checked here: coprime_unfalsify's refusals below become reasons of the result, not errors
    _factors(factors)
    sigma_window = check_level(sigma_window, "sigma_window (the admissible rms noise of (7.5), e.g. "
                                             "subspace_unfalsify(...).sigma)")
    opts = _premise_options(options)
    u, y = channel_pair(u, y)
    reasons: list = []
    inside = _solve_or_reason(factors, (u, y), False, sigma_window, opts, "window", reasons)
    data = (u, y)
    if validation is not None:
        try:
            uv, yv = validation
        except (TypeError, ValueError):
            raise DataError("validation must be a pair (u, y) of held-out data of the same plant") from None
        data = channel_pair(uv, yv, "validation ")
    # without a held-out record the window stands in for it (in sample: optimistic, and the result says so)
    outside = _solve_or_reason(factors, data, validation is not None, None, opts,
                               "held-out record" if validation is not None else "window (no held-out record)",
                               reasons)
    eps_in = inside.epsilon if inside is not None else float("nan")
    eps_out = outside.epsilon if outside is not None else float("nan")
    eps = float(np.nanmax([eps_in, eps_out])) if np.isfinite([eps_in, eps_out]).any() else float("nan")
    decided = "in sample"
    if math.isfinite(eps_out) and not eps_out < eps:
        decided = "held out" if outside.held_out else "in sample, noise estimated"
    worst, frf, low = float("nan"), None, None
    if math.isfinite(eps):
        uu, _ = data
        ue = uu[factors.horizon:]
        dt = _step(factors.dt)  # the estimates need a number
        try:
            # the equation error of the whole record (FIR: every row usable), already formed by the solve above; a
            # held-out record too short for its test is too short for this one (its residual had raised, uncaught)
            e = outside.residual if outside is not None else factors.residual(*data)
            frf = frequency_response_estimate(ue, e, dt, nperseg=opts.nperseg, confidence=opts.confidence)
        except DataError as exc:
            reasons.append(f"no frequency-response estimate of the equation error on the "
                           f"{'held-out record' if validation is not None else 'window'} ({exc})")
    if frf is not None:
        worst, why = _gap_reason(factors, frf, eps, "at the Welch frequencies")
        if why:
            reasons.append(why)
        bins = _low_bins(e.shape[0], frf.nperseg, 1 if ue.ndim == 1 else ue.shape[1])
        if bins:
            low = low_band_estimate(ue, e, dt, bins=bins, confidence=opts.confidence)
            low_worst, why = _gap_reason(factors, low, eps, "at low frequency (below the Welch resolution)")
            worst = float(np.fmax(worst, low_worst))
            if why:
                reasons.append(why)
    whole = None
    if record is not None and frf is not None:
        whole, whole_worst, why = _record_gap(factors, record, eps, dt, frf.nperseg, opts)
        if why:  # refutation only: an in-sample estimate inside the family confirms nothing
            worst = float(np.fmax(worst, whole_worst))
            reasons.append(why)
    return CoprimePremise(factors=factors, in_sample=inside, held_out=outside, epsilon=eps, decided_by=decided,
                          inconsistency=worst, reason="; ".join(reasons), error_frf=frf, error_low_band=low,
                          record_low_band=whole)


def _record_gap(factors: CoprimeFactors, record, eps: float, dt: float, nperseg: int,
                opts: PremiseOptions) -> tuple[LowBandEstimate | None, float, str]:
    """``(estimate, max gap/ε, reason)`` of the low band of the equation error over ``record`` (the coprime form
    of :func:`unfalsify.premise._record_low_band`: in sample, a refutation only)."""
    try:
        ur, yr = channel_pair(*record, "record ")
        e = factors.residual(ur, yr)
    except (DataError, TypeError, ValueError):
        return None, float("nan"), ""  # no usable record: no evidence
    est = _residual_low_band(ur[factors.horizon:], e, dt, nperseg, opts.confidence)
    if est is None:
        return None, float("nan"), ""
    unit = _unit(dt)
    worst, why = _gap_reason(factors, est, eps, f"over the whole {ur.shape[0]}-sample record (in sample, lowest "
                             f"frequency {est.frequency[0]:.3g} {unit}: slower than the held-out part shows), at low "
                             "frequency")
    return est, worst, why


def unconfirmed_coprime_premise(premise: CoprimePremise, bound: float) -> str:
    """Why the data do not confirm the premise of a coprime-factor certificate -- the plant within ``bound`` of
    P̂'s factors -- ``''`` when they do (the coprime form of :func:`unfalsify.unconfirmed_premise`).

    The data estimate ``R = M̂P − N̂``, and ``(M̂, N̂ + R)`` factors the plant, so ``[Δ_N Δ_M] = [R 0]`` is one
    perturbation that reaches it: where the confidence regions of ``R`` (``error_frf`` at the excited Welch
    frequencies, ``error_low_band`` below them) reach beyond ``bound``, the data allow a plant that only a larger
    perturbation of these factors reaches.  :func:`check_coprime_premise` refuses only where a region lies wholly
    beyond ε (evidence), so a certified loop can rest on a ball the data do not confirm.  Measured (2026-11-29,
    slowH hunt): a slow mode that flips the plant's DC gain (``P(1) = −0.1``, P̂'s 0.93 at i = 5) left the additive
    premise refuted and the coprime one passed (largest gap 0.41 ε at 0.127 rad/s); the loop certified in coprime
    form was unstable on the plant, whose distance from the family was 3.8–9.1 ε, while the regions of ``R`` reached
    2.7 times ``(1 + margin)·ε`` -- this statement, where before a coprime result said nothing.

    Parameters
    ----------
    premise : CoprimePremise
    bound : float
        The radius of the family the certificate is a theorem about, ``(1 + margin)·ε``.

    Returns
    -------
    str
        ``''`` when the regions reach no further than ``bound`` (or nothing was estimated); otherwise the
        statement, with the numbers and the fix.

    Examples
    --------
    >>> F = CoprimeFactors(N=np.array([[[0.0]], [[0.1]]]), M=np.array([[[1.0]], [[-0.5]]]), dt=1.0)
    >>> est = LowBandEstimate(frequency=np.array([0.01, 0.02]), response=np.array([0.1, 0.05]),
    ...                       radius=np.array([0.05, 0.02]), confidence=0.99, window=16, degree=2, samples=600, dt=1.0)
    >>> p = CoprimePremise(factors=F, in_sample=None, held_out=None, epsilon=0.05, decided_by="held out",
    ...                    inconsistency=0.5, reason="", error_frf=None, error_low_band=est)
    >>> unconfirmed_coprime_premise(p, 0.0625)[:60]
    'the data do not confirm the premise of the coprime-factor ce'
    >>> unconfirmed_coprime_premise(p, 0.2)
    ''
    """
    check_instance(premise, CoprimePremise, "premise", "a CoprimePremise (RobustDesignResult.coprime)")
    bound = check_nonnegative(bound, "bound ((1 + margin)·ε of the certificate)")
    upper, where = _region_reach(getattr(premise, "error_frf", None), getattr(premise, "error_low_band", None))
    if not upper > bound:
        return ""
    est = premise.error_frf if premise.error_frf is not None else premise.error_low_band
    return (f"the data do not confirm the premise of the coprime-factor certificate, the plant within "
            f"(1 + margin)·ε = {bound:.4g} of P̂'s factors: their {est.confidence:.0%} confidence regions of the "
            f"equation error's response M̂P − N̂ (a perturbation of N̂ that reaches the plant) reach {upper:.3g} "
            f"({_times(upper, bound)} that) at {where:.3g} {_unit(est.dt)}; the plant is assumed inside the family "
            "there (the loop's own test against those regions, the excitation check, refuses on evidence only, and a "
            "model error slower than the record shows is not seen); a longer record or a larger input amplitude "
            "narrows the regions, and a higher horizon lowers a slow error of P̂ itself")
