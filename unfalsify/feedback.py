"""Was the record taken under feedback?  The input's innovation against the output's, lag by lag.

The §7.4 certificate rests on P̂ and on a premise test that compares P̂ with held-out data.  Both assume open-loop
data: noise that does not reach the input.  Under feedback ``u = K(r − y)`` the output's noise enters the input, the
least-squares predictor is biased (towards ``−1/K`` where the noise dominates the reference's share of ``u``), and
held-out data from the same loop share the bias, so the premise test cannot see it.  Measured (a script: a
third-order plant under ``u = k(r − y)``, k = 0.5, 1, 3 and a PI controller, a ±1 PRBS reference of amplitude 0.05
or 0.2, white or AR(0.9) sensor noise of rms 0.2, seeds 0–2, both protocols of the adversarial catalogue): 27 of 84
runs certified, every one a loop unstable on the true plant, premise ratios ‖P − P̂‖∞/δ of 2.7–10.

The test (the classical check of residuals against future inputs): the output's innovation ``e`` (residual of an
ARX(p) fit of each output on the past of every output and input, with a constant) and the input's innovation ``ε``
(residual of an AR(p) fit of each input on the past of every input, with a constant) are cross-correlated at lags
``0 … M`` (``ε`` later than ``e``).  In open loop the input does not depend on the noise, so the normalised
correlations are ``N(0, 1/N)`` whenever ``e`` is white and ``Q = N Σ ρ(τ)²`` is χ²(M + 1); under feedback ``ε`` holds
the controller's response to ``e``.  One input–output pair: that p-value; several: the smallest times m·l.  The size
of the largest correlation says how much of the input's fresh variation is the output's noise fed back: ``|ρ|²`` is
that share of its variance (for a static controller at lag 0).

Measured with p = 16, M = 10 (a script): on the adversarial catalogue's 144 open-loop records (seeds 0–2) the
smallest p-value was 2.9e-5 (a low-band multisine, whose AR(16) residual is not white; ``|ρ| = 0.07``), every other
above 1e-3 and every ``|ρ|`` at most 0.11; on 138 open-loop records of the same hunt (AR(0.9), Student-t and
outlier noise, offsets, fractional delays, aliased modes, clipped outputs, gaps) none below 1e-3.  Closed loop: the
27 false certificates above (14 records) had ``|ρ|`` of 0.78–0.97 (p below 1e-150); the catalogue's closed loops with
a white PRBS reference (which dominates the input) gave p 0.1–0.8, ``|ρ| ≤ 0.11``, and their certified loops held;
with a low-pass reference ``|ρ| ≈ 0.65``.  Hence :data:`FEEDBACK_NOTED` (a premise stated in ``assumed``) and
:data:`FEEDBACK_REFUSED` (the certificate refused).

What the data cannot tell apart: a plant with a direct feedthrough (``y_k`` depends on ``u_k``) correlates the
innovations at lag 0 as a controller acting within the sample does (``u_k`` from ``y_k``): jointly, both records are
the same pair of correlated white sequences.  By default the plant is taken to be strictly proper (a sampled plant
whose output is measured before the input is applied) and lag 0 is tested.  ``feedthrough=True`` declares a direct
feedthrough: the output's ARX fit then includes ``u_k``, which absorbs the lag-0 correlation, and only lags ``1 … M``
are tested, so feedback within the sample goes unseen (the pipeline states that).  Measured (a script: the
first-order plant of the Examples with ``D`` added, open loop, a ±1 PRBS): by default ``|ρ|`` at lag 0 was 0.43 for
``D = 0.05``, 0.88 for 0.2 and 0.97 for 0.5, each a refusal or a statement of feedback that is not there.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.stats

from synthesis.results import result
from synthesis.validation import as_signal, check_flag, check_level

from .arx import arx_regressor

__all__ = ["FeedbackTest", "check_feedback", "FEEDBACK_LEVEL", "FEEDBACK_NOTED", "FEEDBACK_REFUSED",
           "FEEDTHROUGH_STATEMENT"]

#: p-values below it say the input depends on the output's noise (with ``|ρ|`` at least :data:`FEEDBACK_NOTED`).
FEEDBACK_LEVEL = 1e-3
#: Smallest ``|ρ|`` stated in ``assumed``: below it under 1 % of the input's fresh variance is the output's noise.
FEEDBACK_NOTED = 0.1
#: ``|ρ|`` from which the certificate is refused: a quarter or more of the input's fresh variance is the output's
#: noise fed back (the measured false certificates had 0.78 and more, the closed loops that held 0.11 or less).
FEEDBACK_REFUSED = 0.5
#: ARX / AR order of the innovations (as the time-invariance test: long enough to whiten an output-error plant's
#: equation error) and the number of lags after lag 0.
_ORDER, _LAGS = 16, 10
#: Rows per parameter of the ARX fit below which the test is not run.
_ROWS_PER_PARAMETER = 10
#: In ``assumed`` whenever the plant is declared to have a direct feedthrough: what lag 0 can then no longer show.
FEEDTHROUGH_STATEMENT = ("the plant has a direct feedthrough (declared): a controller acting within the sample (u_k "
                         "computed from y_k) correlates the record at lag 0 as the feedthrough does, so feedback there "
                         "is not tested; the certificate assumes the record has none (record in open loop, or with a "
                         "controller that acts a sample later)")
#: Said with every finding at lag 0 of a plant taken to be strictly proper: the other cause the data cannot exclude.
_LAG0_ALTERNATIVE = ("; at lag 0 a direct feedthrough of the plant (y_k responding to u_k) gives the same correlation "
                     "in open loop: if the plant has one, declare it (CertificateOptions(feedthrough=True), "
                     "check_feedback(..., feedthrough=True), or --feedthrough of python -m experiments design)")
#: at a lag ≥ 1 an open-loop record shows the same dependence when its input and output columns are swapped: the
#: recorded "input" is then the plant's response to the recorded "output" (measured: a lightly damped plant's record
#: with u and y exchanged was refused with the closed-loop statement alone, which sent the user to the wrong fix)
_SWAP_ALTERNATIVE = ("; in an open-loop record the same dependence can also mean that the input and output columns "
                     "are swapped (the column taken as the input responds to the one taken as the output): check "
                     "which is which (u= and y=, or --u and --y of python -m experiments design)")


@result
@dataclass(frozen=True)
class FeedbackTest:
    """Result of :func:`check_feedback`.

    Attributes
    ----------
    p_value : float
        Probability of cross-correlations at least this large if the input does not depend on the output's noise
        (several channels: the smallest per-pair p-value times m·l, at most 1).
    correlation : float
        The largest correlation (signed) between the output's and the input's innovations, over the lags and pairs.
    lag : int
        Its lag (samples by which the input's innovation follows the output's).
    pair : tuple of int
        ``(input, output)`` of that correlation.
    order : int
        ARX / AR order of the innovations.
    level : float
    feedthrough : bool
        The plant was declared to have a direct feedthrough: lag 0 was not tested (module docstring).
    statement : str
        For ``RobustDesignResult.assumed`` when feedback is detected (``p < level`` and ``|correlation|`` at least
        :data:`FEEDBACK_NOTED`), else ``''``.
    reason : str
        Why the certificate is refused when ``|correlation|`` reaches :data:`FEEDBACK_REFUSED` with feedback
        detected, else ``''``.
    """

    p_value: float
    correlation: float
    lag: int
    pair: tuple
    order: int
    level: float
    statement: str
    reason: str
    feedthrough: bool = False

    @property
    def detected(self) -> bool:
        """The input depends on the output's noise, by at least :data:`FEEDBACK_NOTED`."""
        return bool(self.statement)


