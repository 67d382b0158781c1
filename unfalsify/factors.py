"""``P̂ = M̂⁻¹N̂``: the left coprime factors of the data-based model, read off the predictor's first block row.

The predictor's first block row is an ARX model (:mod:`unfalsify.model`),

    y_k + Σ_{d=1..i} M_d y_{k−d} = Σ_{d=0..i} N_d u_{k−d},

with the FIR polynomial matrices ``M̂(q) = I + Σ M_d q^{−d}`` and ``N̂(q) = Σ N_d q^{−d}``.  The uncertainty these
factors carry, and the tests on it, are in :mod:`unfalsify.coprime`; the object itself is here, apart, so that the
premise tests (:mod:`unfalsify.premise`), which :mod:`unfalsify.coprime` builds on, can use its equation error too.
"""
from __future__ import annotations

from dataclasses import dataclass

import control
import numpy as np

from synthesis.results import result
from synthesis.validation import DataError, check_instance, check_sample_time

from ._common import channel_pair
from .model import _delay_line, predictor_model

__all__ = ["CoprimeFactors", "coprime_factors"]


@result
@dataclass(frozen=True, eq=False)
class CoprimeFactors:
    """``P̂ = M̂⁻¹N̂``: the FIR polynomial matrices of the predictor's first block row (module docstring).

    Attributes
    ----------
    N : ndarray, shape (i + 1, l, m)
        ``N̂(q) = Σ_d N[d] q^{−d}``.
    M : ndarray, shape (i + 1, l, l)
        ``M̂(q) = Σ_d M[d] q^{−d}``, ``M[0] = I``.
    dt : float or True
        Sample time (True: unspecified, as python-control's ``dt=True``).
    """

    N: np.ndarray
    M: np.ndarray
    dt: float

    def __post_init__(self):
        # the realisations (model, equation) read M[0] = I and degree ≥ 1 without looking: check them here, so that
        # hand-made factors cannot give a silently wrong P̂
        N, M = _taps(self.N, "N"), _taps(self.M, "M")
        if N.ndim != 3 or M.ndim != 3 or M.shape[1] != M.shape[2] or N.shape[:2] != M.shape[:2]:
            raise DataError(f"coprime factors need N of shape (i + 1, l, m) and M of shape (i + 1, l, l), got "
                            f"{np.shape(self.N)} and {np.shape(self.M)}")
        if N.shape[0] < 2:
            raise DataError("coprime factors need degree i ≥ 1 (at least two taps); pad a static factor with a zero "
                            "tap, e.g. N = np.concatenate([N, np.zeros_like(N)])")
        if not (np.all(np.isfinite(N)) and np.all(np.isfinite(M))):
            raise DataError("coprime factors have NaN or infinite taps")
        if not np.allclose(M[0], np.eye(M.shape[1]), rtol=0.0, atol=1e-12):
            raise DataError(f"coprime factors need M[0] = I (M̂(∞) = I), got M[0] = {M[0].tolist()}; divide both "
                            "factors on the left by M[0]")
        object.__setattr__(self, "N", N)
        object.__setattr__(self, "M", M)
        # True (unspecified) is kept, as python-control keeps it: float(True) = 1.0 would claim a sample time of 1
        object.__setattr__(self, "dt", check_sample_time(self.dt, "dt"))

    @property
    def horizon(self) -> int:
        """``i``, the degree of the polynomials."""
        return int(self.N.shape[0] - 1)

    @property
    def inputs(self) -> int:
        return int(self.N.shape[2])

    @property
    def outputs(self) -> int:
        return int(self.N.shape[1])

    def response(self, omega) -> tuple[np.ndarray, np.ndarray]:
        """``(N̂, M̂)`` at ``z = e^{jω dt}``: arrays (F, l, m) and (F, l, l) for ``omega`` (F,) in rad/s."""
        w = np.atleast_1d(np.asarray(omega, float))
        powers = np.exp(-1j * np.outer(w * self.dt, np.arange(self.horizon + 1)))  # z^{−d}
        return np.einsum("fd,dab->fab", powers, self.N), np.einsum("fd,dab->fab", powers, self.M)

    def residual(self, u, y) -> np.ndarray:
        """The equation error ``e_k = Σ M_d y_{k−d} − Σ N_d u_{k−d}`` for ``k ≥ i``: (n − i,) or (n − i, l).

        Every sample uses measured data only (no simulation, no initial state to guess).
        """
        u, y = channel_pair(u, y)
        U, Y = u.reshape(u.shape[0], -1), y.reshape(y.shape[0], -1)
        if U.shape[1] != self.inputs or Y.shape[1] != self.outputs:
            raise DataError(f"the factors have {self.inputs} input(s) and {self.outputs} output(s), the data "
                            f"{U.shape[1]} and {Y.shape[1]}: pass the record of the channels P̂ was fitted on")
        i, n = self.horizon, U.shape[0]
        if n <= i:
            raise DataError(f"the record has {n} samples; the equation error needs more than i = {i}")
        e = np.zeros((n - i, self.outputs))
        for d in range(i + 1):
            e += Y[i - d: n - d] @ self.M[d].T - U[i - d: n - d] @ self.N[d].T
        return e[:, 0] if u.ndim == 1 else e

    def model(self) -> control.StateSpace:
        """``P̂ = M̂⁻¹N̂`` in the delay-line state (the same realisation as :func:`unfalsify.predictor_model`)."""
        C, D = self._row()
        return _delay_line(C, D, self.horizon, self.inputs, self.outputs, self.dt)

    def equation(self) -> control.StateSpace:
        """``M̂⁻¹ [N̂  I]``: inputs ``[u; v]``, output ``y``, one realisation (so ``v`` and ``u`` share P̂'s poles)."""
        C, D = self._row()
        return _delay_line(C, D, self.horizon, self.inputs, self.outputs, self.dt, disturbance=True)

    def _row(self) -> tuple[np.ndarray, np.ndarray]:
        """``(C, D)`` of ``y_k = C w_p(k) + D u_k``, ``w_p = [u_{k−i} … u_{k−1}; y_{k−i} … y_{k−1}]``."""
        i = self.horizon
        Cu = np.hstack([self.N[i - s] for s in range(i)])    # column block s multiplies u_{k−i+s}: lag i − s
        Cy = np.hstack([-self.M[i - s] for s in range(i)])
        return np.hstack([Cu, Cy]), np.asarray(self.N[0], float)


