"""Uncertainty-model unfalsification as cvxpy LMI models (thesis Ch. 7).

* :func:`unfalsified_gain` -- Theorem 7.1 (smallest H∞ gain explaining SISO data);
* :func:`arx_unfalsify` -- ARX uncertainty model, program (7.4);
* :func:`subspace_unfalsify` -- subspace uncertainty model, program (7.5) (``executor=``: split by columns,
  :func:`split_solve`);
* :func:`robust_design_from_data` -- §7.4 steps 1–5 (δ → additive-uncertainty H∞ design).
"""
from ._common import BACKENDS, COND_WARN, Certificate, IllConditionedWarning, NotAtRestWarning, SolverWarning, UnfalsificationError
from ._toeplitz import deconvolve, toeplitz_cond, toeplitz_matrix, toeplitz_norm
from .arx import ArxProblem, ArxResult, arx_least_squares, arx_regressor, arx_unfalsify
from .gain import GainResult, is_unfalsified, unfalsified_gain, unfalsified_gain_result
from .subspace import SubspaceProblem, SubspaceResult, subspace_data, subspace_unfalsify
from .split import split_solve
from .model import predictor_model
from .certify import LoopCertificate, StepMetrics, certify_loop, closed_loop_ry, loop_parts, step_metrics
from .robust import (
    AdditiveRobustness,
    DesignSearch,
    FewDataWarning,
    NotCertifiedError,
    NotCertifiedWarning,
    RobustDesignResult,
    SearchRecord,
    additive_channel,
    additive_robustness,
    additive_weight_fixed_point,
    robust_design_from_data,
)

__all__ = [
    "BACKENDS",
    "COND_WARN",
    "Certificate",
    "IllConditionedWarning",
    "NotAtRestWarning",
    "SolverWarning",
    "UnfalsificationError",
    "deconvolve",
    "toeplitz_cond",
    "toeplitz_matrix",
    "toeplitz_norm",
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
    "loop_parts",
    "step_metrics",
    "AdditiveRobustness",
    "DesignSearch",
    "FewDataWarning",
    "NotCertifiedError",
    "NotCertifiedWarning",
    "RobustDesignResult",
    "SearchRecord",
    "additive_channel",
    "additive_robustness",
    "additive_weight_fixed_point",
    "robust_design_from_data",
]

from synthesis import __version__  # noqa: E402 - one distribution, one version
