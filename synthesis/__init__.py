"""
Model-free subspace based H∞ synthesis (thesis Ch. 2–5)
=======================================================

Controllers designed directly from input/output data: the least-squares subspace predictor (Ch. 2),
finite-horizon H∞ and LQG laws computed from it by one minimax engine (Ch. 3–4), their LTI, receding-horizon
and adaptive implementations (Ch. 5), model-based comparators and a certified discrete H∞ norm. Equation
numbers are the thesis's. Conventions: time along axis 0 (``u`` is ``(n,)`` or ``(n, m)``); weights and
controllers are python-control discrete systems sharing the data's sample time; results are frozen
dataclasses; bad input raises a ``ValueError`` subclass that names the problem and the fix.

Subspace predictor (Ch. 2)
--------------------------

   fit_predictor          -- least-squares predictor ``ŷ = Lw w_p + Lu u_f`` (2.5)–(2.6) from ``(u, y)``
   Predictor              -- a fitted predictor: ``Lw``, ``Lu``, ranks, ``past_vector``, ``predict``
   RecursivePredictor     -- predictor under data updates and (sliding ``window``) downdates, §2.3.1
   block_hankel           -- block Hankel matrix (2.1)–(2.4)
   hankel_gram            -- ``AAᵀ`` of the Hankel data by the recursions (2.8)–(2.9), never forming ``A``
   hankel_order           -- row permutation from the interleaved Hankel data to ``[U_p; Y_p; U_f; Y_f]``
   default_rcond          -- default relative tolerance of the pseudo-inverse of §2.2
   cholupdate             -- rank-1 Cholesky update (§2.3.1)
   choldowndate           -- rank-1 Cholesky downdate (§2.3.1)

Weights (§3, §5.4)
------------------

   makeweight             -- first-order discrete weight from DC gain, a crossover and HF gain (MATLAB's ``makeweight``)
   tustin                 -- discretise a continuous-time weight by the bilinear transform
   as_weight              -- check a weighting filter and return it as a discrete ``StateSpace``
   common_dt              -- the one sample time shared by the dynamic weights
   diagonal_weight        -- a diagonal weight for several channels from SISO weights
   is_zero_weight         -- whether a weight's transfer function is identically zero
   markov_toeplitz        -- block Toeplitz matrix of Markov parameters (3.10)/(3.11), from (A, B, C, D)
   observability          -- extended observability matrix (3.12)

H∞ and LQG laws (Ch. 3–4)
-------------------------

   gamma_min              -- best achievable level γ_min: (3.8), causal (3.41), multiplicative (3.46), additive (3.64)
   hinf_design            -- central H∞ design (Thms 3.1, 3.2, 3.4, 3.7) and its LTI controller (5.3)–(5.4)
   HinfDesign             -- result of ``hinf_design``
   Multiplicative         -- output multiplicative uncertainty ``(I + W4 Δ W3)`` (Fig. 3.4, Thm 3.4)
   Additive               -- additive uncertainty ``W4 Δ W3`` on the predictor output (Fig. 3.5, Thm 3.7)
   performance_map        -- the performance map ``z = M_d d + M_u u + M_x x`` of a law
   PerformanceMap         -- result of ``performance_map``
   lqg_design             -- subspace LQG law (4.2), Thm 4.1, and its LTI controller
   LqgDesign              -- result of ``lqg_design``

Minimax engine (Ch. 3)
----------------------

   solve_minimax          -- saddle-point gains of the game (3.31) at a level ``gamma > γ_min``
   minimax_gamma_min      -- exact threshold ``γ_min = ‖(I − P_u) M_d‖₂`` of (3.29)
   feasibility_threshold  -- smallest level the engine accepts, ``γ_min`` plus a rounding margin
   MinimaxSolution        -- result of ``solve_minimax``
   NEAR_GAMMA_MIN_RATIO   -- 1.03: levels below this multiple of γ_min warn

Controllers (Ch. 5)
-------------------

   lti_controller         -- the LTI controller (5.3)–(5.4) of a design (inputs ``[r; y]``, output ``u``)
   RecedingHorizonController -- the step-by-step loop of §5.1: ``control(r_k)``, ``observe(u_k, y_k, r_k)``
   WeightState            -- a weight filter state run inside the controller
   AdaptiveHinf           -- adaptive controller of Fig. 5.1 (recursive predictor, redesign every update)
   AdaptiveUpdate         -- one design swapped into the adaptive controller
   GammaPolicy            -- rule choosing γ from the latest γ_min (§5.3)

Model-based comparators (§4.2, §6.2)
------------------------------------

   generalized_plant      -- the §4.2.1 generalized plant of a discrete plant and weights
   GeneralizedPlant       -- result of ``generalized_plant``
   hinf_riccati           -- model-based finite-horizon full-information H∞ law (4.15)–(4.19)
   lqr_riccati            -- model-based finite-horizon LQR (4.21)–(4.24)
   RiccatiLaw             -- result of ``hinf_riccati`` / ``lqr_riccati``
   discrete_mixsyn        -- discrete ∞-horizon mixed-sensitivity design ``min ‖[W1 S; W2 K S]‖∞``
   MixsynResult           -- result of ``discrete_mixsyn``
   mixsyn_closed_loop     -- the closed loop ``r → [W1 S r; W2 K S r]`` of an error-feedback controller
   peak_gain              -- dense-grid estimate of an H∞ norm (a lower bound, kept for comparison)

Identify-then-design baselines and the horizon from data
--------------------------------------------------------

   subspace_id            -- state-space model from the SVD of the predictor's ``L_w W_p`` (N4SID/MOESP style)
   SubspaceModel          -- result of ``subspace_id``: model, order and the order criterion's scores
   arx_id                 -- least-squares SISO ARX model, order by AIC, hold-out output error or given
   ArxModel               -- result of ``arx_id``
   choose_horizon         -- the prediction horizon ``i`` chosen from the data by a stated rule, explained
   HorizonChoice          -- result of ``choose_horizon``: ``horizon``, ``reason``, the design, every candidate
   HorizonCandidate       -- one horizon tried by ``choose_horizon`` and its checks
   HorizonChoiceWarning   -- ``choose_horizon`` found no candidate passing its checks (a fallback design returned)

Certified H∞ norm
-----------------

   hinf_norm              -- bracket ``lower ≤ ‖G‖∞ ≤ upper`` of a discrete system, ``upper`` proven
   NormBracket            -- result of ``hinf_norm``
   norm_below             -- prove ``‖G‖∞ < gamma`` (truthy) or say why not
   NormTest               -- result of ``norm_below``
   bounded_real_certificate -- a second proof of ``‖G‖∞ < gamma``: a bounded-real (KYP) matrix ``P``
   BoundedRealCertificate -- result of ``bounded_real_certificate``, re-checkable by ``verify()``

Data helpers and saving
-----------------------

   estimate_noise         -- σ from the data: residual rms of the least-squares predictor, and how it was obtained
   NoiseEstimate          -- result of ``estimate_noise``
   record_fingerprint     -- hashes of a record's blocks: which samples of another record it holds (held-out checks)
   RecordFingerprint      -- result of ``record_fingerprint``, kept on a fitted ``Predictor``
   save_controller        -- write a controller to ``.npz`` or ``.mat`` (A, B, C, D, dt, signal names)
   load_controller        -- read it back as a ``control.StateSpace``
   read_variables         -- the variables of an ``.npz`` or ``.mat`` file (unreadable files named, with the fix)
   CONTROLLER_FORMATS     -- the file suffixes ``save_controller`` writes
   ControllerFileError    -- a controller file that cannot be written or read (the message names the fix)

Errors and warnings
-------------------

   DataError              -- invalid input data (shape, length, NaN/inf, too few samples, …)
   InputTypeError         -- an argument of the wrong type (also a ``TypeError``)
   WeightError            -- an unusable weighting filter (improper, continuous, wrong size or dt, NaN)
   InfeasibleGammaError   -- γ ≤ γ_min: the level-γ problem has no solution (3.29)
   StageSaddleError       -- a stage of the H∞ Riccati recursion (4.17) has no saddle point
   DowndateError          -- a Cholesky downdate is impossible
   PersistenceWarning     -- the input is not persistently exciting (rank-deficient data)
   OrderWarning           -- ``subspace_id``'s order criterion chose its largest order: the order may be capped
   RefactorWarning        -- a downdate lost definiteness; the factor was recomputed from the window
   NearGammaMinWarning    -- γ < 1.03 γ_min: huge gains
   HorizonWarning         -- the data show no effect of the control over the horizon (``i`` ≤ the plant's delay)

The errors and warnings live in ``synthesis.exceptions``.

Building blocks for the packages on synthesis (``unfalsify``, ``experiments``)
------------------------------------------------------------------------------

   result                 -- class decorator of the frozen result dataclasses (short repr, equality, pickling)
   as_real_array          -- an array of real numbers of any shape (text, complex, None refused), or a ``DataError``
   as_signal              -- a signal as a float array ``(n, k)``, time along axis 0, or a ``DataError``
   as_discrete_system     -- a discrete-time python-control system, or a ``DataError`` naming the fix
   check_horizon          -- a prediction horizon i checked against the number of samples
   check_sample_time      -- a sample time checked (positive, finite, or ``True``)
   check_same_dt          -- two systems checked for one sample time
   check_flag             -- a True/False option checked (a string such as "no" is refused, not read as True)
   check_count            -- a count (an integer ≥ a least value) checked (a float or a bool is refused, not rounded)
   check_level            -- a number > a least value (a level γ, a ratio, a tolerance) checked
   check_nonnegative      -- a finite number ≥ 0 checked (NaN, a string or a bool is refused)
   check_predictor_dt     -- a design's sample time checked against the predictor's
   check_instance         -- an argument of the expected type, or ``InputTypeError`` naming it
   check_inputs_move      -- every input channel moves (one of zeros is refused: the record holds no response to it)
   check_output_moves     -- every output channel moves (a constant one is refused: a wrong column, a dead sensor)

Also in ``synthesis.results`` and ``synthesis.validation``.

Former routes kept as measured references
-----------------------------------------

``synthesis.baselines`` (not imported here: ``from synthesis import baselines``) gives the routes the fast
paths replaced, and the pieces of one adaptive redesign, public names for the benchmarks that time them
(``experiments/bench/``); ``help(synthesis.baselines)`` lists them.

Tour
----

``fit_predictor(u, y, i)`` fits the predictor from ``u: (n,) | (n, m)`` and ``y: (n,) | (n, l)``
(``j = n − 2i + 1`` columns). The default ``method="cholesky"`` builds ``AAᵀ`` with the Hankel recursions
(2.8)–(2.9) in ``O(ij + i²)`` time and ``O(i² + j)`` memory (the Hankel matrices are never formed);
``"qr"`` is the QR/SVD route (2.7) of §2.2, ``"lstsq"`` a plain numpy reference. Rank-deficient data give
the minimum-norm predictor, its numerical ``rank``/``input_rank``, and a ``PersistenceWarning``. On an FIR
plant the first column of ``Lu`` holds its Markov parameters (2.10):

>>> import numpy as np
>>> import synthesis as sy
>>> rng = np.random.default_rng(0)
>>> n, i = 2000, 10
>>> u = rng.standard_normal(n)
>>> y = np.convolve(u, [0.0, 0.5, 0.3, 0.1])[:n] + 0.02 * rng.standard_normal(n)
>>> pred = sy.fit_predictor(u, y, i)                  # method="cholesky" (default), "qr", "lstsq"
>>> pred.Lw.shape, pred.Lu.shape, pred.rank, pred.input_rank
((10, 20), (10, 10), 30, 20)
>>> print(np.round(pred.Lu[1:4, 0], 2))
[0.5 0.3 0.1]

Predictions: ``w_p = [u_{k−i} … u_{k−1}; y_{k−i} … y_{k−1}]`` (3.13) is the past, ``predict`` returns
``y_k … y_{k+i−1}`` (2.6), here within the noise level:

>>> k = 1500
>>> y_hat = pred.predict(pred.past_vector(u[:k], y[:k]), u[k:k + i])
>>> y_hat.shape, bool(np.abs(y_hat[:, 0] - y[k:k + i]).max() < 0.1)
((10, 1), True)

``RecursivePredictor`` adds (and, with a sliding ``window``, removes) data in ``O(i²)`` per sample
(§2.3.1); ``cholupdate``/``choldowndate`` are the rank-1 Cholesky update/downdate. It equals the batch
fit on the same window:

>>> rp = sy.RecursivePredictor.from_data(u[:500], y[:500], i, window=400)
>>> for t in range(500, n, 50):
...     _ = rp.push(u[t:t + 50], y[t:t + 50])         # §6.3: 50 new samples at a time
>>> ref = sy.fit_predictor(u[n - 400 - 2 * i + 1:], y[n - 400 - 2 * i + 1:], i)
>>> bool(np.abs(rp.predictor().Lu - ref.Lu).max() < 1e-10)
True

An H∞ design from data (§5.4, Table 5.1, Design 1: servo ``1/(s(s+1))`` at 10 Hz, PRBS input, noise
σ = 0.05 at the plant input and on the sensor; γ_min ≈ 0.88 in the thesis). ``hinf_design`` uses
γ = 1.1 γ_min by default, ``dt=`` checks the weights against the data, and the LTI controller has inputs
``[r; y]``, output ``u`` and order ``i(m+l)`` plus the weights' states:

>>> import control
>>> from scipy import signal
>>> dt, i = 0.1, 20
>>> Pd = control.c2d(control.tf([1], [1, 1, 0]), dt)
>>> rng = np.random.default_rng(3)
>>> n = 2 * i + 1000 - 1                                # j = 1000
>>> u = 2.0 * signal.max_len_seq(11, length=n)[0] - 1.0
>>> y = control.forced_response(Pd, U=u + 0.05 * rng.standard_normal(n)).outputs + 0.05 * rng.standard_normal(n)
>>> pred = sy.fit_predictor(u, y, i)
>>> s = control.tf("s")
>>> W1 = sy.tustin(100 * (0.01 / 5) * (s + 5) / (s + 0.01), dt)    # W11
>>> W2 = sy.tustin(0.05 * (10 / 0.5) * (s + 0.5) / (s + 10), dt)   # W21
>>> round(sy.gamma_min(pred, W1, W2), 2)
0.87
>>> design = sy.hinf_design(pred, W1, W2, dt=dt)
>>> round(design.gamma / design.gamma_min, 3), design.controller.nstates
(1.1, 42)

Other laws: ``hinf_design(pred, W1, W2, causal=True)`` (``r_k`` known, Thm 3.2),
``uncertainty=Multiplicative(W3, W4)`` / ``Additive(W3, W4)`` (Thms 3.4, 3.7), ``lqg_design(pred, Q, R)``
(Thm 4.1). ``RecedingHorizonController(design)`` runs the step-by-step loop of §5.1 (``control(r_k)`` /
``observe(u_k, y_k, r_k)``; ``r_k`` is required whenever W1 has states; ``set_design(new)`` for
adaptation); ``AdaptiveHinf`` with a ``GammaPolicy`` is §5.3. ``gamma ≤ γ_min`` raises
``InfeasibleGammaError`` (stating γ_min); ``gamma < 1.03 γ_min`` warns (``NearGammaMinWarning``).
The engine works on any performance map ``z = M_d d + M_u u + M_x x``; ``performance_map`` returns the one
of each law:

>>> pm = sy.performance_map(pred, W1, W2)
>>> bool(abs(sy.minimax_gamma_min(pm.Md, pm.Mu) - design.gamma_min) < 1e-9)
True
>>> sol = sy.solve_minimax(pm.Md, pm.Mu, pm.Mx, design.gamma)
>>> round(sol.gamma / sol.gamma_min, 3)
1.1
>>> sy.lqg_design(pred, 1.0, 0.1, dt=dt).controller.nstates
40

Certified norms: ``hinf_norm`` returns a bracket whose upper side is proven (the discrete bounded-real
pencil test), ``norm_below`` is truthy only with such a proof, and ``bounded_real_certificate`` proves
the same a second way, by a matrix ``P`` anyone can re-check (``verify()``):

>>> G = control.tf([1], [1, -0.5], 1.0)                # ‖G‖∞ = 2, at ω = 0
>>> b = sy.hinf_norm(G)
>>> bool(b.lower <= 2.0 <= b.upper), bool(sy.norm_below(G, 2.01)), bool(sy.norm_below(G, 1.99))
(True, True, False)
>>> bool(sy.bounded_real_certificate(G, 2.01))
True
"""
from importlib.metadata import PackageNotFoundError as _PackageNotFoundError
from importlib.metadata import version as _version