def _taps(x, name: str) -> np.ndarray:
    """The taps ``N`` or ``M`` of :class:`CoprimeFactors` as a real float array (DataError otherwise: a string had
    reached numpy's own conversion error, and a complex array would have lost its imaginary part silently)."""
    if np.iscomplexobj(x):
        raise DataError(f"coprime factors need real taps; {name} is complex")
    try:
        if np.asarray(x).dtype.kind in "US":  # numpy parses "0.5" as a number: text is refused, not read
            raise TypeError("text")
        return np.asarray(x, dtype=float)
    except (TypeError, ValueError) as exc:
        raise DataError(f"coprime factors need numeric taps: {name} must be an array of shape (i + 1, l, "
                        f"{'m' if name == 'N' else 'l'}), got {type(x).__name__} {x!r:.40}") from exc


def _factors(factors, name: str = "factors") -> CoprimeFactors:
    """``factors`` when it is a :class:`CoprimeFactors`, else InputTypeError naming where they come from."""
    return check_instance(factors, CoprimeFactors, name, "a CoprimeFactors (unfalsify.coprime_factors(pred, dt))")


def coprime_factors(pred, dt=None) -> CoprimeFactors:
    """The left coprime factors ``(N̂, M̂)`` of the predictor's first block row (module docstring).

    Parameters
    ----------
    pred : synthesis.Predictor
        ``Lw``, ``Lu``, ``horizon``, ``m``, ``l`` (as for :func:`unfalsify.predictor_model`).
    dt : float, optional
        The data's sample time.  Default: the predictor's (:attr:`synthesis.Predictor.dt`);
        required when it carries none, refused when it differs from the predictor's.

    Returns
    -------
    CoprimeFactors

    Examples
    --------
    An integrator ``y_k = y_{k−1} + 0.1 u_{k−1}``: ``M̂(q) = 1 − q⁻¹``, ``N̂(q) = 0.1 q⁻¹``, both FIR.

    >>> import numpy as np
    >>> import synthesis as sy
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(200)
    >>> y = np.concatenate([[0.0], np.cumsum(0.1 * u)[:-1]])
    >>> F = coprime_factors(sy.fit_predictor(u, y, 1), 1.0)
    >>> np.round(F.M[:, 0, 0], 6).tolist(), np.round(F.N[:, 0, 0], 6).tolist()
    ([1.0, -1.0], [0.0, 0.1])
    >>> bool(np.max(np.abs(F.residual(u, y))) < 1e-9)                    # the equation holds exactly
    True
    """
    return _model_factors(predictor_model(pred, dt), int(pred.horizon))  # validates the predictor and dt


def _model_factors(model, horizon: int) -> CoprimeFactors:
    """The factors of a model in the delay-line state of :func:`unfalsify.predictor_model` (horizon ``horizon``):
    read off its output row ``y_k = C w_p(k) + D u_k``."""
    i, m, l = int(horizon), int(model.ninputs), int(model.noutputs)
    C, D = np.asarray(model.C, float), np.asarray(model.D, float)
    N = np.zeros((i + 1, l, m))
    M = np.zeros((i + 1, l, l))
    N[0], M[0] = D, np.eye(l)
    for d in range(1, i + 1):
        s = i - d  # the column block of lag d
        N[d] = C[:, s * m:(s + 1) * m]
        M[d] = -C[:, i * m + s * l: i * m + (s + 1) * l]
    return CoprimeFactors(N=N, M=M, dt=model.dt)  # model.dt: a positive float, or True (unspecified)
