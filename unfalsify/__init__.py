"""Uncertainty-model unfalsification as cvxpy LMI models (thesis Ch. 7)."""

__all__: list[str] = []
