"""
Uncertainty-model unfalsification and the §7.4 robust design (thesis Ch. 7)
===========================================================================

The smallest uncertainty bound not falsified by input/output data, as convex programs that certify their
own answers (cvxpy with Clarabel, passed explicitly, or a structured barrier solver that exploits the
Toeplitz structure), and the §7.4 pipeline from that bound δ to a robust Theorem 3.7 controller whose
implemented loop is certified. The method, the two corrections to the thesis's §7.4 and the certificate
are explained in ``docs/UNFALSIFICATION.md`` of the source tree.

The front ends below validate the data, build the program (``ArxProblem``, ``SubspaceProblem``), hand it
to a solver of the registry :data:`unfalsify.solvers.SOLVERS` (``backend=`` and ``method=`` name one)
and build the certificate from its answer.  The solvers, the Toeplitz toolkit they share and the one
barrier skeleton live in :mod:`unfalsify.solvers`; the exceptions and warnings in :mod:`unfalsify.exceptions`.

Several inputs and outputs: ``unfalsified_gain`` and ``subspace_unfalsify`` take u of shape
(n, m) and y of shape (n, l), time along axis 0.  Δ is then an l × m causal LTI operator, its first n
Markov parameters h (n, l, m) enter the data relation linearly, and ``‖T(h)‖₂`` of the nl × nm block
lower-triangular Toeplitz matrix is the least H∞ norm with those Markov parameters (matrix
Carathéodory–Fejér); (7.5) has one l × m operator per column of ``U_f`` and ``‖Ξ‖_F ≤ σ√(ilj)``.  With
several channels (7.5) runs in the conditioned form on both backends, cvxpy and ``backend="structured"``
(the solver ``block_barrier``; ``executor=`` raises :class:`UnknownSolverError` naming ``backend="cvxpy"``),
and both return the same two-sided certificate (the MIMO dual bound is derived in
:class:`unfalsify.solvers.columns.BlockColumnForm`).
``arx_unfalsify`` (multi-output equation error, one Frobenius noise ball), ``robust_design_from_data`` and
the premise tests (H1 Welch estimate with a spectral-norm radius, local polynomial method, the excitation
test by σ̄) take several channels too; every norm is then the largest singular value.  One channel each
runs the SISO code unchanged.

Theorem 7.1
-----------

   unfalsified_gain       -- smallest γ such that an LTI Δ with ‖Δ‖∞ ≤ γ maps u to y on the window (u (n, m), y (n, l))
   unfalsified_gain_result -- the same with ``h = T(u)⁻¹y`` and cond T(u)
   GainResult             -- result of ``unfalsified_gain_result``
   is_unfalsified         -- whether the data do not falsify "y = Δu with ‖Δ‖∞ ≤ gamma"

ARX uncertainty model (7.4)
---------------------------

   arx_unfalsify          -- smallest ‖Δ‖∞ unfalsifying the ARX model (7.3) with ‖ξ‖_rms ≤ σ
   ArxResult              -- result of ``arx_unfalsify`` (δ, status, certificate, the cvxpy problem)
   ArxProblem             -- program (7.4) on given data: validation, scaling, independent bounds
   arx_least_squares      -- classical ARX (7.2) and the rms of its residual
   arx_regressor          -- the regressor ``(Φ, Y)`` of §7.2.1

Subspace uncertainty model (7.5)
--------------------------------

   subspace_unfalsify     -- smallest δ bounding the column operators Δ_k (L optimised, or ``predictor=`` fixed; l × m Δ_k)
   SubspaceResult         -- result of ``subspace_unfalsify``
   SubspaceProblem        -- program (7.5) on given data: validation, scaling, the fixed predictor, bounds
   subspace_data          -- ``(A, U_f, Y_f)`` of a window, ``A = [U_p; Y_p; U_f]``
   split_solve            -- (7.5) with a fixed predictor split by columns over an ``Executor``

Certificates and Toeplitz helpers
---------------------------------

   Certificate            -- two-sided bracket ``lower ≤ δ ≤ upper`` of an answer, ``verify()`` from the data
   BACKENDS               -- the solver backends, ``("cvxpy", "structured")``, resolved by :mod:`unfalsify.solvers`
   SOLVERS                -- the solver registry: name → ``solve(problem, **options) -> SolverOutput``
   SolverOutput           -- what every registered solver returns (δ, primal and dual point, status, in data units)
   SolverStatus           -- how a solve ended, shared by all solvers (a ``str`` enum: ``"optimal"``, …)
   COND_WARN              -- cond T(u) above which ``IllConditionedWarning`` is raised (1e8)
   toeplitz_matrix        -- dense lower-triangular Toeplitz matrix T(x)
   toeplitz_norm          -- spectral norm ‖T(h)‖₂
   toeplitz_cond          -- condition number of T(u)
   deconvolve             -- solve ``T(u) h = y``
   minimal_extension      -- the next Markov parameters of the least-H∞-norm system with given first ones

Robust design from data (§7.4)
------------------------------

   robust_design_from_data -- δ by (7.5), a Theorem 3.7 design, searched until its shipped loop is certified
   RobustDesignResult     -- result: δ, the design, its controller, certificates, the search
   REFERENCE_COLUMNS      -- columns per regressor of the reference model's fit when its horizon comes from the record
   REFERENCE_HORIZON_CAP  -- the longest reference horizon chosen from the record (60)
   DesignSearch           -- the family of designs the search tries (γ ratios, W3 gains, causality, horizons)
   DesignOptions          -- the first design (γ ratio, W3 rule and margin, causal law)
   CertificateOptions     -- the loop certificate (margin, performance floor, reference model)
   EstimationOptions      -- how (7.5) is solved (form, backend, cvxpy solver)
   estimate_delta         -- step 1 alone: window checks and δ of (7.5)
   SearchRecord           -- one design tried by the search and why it failed
   additive_weight_fixed_point -- the W3 gain ``c = (1 + margin) δ γ(c)``
   solve_estimate         -- rough time and memory of a (7.5) solve, which subspace_unfalsify checks before solving
   arx_solve_estimate     -- the same for (7.4) by the cvxpy backend, which arx_unfalsify checks before solving
   predictor_model        -- the data-based model P̂: ARX model of the predictor's first block row

The certificate's premise, tested on the data
---------------------------------------------

   check_premise          -- δ of P̂'s output error (Thm 7.1) beside δ of (7.5), and P̂ against the data's frequency response
   PremiseTest            -- result of ``check_premise`` (``delta``, ``decided_by``, ``reason``)
   PremiseOptions         -- how the pipeline tests the premise (noise level, confidence, sizes, time limit)
   untested_premises      -- what the certificate assumes that the data cannot test (a two-level input: linearity)
   unconfirmed_premise    -- why the data's confidence regions of P − P̂ do not confirm a certificate's ball
   LEVEL_SPREAD           -- an input within this fraction of its levels' spacing of two levels takes two (0.1)
   operating_point_note   -- which channels of a record sit at an operating point (the models have no constant term)
   OFFSET_NOTE            -- a mean above this fraction of the standard deviation is named (0.1)
   glitch_note            -- which samples of y look like a sensor's glitches against P̂ (robust z of its output error)
   GLITCH_LEVEL           -- robust standard deviations beyond which an output-error sample is named (8)
   check_time_invariance  -- is the record that of one time-invariant plant? (Chow's test on ARX fits of its segments)
   InvarianceTest         -- result of ``check_time_invariance``
   TIME_INVARIANCE_LEVEL  -- the default level of ``check_time_invariance`` (1e-3)
   min_record_length      -- the shortest record ``check_time_invariance`` tests at its default order
   check_feedback         -- was the record taken under feedback? (the input's innovation against the output's)
   FeedbackTest           -- result of ``check_feedback``
   FEEDBACK_LEVEL         -- the level of ``check_feedback`` (1e-3)
   FEEDBACK_NOTED         -- the correlation from which feedback is stated in ``assumed`` (0.1)
   FEEDBACK_REFUSED       -- the correlation from which it refuses the certificate (0.5)
   FEEDTHROUGH_STATEMENT  -- what ``assumed`` says when the plant is declared to have a direct feedthrough
   clipped_outputs        -- which outputs of a record pile up at an extreme value (a clipped sensor), or ''
   CLIP_FRACTION          -- the fraction of samples at an extreme from which an output counts as clipped
   output_error_unfalsify -- smallest additive LTI uncertainty on P̂ explaining ``y − P̂u`` (Thm 7.1, two-sided)
   output_error_residual  -- ``y − P̂u`` with P̂ simulated from the measured past
   OutputErrorResult      -- result of ``output_error_unfalsify``
   frequency_response_estimate -- Welch estimate ``S_yu S_uu⁻¹`` with simultaneous confidence regions (σ̄ radius)
   FrequencyResponseEstimate -- result of ``frequency_response_estimate``
   leaked_bins            -- Welch bins whose estimate is the response elsewhere (window leakage from one side)
   low_band_estimate      -- response at the lowest DFT frequencies (local polynomial method), with regions
   LowBandEstimate        -- result of ``low_band_estimate``
   check_excitation       -- do the data determine the plant where the loop (P̂, K) is sensitive?
   ExcitationCheck        -- result of ``check_excitation``
   residual_line          -- the loop gain of the strongest narrow line in P̂'s output error over a whole record
   LINE_LOOP_GAIN         -- such a line refuses the loop from this loop gain on (0.2)
   hidden_line_gain       -- the loop gain of the largest line a record could hide below that test's threshold
   HIDDEN_LINE_LIMIT      -- from this hidden-line gain on a certificate states it assumes no such line
   EXCITATION_FLOOR       -- input power below this fraction of its peak: not excited (1e-3)

Coprime-factor uncertainty (finite for integrating plants)
----------------------------------------------------------

   coprime_factors        -- ``P̂ = M̂⁻¹N̂``: the FIR factors of the predictor's first block row
   CoprimeFactors         -- the factors, their response, equation error ``M̂y − N̂u`` and realisations
   coprime_unfalsify      -- smallest ‖[Δ_N Δ_M]‖∞ explaining the equation error (Thm 7.1 on w = [u; y], two-sided)
   CoprimeUnfalsification -- result of ``coprime_unfalsify``
   check_coprime_premise  -- ε in sample and held out, and the gap to the data's estimate of ``M̂P − N̂``
   CoprimePremise         -- result of ``check_coprime_premise``
   unconfirmed_coprime_premise -- why the data's regions of ``M̂P − N̂`` do not confirm a coprime certificate's family
   coprime_gap            -- pointwise least coprime perturbation a plant (or a confidence region) needs
   error_gap              -- its lower bound from an estimate of ``M̂P − N̂`` alone
   coprime_distance       -- a plant's largest pointwise coprime distance from the factors (a lower bound)
   coprime_channel        -- ``[C_y; I](M̂ − N̂C_y)⁻¹``, the map a coprime-factor perturbation sees

Loop certificate
----------------

   certify_loop           -- certify the loop (P̂, K) for additive (or, with ``factors=``, coprime-factor) uncertainty
   LoopCertificate        -- result of ``certify_loop``
   additive_robustness    -- nominal stability and a certified ‖K(I+PK)⁻¹‖∞ of a controller with inputs [r; y]
   AdditiveRobustness     -- result of ``additive_robustness``
   additive_channel       -- the transfer an additive plant perturbation sees (Fig. 3.5)
   closed_loop_ry         -- the noise-free closed loop r → y
   loop_parts             -- checked plant and controller parts of a loop
   step_metrics           -- unit-step metrics of a loop r → y
   StepMetrics            -- result of ``step_metrics``
   tracking_floors        -- the performance floor per output channel

Errors and warnings
-------------------

   UnfalsificationError   -- infeasible, unbounded or failed solve
   UnknownSolverError     -- a ``backend=``/``method=`` the solver registry does not know (lists the valid names)
   NotCertifiedError      -- ``require_certified=True`` and no design of the search certifies
   NotCertifiedWarning    -- the pipeline could not certify the loop it returns (with the reason)
   UntestedPremiseWarning -- the loop is certified on a premise the data cannot test (``result.assumed``)
   FewDataWarning         -- the (7.5) window has few columns for the predictor it estimates
   LongSolveWarning       -- the (7.5) solve is estimated to take long (with the estimate and the fix)
   IllConditionedWarning  -- cond T(u) > 1e8: the literal Chapter 7 quantities are meaningless
   NotAtRestWarning       -- a record that starts mid-motion where rest is assumed
   SolverWarning          -- the conic solver returned a status other than ``optimal``

Tour
----

Servo data (§5.4: 1/(s(s+1)) at 10 Hz, PRBS input, noise σ = 0.05 at the input and on the sensor).
Theorem 7.1 on a 30-sample window; noise is not a bounded causal Δ, so γ grows with the window:

>>> import numpy as np
>>> import synthesis as sy
>>> import unfalsify as uf
>>> from experiments import collect_data, prbs, servo
>>> P = servo()
>>> data = collect_data(P, prbs(1000, seed=0), process_noise=0.05, sensor_noise=0.05, seed=1)
>>> u, y = data.u[:, 0], data.y[:, 0]
>>> g = uf.unfalsified_gain_result(u[:30], y[:30])
>>> round(g.gamma), f"{g.cond_Tu:.1e}"
(104, '9.6e+03')

ARX (7.4): ``A(q)y − B(q)u = ξ + Δu`` with ‖ξ‖_rms ≤ σ, here σ = ½ the least-squares residual rms.
``form="conditioned"`` (default) solves the substitution ``e − ξ = T(u)h``; ``form="thesis"`` keeps the
literal LMIs. Every result carries ``status``, ``solve_time``, ``cond_Tu`` and a ``certificate``; a status
other than ``optimal`` warns, and δ is NaN when the solve failed:

>>> _, rms = uf.arx_least_squares(u[:30], y[:30], 2, 2)
>>> arx = uf.arx_unfalsify(u[:30], y[:30], 2, 2, 0.5 * rms)          # cvxpy + Clarabel
>>> round(arx.delta, 3), arx.status, bool(arx.certificate.max_violation < 1e-6)
(0.2, 'optimal', True)
>>> fast = uf.arx_unfalsify(u[:30], y[:30], 2, 2, 0.5 * rms, backend="structured", progress=False)
>>> c = fast.certificate                                           # lower ≤ δ_unf ≤ upper, both proven
>>> bool(c.lower_bound <= arx.delta * (1 + 1e-6)), bool(c.verify())
(True, True)

Subspace (7.5) for a fixed least-squares predictor (i = 20) on a j = 20 window: only this δ acts
additively on the predictor output as Theorem 3.7 assumes, so only it sizes the robust design
(``robust_design_from_data``; the README's quick start runs the whole pipeline):

>>> i, j = 20, 20
>>> pred = sy.fit_predictor(u, y, i)
>>> n = 2 * i + j - 1
>>> A, Uf, Yf = uf.subspace_data(u[:n], y[:n], i)
>>> rms_f = np.linalg.norm(Yf - np.hstack([pred.Lw, pred.Lu]) @ A) / np.sqrt(Yf.size)
>>> sub = uf.subspace_unfalsify(u[:n], y[:n], i, 0.5 * rms_f, predictor=pred, backend="structured", progress=False)
>>> round(sub.delta, 3), sub.status
(0.102, 'optimal')

Several channels: a 2 × 2 record (two independent PRBS inputs through a coupled plant, output noise);
(7.5) on the cvxpy backend with its two-sided certificate, and Theorem 7.1 on a short window:

>>> rng = np.random.default_rng(0)
>>> u2 = np.sign(rng.standard_normal((40, 2)))
>>> y2 = np.column_stack([0.5 * np.roll(u2[:, 0], 1) + 0.2 * np.roll(u2[:, 1], 1), 0.3 * np.roll(u2[:, 1], 1)])
>>> y2 += 0.05 * rng.standard_normal((40, 2))
>>> mimo = uf.subspace_unfalsify(u2, y2, 3, 0.02)
>>> mimo.impulses.shape, mimo.status, bool(mimo.certificate.verify()), bool(mimo.certificate.relative_gap < 1e-4)
((3, 2, 2, 35), 'optimal', True, True)
>>> fast = uf.subspace_unfalsify(u2, y2, 3, 0.02, backend="structured", progress=False)
>>> bool(abs(fast.delta - mimo.delta) <= 1e-5 * mimo.delta), bool(fast.certificate.verify())
(True, True)
>>> bool(uf.unfalsified_gain(u2[:20], y2[:20]) > 0)
True

The robustness of a loop on a plant, with a proven ‖K(I+PK)⁻¹‖∞ (here the nominal §5.4 design on the true
plant; its radius 1/‖K(I+PK)⁻¹‖∞ is far below this δ, which is why the pipeline searches):

>>> import control
>>> s = control.tf("s")
>>> W1 = sy.tustin(100 * (0.01 / 5) * (s + 5) / (s + 0.01), P.dt)
>>> W2 = sy.tustin(0.05 * (10 / 0.5) * (s + 0.5) / (s + 10), P.dt)
>>> rob = uf.additive_robustness(P, sy.hinf_design(pred, W1, W2, dt=P.dt).controller)
>>> rob.stable, round(rob.peak, 1), bool(sub.delta * rob.peak < 1)
(True, 13.7, False)
"""
from .exceptions import (FewDataWarning, IllConditionedWarning, LongSolveWarning, NotAtRestWarning, NotCertifiedError,
                         NotCertifiedWarning, SolverWarning, UnfalsificationError, UnknownSolverError,
                         UntestedPremiseWarning)
