"""Weighting functions of thesis Ch. 6 (three-disk torsional plant, 64 Hz), chosen here.

The thesis gives the Ch. 6 weights only as Bode plots (Figs 6.3 and 6.8, lost in the OCR'd
text), so they are *chosen* to match what the text says about them and the γ values it reports:

§6.2, non-collocated (output ``y3``, Fig. 6.3)
    ``W1(s) = (s/2 + 20) / (s + 1) = 0.5 (s + 40)/(s + 1)``
        DC gain 20 (26 dB of rejection, "26 dB at DC" in the steady-state-error argument),
        high-frequency gain 0.5 (so ``|S| ≤ 2γ`` at high frequency), ``|W1(jω)| = 1`` at
        ω ≈ 23 rad/s: a design bandwidth "of nearly 20 rad/s", past the first resonance (15.85 rad/s).
    ``W2(s) = 0.05 (s + 1)/(s + 100)``
        A high-pass control weight: 5·10⁻⁴ at DC (control is free at low frequency), 0.05 above
        100 rad/s (limits high-frequency control effort, ``|K S| ≤ 20 γ`` there).
    With the ZOH model of ``P_{y3,u}`` at 64 Hz these give a discrete ∞-horizon model-based
    ``γ_opt = 2.264`` (thesis: 2.24; :func:`synthesis.infinite_horizon.discrete_mixsyn`).  A scan of
    the ``W1`` corner gave γ_opt ≈ 1.39 / 1.84 / 2.26 / 2.67 for ``wb`` = 10 / 15 / 20 / 25 rad/s.

§6.3, collocated (output ``y1``, Fig. 6.8)
    The collocated plant is much easier, so the same weights would give ``γ_opt ≈ 1.2``; the thesis
    reports ``γ_min ≈ 2.25`` in steady state, close to its ∞-horizon model-based value. We keep the
    same shapes and the same ``W2`` and raise the ``W1`` bandwidth until the ∞-horizon model-based
    ``γ_opt`` is about 2.25 (measured 2.232; ``wb`` = 52 / 55 / 58 gave 2.13 / 2.21 / 2.28):
    ``W1(s) = (s/2 + 56) / (s + 2.8) = 0.5 (s + 112)/(s + 2.8)``
        DC gain 20 (26 dB), high-frequency gain 0.5, ``|W1| = 1`` near 65 rad/s.
    ``W2(s) = 0.05 (s + 1)/(s + 100)`` (as in §6.2).

All weights are biproper (relative McMillan degree zero, §5.1 comment 3) and are discretised with
the Tustin transform at the sample rate (§6.2: "selected in continuous time, and discretized using
the Tustin transformation").
"""
from __future__ import annotations

from dataclasses import dataclass

import control as ct

from synthesis.validation import DataError

from .plants import THREE_DISK_DT

__all__ = ["WeightSpec", "NONCOLLOCATED", "COLLOCATED", "torsional_weights"]


@dataclass(frozen=True)
class WeightSpec:
    """First-order biproper weights ``W1 = (s/M + wb)/(s + wb·A)``, ``W2 = c (s + a)/(s + b)``.

    Attributes
    ----------
    wb : float
        ``W1`` corner (rad/s); ``|W1(jω)| = 1`` slightly above it.
    A : float
        ``1/|W1(0)|``: the DC sensitivity bound (``A = 1/20`` is 26 dB of rejection).
    M : float
        ``1/|W1(∞)|``: the high-frequency sensitivity bound.
    c, a, b : float
        ``W2 = c (s + a)/(s + b)``: high-frequency gain ``c``, DC gain ``c a / b``.
    label : str
        Where it is used.
    """

    wb: float
    A: float
    M: float
    c: float
    a: float
    b: float
    label: str

    def continuous(self) -> tuple[ct.TransferFunction, ct.TransferFunction]:
        """Continuous-time ``(W1, W2)`` as python-control transfer functions."""
        W1 = ct.tf([1.0 / self.M, self.wb], [1.0, self.wb * self.A])
        W2 = ct.tf([self.c, self.c * self.a], [1.0, self.b])
        return W1, W2

    def discrete(self, dt: float = THREE_DISK_DT) -> tuple[ct.StateSpace, ct.StateSpace]:
        """Tustin discretisations of ``(W1, W2)`` at sample time ``dt``, as state space."""
        W1, W2 = self.continuous()
        return _tustin(W1, dt), _tustin(W2, dt)

    def describe(self) -> str:
        """One-line human description (used in the reports)."""
        return (
            f"W1(s) = (s/{self.M:g} + {self.wb:g})/(s + {self.wb * self.A:g}) "
            f"(DC {1 / self.A:g}, HF {1 / self.M:g}); "
            f"W2(s) = {self.c:g}(s + {self.a:g})/(s + {self.b:g}); Tustin at 64 Hz"
        )


#: §6.2 weights (Fig. 6.3), non-collocated output y3.
NONCOLLOCATED = WeightSpec(wb=20.0, A=1 / 20, M=2.0, c=0.05, a=1.0, b=100.0, label="§6.2 (y3)")
#: §6.3 weights (Fig. 6.8), collocated output y1.
COLLOCATED = WeightSpec(wb=56.0, A=1 / 20, M=2.0, c=0.05, a=1.0, b=100.0, label="§6.3 (y1)")


def torsional_weights(kind: str, dt: float = THREE_DISK_DT) -> tuple[ct.StateSpace, ct.StateSpace]:
    """The Ch. 6 weights of one output of the three-disk plant, discretised by Tustin.

    Parameters
    ----------
    kind : {"noncollocated", "collocated"}
        ``"noncollocated"``: the §6.2 weights of output ``y3`` (:data:`NONCOLLOCATED`); ``"collocated"``: the
        §6.3 weights of output ``y1`` (:data:`COLLOCATED`).
    dt : float, optional
        Sample time (s); default the plant's 1/64 s (:data:`experiments.THREE_DISK_DT`).

    Returns
    -------
    W1, W2 : control.StateSpace
        Discrete performance and control weights.

    Raises
    ------
    ValueError
        Unknown ``kind`` (the message lists the valid ones).

    Examples
    --------
    >>> from experiments.lab import torsional_weights
    >>> W1, W2 = torsional_weights("noncollocated")
    >>> W1.dt, round(float(abs(W1(1.0))), 6)  # |W1| at DC: 20 (26 dB of rejection)
    (0.015625, 20.0)
    """
    specs = {"noncollocated": NONCOLLOCATED, "collocated": COLLOCATED}
    if kind not in specs:
        raise DataError(f"unknown weight set {kind!r}; use one of {sorted(specs)}")
    return specs[kind].discrete(dt)


def _tustin(sys_c, dt: float) -> ct.StateSpace:
    try:  # the toolkit's own helper when present (validates biproperness)
        from synthesis.weights import tustin
    except ImportError:  # pragma: no cover - before synthesis.weights exists
        return ct.ss(ct.c2d(ct.ss(sys_c), dt, method="tustin"))
    return ct.ss(tustin(sys_c, dt))