from .exceptions import DataError, HorizonChoiceWarning, InputTypeError
from .results import result
from .validation import (as_discrete_system, as_real_array, as_signal, check_count, check_flag, check_horizon,
                         check_inputs_move, check_instance, check_level, check_nonnegative, check_output_moves,
                         check_predictor_dt, check_same_dt, check_sample_time)
from .predictor import PersistenceWarning, Predictor, block_hankel, fit_predictor
from .predictor import default_rcond
from .hankel import hankel_gram, hankel_order
from .cholesky import DowndateError, choldowndate, cholupdate
from .recursive import RecursivePredictor, RefactorWarning
from .weights import (
    WeightError,
    as_weight,
    common_dt,
    diagonal_weight,
    is_zero_weight,
    makeweight,
    markov_toeplitz,
    observability,
    tustin,
)
from .minimax import (
    NEAR_GAMMA_MIN_RATIO,
    InfeasibleGammaError,
    MinimaxSolution,
    NearGammaMinWarning,
    feasibility_threshold,
    minimax_gamma_min,
    solve_minimax,
)
from .controller import RecedingHorizonController, WeightState, lti_controller
from .hinf import (Additive, HinfDesign, HorizonWarning, Multiplicative, PerformanceMap, gamma_min, hinf_design,
                   performance_map)
