"""Model-free subspace based H∞ synthesis (thesis Ch. 2–5).

Subspace predictor (Ch. 2), finite-horizon minimax H∞/LQG laws (Ch. 3–4),
LTI / receding-horizon / adaptive implementations (Ch. 5) and model-based
comparators.
"""
from ._validation import DataError
from .predictor import PersistenceWarning, Predictor, block_hankel, fit_predictor

__all__ = [
    "DataError",
    "PersistenceWarning",
    "Predictor",
    "block_hankel",
    "fit_predictor",
]
