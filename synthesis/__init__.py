"""Model-free subspace based H∞ synthesis (thesis Ch. 2–5).

Subspace predictor (Ch. 2), finite-horizon minimax H∞/LQG laws (Ch. 3–4),
LTI / receding-horizon / adaptive implementations (Ch. 5) and model-based
comparators.
"""
from importlib.metadata import PackageNotFoundError as _PackageNotFoundError
from importlib.metadata import version as _version

from ._validation import DataError, InputTypeError
from .predictor import PersistenceWarning, Predictor, block_hankel, fit_predictor
from .predictor import default_rcond
from .hankel import hankel_gram, hankel_order
from .cholesky import DowndateError, choldowndate, cholupdate
from .recursive import RecursivePredictor, RefactorWarning
from .weights import (
    WeightError,
    as_weight,
    common_dt,
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
from .hinf import Additive, HinfDesign, Multiplicative, PerformanceMap, gamma_min, hinf_design, performance_map
from .lqg import LqgDesign, lqg_design
from .riccati import GeneralizedPlant, RiccatiLaw, StageSaddleError, generalized_plant, hinf_riccati, lqr_riccati
from .hinfnorm import NormBracket, NormTest, hinf_norm, norm_below
from .bounded_real import BoundedRealCertificate, bounded_real_certificate
from .infinite_horizon import MixsynResult, discrete_mixsyn, mixsyn_closed_loop, peak_gain
from .adaptive import AdaptiveHinf, AdaptiveUpdate, GammaPolicy
from .noise import NoiseEstimate, estimate_noise
from .export import CONTROLLER_FORMATS, ControllerFileError, load_controller, save_controller

__all__ = [
    "DataError",
    "InputTypeError",
    "PersistenceWarning",
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
    "estimate_noise",
    "makeweight",
    # controller files
    "ControllerFileError",
    "CONTROLLER_FORMATS",
    "save_controller",
    "load_controller",
    # module-level public helpers
    "hankel_order",
    "common_dt",
    "is_zero_weight",
    "NEAR_GAMMA_MIN_RATIO",
]

try:
    __version__ = _version("subspace-hinf")
except _PackageNotFoundError:  # a source tree that was never installed
    __version__ = "0+unknown"