def _innovation(target: np.ndarray, regressor: np.ndarray) -> np.ndarray:
    X = np.column_stack([regressor, np.ones(regressor.shape[0])])
    return target - X @ np.linalg.lstsq(X, target, rcond=None)[0]


def _pair(e: np.ndarray, eps: np.ndarray, first: int, last: int) -> tuple[float, float, int]:
    """p-value of ``N Σ ρ(τ)²`` over lags ``first … last`` (χ² with as many degrees of freedom), the largest ρ and
    its lag."""
    ne, nu = float(np.linalg.norm(e)), float(np.linalg.norm(eps))
    N = e.size
    if not (ne > 0.0 and nu > 0.0):
        return 1.0, 0.0, first  # an exact fit or a silent channel: no innovation to correlate
    lags = range(first, last + 1)
    rho = np.array([e[: N - t] @ eps[t:] for t in lags]) / (ne * nu)
    k = int(np.argmax(np.abs(rho)))
    return float(scipy.stats.chi2.sf(N * float(rho @ rho), len(lags))), float(rho[k]), lags[k]


def check_feedback(u, y, *, level: float = FEEDBACK_LEVEL, feedthrough: bool = False) -> FeedbackTest | None:
    """Test whether the input of ``(u, y)`` depends on the output's noise (module docstring).

    Parameters
    ----------
    u, y : array_like, shape (n,) or (n, m) and (n, l)
        The record, time along axis 0.
    level : float
        p-values below it (with ``|ρ| ≥`` :data:`FEEDBACK_NOTED`) detect feedback.
    feedthrough : bool
        The plant has a direct feedthrough (``y_k`` responds to ``u_k``): lag 0, where it correlates the innovations as
        feedback within the sample would, is not tested (module docstring).  Default False: strictly proper.

    Returns
    -------
    FeedbackTest or None
        None when the record is too short for ten rows per parameter of the ARX(16) fit (nothing is stated then).

    Raises
    ------
    DataError
        Bad data, or a level outside (0, 1).

    Examples
    --------
    >>> import numpy as np
    >>> import scipy.signal
    >>> rng = np.random.default_rng(0)
    >>> r, v = np.sign(rng.standard_normal(1200)), rng.standard_normal(1200)
    >>> y = scipy.signal.lfilter([0.0, 0.5], [1.0, -0.8], r) + 0.1 * v
    >>> check_feedback(r, y).detected                                   # open loop
    False
    >>> u, y, x = np.zeros(1200), np.zeros(1200), 0.0                   # u = r/20 − y: the noise dominates u
    >>> for k in range(1200):
    ...     y[k] = x + 0.1 * v[k]
    ...     u[k] = 0.05 * r[k] - y[k]
    ...     x = 0.8 * x + 0.5 * u[k]
    >>> t = check_feedback(u, y)
    >>> t.detected, t.correlation < -0.5, bool(t.reason)
    (True, True, True)

    An open-loop plant with a direct feedthrough looks like feedback at lag 0 unless it is declared:

    >>> y = scipy.signal.lfilter([0.3, 0.5], [1.0, -0.8], r) + 0.1 * v
    >>> t = check_feedback(r, y)
    >>> t.detected, t.lag, "direct feedthrough" in t.reason
    (True, 0, True)
    >>> check_feedback(r, y, feedthrough=True).detected
    False
    """
    u = as_signal(u, "u")
    y = as_signal(y, "y", n=u.shape[0])
    level = check_level(level, "level", maximum=1.0)  # float(level) had passed '0.1' and raised TypeError on None
    feedthrough = check_flag(feedthrough, "feedthrough")
    n, m = u.shape
    l = y.shape[1]
    p = _ORDER
    if n - p < _ROWS_PER_PARAMETER * (p * (l + m) + 1 + m * feedthrough):
        return None
    Phi = arx_regressor(u, y, p, p)[0][p:]
    if feedthrough:
        Phi = np.hstack([u[p:], Phi])  # u_k in the output's fit: its feedthrough is not an innovation
    U = arx_regressor(u, u, p, 0)[0][p:]  # rows [u_{k−1}ᵀ … u_{k−p}ᵀ]: the input's own past
    es = [_innovation(y[p:, c], Phi) for c in range(l)]
    eps = [_innovation(u[p:, j], U) for j in range(m)]
    tests = [(_pair(es[c], eps[j], int(feedthrough), _LAGS), (j, c)) for j in range(m) for c in range(l)]
    (pv, rho, lag), pair = min(tests, key=lambda t: t[0][0])
    pv = min(1.0, pv * m * l)
    statement, reason = "", ""
    if pv < level and abs(rho) >= FEEDBACK_NOTED:
        where = f"input {pair[0]} on output {pair[1]}, " if m * l > 1 else ""
        alternative = _LAG0_ALTERNATIVE if lag == 0 else _SWAP_ALTERNATIVE
        statement = (f"the record is that of a closed loop: the input's innovation follows the output's ({where}"
                     f"correlation {rho:+.2f} at lag {lag}, p = {pv:.2g}), so the output's noise reaches the input "
                     "through a controller and biases P̂ (towards −1/K where the noise dominates the reference's share "
                     "of u), and held-out data of the same loop share the bias, which the premise test therefore "
                     "cannot see; the certificate assumes the reference dominates the input (record in open loop, or "
                     f"raise the reference's excitation){alternative}")
        if abs(rho) >= FEEDBACK_REFUSED:
            reason = (f"the input is largely the loop's response to the output's noise (correlation {rho:+.2f} of the "
                      f"input's and the output's innovations at lag {lag}, p = {pv:.2g}; from "
                      f"{FEEDBACK_REFUSED:g} on, a quarter or more of the input's fresh variance): P̂ is biased "
                      "towards −1/K, and held-out data of the same loop share the bias. Record in open loop, or with "
                      f"a reference excitation that dominates the input{alternative}")
    return FeedbackTest(p_value=float(pv), correlation=float(rho), lag=int(lag), pair=tuple(int(x) for x in pair),
                        order=p, level=float(level), statement=statement, reason=reason, feedthrough=feedthrough)