from ._common import BACKENDS, COND_WARN, Certificate
from .solvers import SOLVERS, SolverOutput, SolverStatus
from .solvers.toeplitz import deconvolve, toeplitz_cond, toeplitz_matrix, toeplitz_norm
from .solvers.extension import minimal_extension
from .arx import ArxProblem, ArxResult, arx_least_squares, arx_regressor, arx_unfalsify
from .gain import GainResult, is_unfalsified, unfalsified_gain, unfalsified_gain_result
from .subspace import SubspaceProblem, SubspaceResult, subspace_data, subspace_unfalsify
from .solvers.split import split_solve
from .model import predictor_model
from .certify import (AdditiveRobustness, LoopCertificate, StepMetrics, additive_channel, additive_robustness,
                      certify_loop, closed_loop_ry, coprime_channel, loop_parts, step_metrics, tracking_floors)
from .frequency_response import (EXCITATION_FLOOR, FrequencyResponseEstimate, LowBandEstimate,
                                 frequency_response_estimate, leaked_bins, low_band_estimate)
from .excitation import ExcitationCheck, check_excitation
from .premise import (
    LEVEL_SPREAD,
    LINE_LOOP_GAIN,
    HIDDEN_LINE_LIMIT,
    hidden_line_gain,
    GLITCH_LEVEL,
    OFFSET_NOTE,
    glitch_note,
    operating_point_note,
    OutputErrorResult,
    PremiseOptions,
    PremiseTest,
    check_premise,
    output_error_residual,
    output_error_unfalsify,
    residual_line,
    unconfirmed_premise,
    untested_premises,
)
from .coprime import (CoprimeFactors, CoprimePremise, CoprimeUnfalsification, check_coprime_premise, coprime_distance,
                      coprime_factors, coprime_gap, coprime_unfalsify, error_gap, unconfirmed_coprime_premise)