from .lqg import LqgDesign, lqg_design
from .riccati import GeneralizedPlant, RiccatiLaw, StageSaddleError, generalized_plant, hinf_riccati, lqr_riccati
from .hinfnorm import NormBracket, NormTest, hinf_norm, norm_below
from .bounded_real import BoundedRealCertificate, bounded_real_certificate
from .infinite_horizon import MixsynResult, discrete_mixsyn, mixsyn_closed_loop, peak_gain
from .adaptive import AdaptiveHinf, AdaptiveUpdate, GammaPolicy
from .noise import NoiseEstimate, estimate_noise
from .fingerprint import RecordFingerprint, record_fingerprint
from .export import CONTROLLER_FORMATS, ControllerFileError, load_controller, read_variables, save_controller
from .subspace_id import OrderWarning, SubspaceModel, subspace_id
from .arx_id import ArxModel, arx_id
from .horizon import HorizonCandidate, HorizonChoice, choose_horizon

__all__ = [
    "DataError",
    "InputTypeError",
    "PersistenceWarning",
    "OrderWarning",
    "Predictor",
    "block_hankel",
    "fit_predictor",
    "default_rcond",
    "hankel_gram",
    "cholupdate",
    "choldowndate",
    "DowndateError",
    "RecursivePredictor",
    "RefactorWarning",
    # weights, minimax engine, H∞ laws, controller implementations (Ch. 3, 5)
    "WeightError",
    "as_weight",
    "markov_toeplitz",
    "observability",
    "tustin",
    "InfeasibleGammaError",
    "MinimaxSolution",
    "NearGammaMinWarning",
    "HorizonWarning",
    "feasibility_threshold",
    "minimax_gamma_min",
    "solve_minimax",
    "RecedingHorizonController",
    "WeightState",
    "lti_controller",
    "Additive",
    "HinfDesign",
    "Multiplicative",
    "PerformanceMap",
    "gamma_min",
    "hinf_design",
    "performance_map",
    "LqgDesign",
    "lqg_design",
    # model-based comparators (§4.2)
    "GeneralizedPlant",
    "RiccatiLaw",
    "StageSaddleError",
    "generalized_plant",
    "hinf_riccati",
    "lqr_riccati",
    "MixsynResult",
    "discrete_mixsyn",
    "mixsyn_closed_loop",
    "peak_gain",
    # certified discrete H∞ norm
    "NormBracket",
    "NormTest",
    "hinf_norm",
    "norm_below",
    "BoundedRealCertificate",
    "bounded_real_certificate",
    "AdaptiveHinf",
    "AdaptiveUpdate",
    "GammaPolicy",
    # the engineer's choices: noise level, weights
    "NoiseEstimate",
    "RecordFingerprint",
    "record_fingerprint",
    "estimate_noise",
    "makeweight",
    "diagonal_weight",
    # controller files
    "ControllerFileError",
    "CONTROLLER_FORMATS",
    "save_controller",
    "load_controller",
    "read_variables",
    # module-level public helpers
    "hankel_order",
    "common_dt",
    "is_zero_weight",
    "NEAR_GAMMA_MIN_RATIO",
    # building blocks for the packages on synthesis
    "result",
    "as_real_array",
    "as_signal",
    "as_discrete_system",
    "check_horizon",
    "check_sample_time",
    "check_same_dt",
    "check_flag",
    "check_count",
    "check_level",
    "check_nonnegative",
    "check_predictor_dt",
    "check_instance",
    "check_inputs_move",
    "check_output_moves",
    # identify-then-design baselines and the horizon from data
    "SubspaceModel",
    "subspace_id",
    "ArxModel",
    "arx_id",
    "HorizonCandidate",
    "HorizonChoice",
    "HorizonChoiceWarning",
    "choose_horizon",
]

try:
    __version__ = _version("subspace-hinf")
except _PackageNotFoundError:  # a source tree that was never installed
    __version__ = "0+unknown"
