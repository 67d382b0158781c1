"""Plants, signals, simulations and the thesis experiments (Ch. 5–7)."""

__all__: list[str] = []