from .options import CertificateOptions, DesignOptions, DesignSearch, EstimationOptions
from .robust import RobustDesignResult, estimate_delta, robust_design_from_data
from .search import REFERENCE_COLUMNS, REFERENCE_HORIZON_CAP, SearchRecord, additive_weight_fixed_point
from .cost import arx_solve_estimate, solve_estimate
from .clipping import CLIP_FRACTION, clipped_outputs
from .feedback import (FEEDBACK_LEVEL, FEEDBACK_NOTED, FEEDBACK_REFUSED, FEEDTHROUGH_STATEMENT, FeedbackTest,
                       check_feedback)
from .invariance import TIME_INVARIANCE_LEVEL, InvarianceTest, check_time_invariance, min_record_length

__all__ = [
    "BACKENDS",
    "COND_WARN",
    "Certificate",
    "IllConditionedWarning",
    "NotAtRestWarning",
    "SolverWarning",
    "UnfalsificationError",
    "UnknownSolverError",
    "SOLVERS",
    "SolverOutput",
    "SolverStatus",
    "deconvolve",
    "toeplitz_cond",
    "toeplitz_matrix",
    "toeplitz_norm",
    "minimal_extension",
    "ArxProblem",
    "ArxResult",
    "arx_least_squares",
    "arx_regressor",
    "arx_unfalsify",
    "GainResult",
    "is_unfalsified",
    "unfalsified_gain",
    "unfalsified_gain_result",
    "SubspaceProblem",
    "SubspaceResult",
    "subspace_data",
    "subspace_unfalsify",
    "split_solve",
    "predictor_model",
    "LoopCertificate",
    "StepMetrics",
    "certify_loop",
    "closed_loop_ry",
    "coprime_channel",
    "loop_parts",
    "step_metrics",
    "tracking_floors",
    "EXCITATION_FLOOR",
    "LEVEL_SPREAD",
    "LINE_LOOP_GAIN",
    "HIDDEN_LINE_LIMIT",
    "hidden_line_gain",
    "OFFSET_NOTE",
    "operating_point_note",
    "GLITCH_LEVEL",
    "glitch_note",
    "ExcitationCheck",
    "FrequencyResponseEstimate",
    "LowBandEstimate",
    "OutputErrorResult",
    "PremiseOptions",
    "PremiseTest",
    "check_excitation",
    "residual_line",
    "check_premise",
    "unconfirmed_premise",
    "frequency_response_estimate",
    "leaked_bins",
    "low_band_estimate",
    "output_error_residual",
    "output_error_unfalsify",
    "untested_premises",
    "CoprimeFactors",
    "CoprimePremise",
    "CoprimeUnfalsification",
    "check_coprime_premise",
    "coprime_distance",
    "coprime_factors",
    "coprime_gap",
    "coprime_unfalsify",
    "unconfirmed_coprime_premise",
    "error_gap",
    "AdditiveRobustness",
    "DesignSearch",
    "FewDataWarning",
    "LongSolveWarning",
    "solve_estimate",
    "arx_solve_estimate",
    "check_time_invariance",
    "check_feedback",
    "clipped_outputs",
    "CLIP_FRACTION",
    "FeedbackTest",
    "FEEDTHROUGH_STATEMENT",
    "FEEDBACK_LEVEL",
    "FEEDBACK_NOTED",
    "FEEDBACK_REFUSED",
    "min_record_length",
    "InvarianceTest",
    "TIME_INVARIANCE_LEVEL",
    "NotCertifiedError",
    "NotCertifiedWarning",
    "UntestedPremiseWarning",
    "RobustDesignResult",
    "SearchRecord",
    "additive_channel",
    "additive_robustness",
    "additive_weight_fixed_point",
    "robust_design_from_data",
    "REFERENCE_COLUMNS",
    "REFERENCE_HORIZON_CAP",
    "DesignOptions",
    "CertificateOptions",
    "EstimationOptions",
    "estimate_delta",
]

from synthesis import __version__  # noqa: E402 - one distribution, one version
