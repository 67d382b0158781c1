"""The option objects of :func:`unfalsify.robust_design_from_data`: how δ is estimated
(:class:`EstimationOptions`), how the controller is designed (:class:`DesignOptions`) and searched
(:class:`DesignSearch`), and what its certificate requires (:class:`CertificateOptions`).

Each is a frozen dataclass that checks its fields when it is made (``DataError`` naming the field), not at the
first solve that reads them.  The keywords of earlier releases (``gamma_ratio=``, ``certificate_margin=``, …)
are mapped onto their fields by the pipeline.
"""
from __future__ import annotations

import dataclasses
import numbers
from dataclasses import dataclass

import numpy as np

from synthesis.validation import DataError, check_flag, check_horizon

from ._common import BACKENDS, check_form, check_solver_options
from .certify import STEP_SAMPLES, TRACKING_FLOOR, _check_step_samples, tracking_floors

__all__ = ["DesignSearch", "DesignOptions", "CertificateOptions", "EstimationOptions"]


#: Default relative margin of the loop certificate (see :func:`robust_design_from_data`).
CERTIFICATE_MARGIN = 0.25


@dataclass(frozen=True)
class DesignSearch:
    """The design family :func:`robust_design_from_data` searches when its first design does not certify.

    Candidates are tried in order of increasing departure from the requested design (the sum
    of the option indices below, the requested values first), and the first that certifies
    (:func:`unfalsify.certify_loop`: nominal stability on P̂, proven small gain, performance
    floor) is returned.

    Attributes
    ----------
    gamma_ratios : tuple of float
        Levels ``γ = ratio · γ_min_a`` (larger: less aggressive, closer to the LQ law).
    w3_factors : tuple of float
        Multipliers of the fixed-point W3 gain ``c`` (a larger ``W3 = cI`` penalises ``u`` in the
        additive channel and widens the finite-horizon coverage ``c/γ``).
    causal : tuple of bool
        Strictly causal (Thm 3.1 family) and causal (Thm 3.2 family) laws.
    horizons : tuple of int
        Further horizons ``i`` (each needs a predictor: ``predictor_for(i)``, or a least-squares
        fit on the given data when the pipeline estimates the predictor itself).

    Examples
    --------
    The default family: every combination of level, W3 factor and causality at the given horizon,
    40 designs (the ones tried are ``RobustDesignResult.search``):

    >>> from unfalsify import DesignSearch
    >>> s = DesignSearch()
    >>> len(s.gamma_ratios) * len(s.w3_factors) * len(s.causal)
    40

    A narrower family, with one further horizon, is passed as ``search=`` to
    :func:`robust_design_from_data`; an empty one is refused:

    >>> DesignSearch(gamma_ratios=(1.1, 2.0), w3_factors=(1.0,), causal=(False,), horizons=(20,))
    DesignSearch(gamma_ratios=(1.1, 2.0), w3_factors=(1.0,), causal=(False,), horizons=(20,))
    >>> DesignSearch(gamma_ratios=())  # doctest: +ELLIPSIS
    Traceback (most recent call last):
        ...
    synthesis.exceptions.DataError: gamma_ratios is empty: the search would try no design; give at least one value ...
    """

    gamma_ratios: tuple = (1.1, 1.5, 2.0, 4.0, 10.0)
    w3_factors: tuple = (1.0, 3.0, 10.0, 30.0)
    causal: tuple = (False, True)
    horizons: tuple = ()

    def __post_init__(self):
        for name in ("gamma_ratios", "w3_factors", "causal", "horizons"):
            if isinstance(getattr(self, name), (str, bytes)) or not np.iterable(getattr(self, name)):
                raise DataError(f"{name} must be a tuple, got {getattr(self, name)!r}")
        for name in ("gamma_ratios", "w3_factors", "causal"):
            if not len(tuple(getattr(self, name))):  # the search tries their combinations: one empty, none at all
                raise DataError(f"{name} is empty: the search would try no design; give at least one value (or pass "
                                "search=False to robust_design_from_data for the first design alone)")
        for r in self.gamma_ratios:
            _positive_real(r, "each of gamma_ratios", above=1.0)
        for f in self.w3_factors:
            _positive_real(f, "each of w3_factors")
        for c in self.causal:
            check_flag(c, "each of causal")
        for h in self.horizons:
            check_horizon(h, name="each of horizons (DesignSearch)")


def _positive_real(value, name: str, *, above: float = 0.0, allow_equal: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not np.isfinite(value) or (
            value < above if allow_equal else value <= above):
        rel = ">=" if allow_equal else ">"
        raise DataError(f"{name} must be a finite real number {rel} {above:g}, got {value!r}")
    return float(value)


@dataclass(frozen=True)
class DesignOptions:
    """The first design of :func:`robust_design_from_data` (step 4).

    Attributes
    ----------
    gamma_ratio : float
        ``γ = gamma_ratio · γ_min_a``.
    margin : float
        Relative margin of the W3 rule: the finite-horizon design covers ``(1 + margin) δ``.
    w3_rule : {"small-gain", "thesis"}
        ``"small-gain"``: ``W3 = c I`` with ``c = (1 + margin) δ γ(c)`` (module docstring).
        ``"thesis"``: the literal §7.4 ``W3 = (1/δ) I``, for comparison only.
    causal : bool
        Causal law (Thm 3.2 variant).

    Examples
    --------
    Made with keywords (the other fields keep their defaults) and passed to :func:`robust_design_from_data`; here
    on the setting of its example (a FIR plant, ``i = 3``, a 45-sample window, the predictors fitted on the
    whole record); ``search=False`` returns the first design, certified or not:

    >>> import warnings
    >>> import numpy as np
    >>> import synthesis as sy
    >>> from unfalsify import robust_design_from_data
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(300)
    >>> y = np.convolve(u, [0.0, 1.0, 0.5])[:300] + 0.01 * rng.standard_normal(300)
    >>> W1, W2 = sy.makeweight(10.0, (0.3, 1.0), 0.5, 1.0), sy.makeweight(0.1, (2.0, 0.3), 1.0, 1.0)
    >>> fits = {"predictor": sy.fit_predictor(u, y, 3), "predictor_for": lambda h: sy.fit_predictor(u, y, h)}
    >>> opts = DesignOptions(gamma_ratio=1.5)
    >>> with warnings.catch_warnings():
    ...     warnings.simplefilter("ignore")  # NotCertifiedWarning or UntestedPremiseWarning
    ...     rd = robust_design_from_data(u[:45], y[:45], 3, W1, W2, "auto", dt=1.0, design=opts, search=False, **fits)
    >>> round(rd.gamma / rd.gamma_min_a, 6), rd.w3_rule, rd.margin, len(rd.search)
    (1.5, 'small-gain', 0.1, 1)

    The options are frozen: :func:`dataclasses.replace` makes a variant, checked like a new one; a bad value
    raises :class:`~synthesis.validation.DataError` naming the field:

    >>> import dataclasses
    >>> dataclasses.replace(opts, causal=True).causal
    True
    >>> dataclasses.replace(opts, gamma_ratio=0.9)
    Traceback (most recent call last):
        ...
    synthesis.exceptions.DataError: gamma_ratio must be a finite real number > 1, got 0.9
    """

    gamma_ratio: float = 1.1
    margin: float = 0.1
    w3_rule: str = "small-gain"
    causal: bool = False

    def __post_init__(self):
        check_flag(self.causal, "causal")
        if self.w3_rule not in ("small-gain", "thesis"):
            raise DataError(f"unknown w3_rule {self.w3_rule!r}; use 'small-gain' or 'thesis'")
        _positive_real(self.gamma_ratio, "gamma_ratio", above=1.0)
        _positive_real(self.margin, "margin", allow_equal=True)


#: the uncertainty families a loop can be certified for (``CertificateOptions.uncertainty``)
UNCERTAINTY_FORMS = ("auto", "additive", "coprime")


#: what a premise the data cannot test does (``CertificateOptions.untested``)
UNTESTED_RULES = ("warn", "refuse")


@dataclass(frozen=True)
class CertificateOptions:
    """The loop certificate of :func:`robust_design_from_data` (step 5).

    Attributes
    ----------
    margin : float
        The certificate needs ``δ·‖K(I+P̂K)⁻¹‖∞ ≤ 1/(1 + margin)`` on P̂ and P̂_ref (default 0.25:
        measured on four plants, the true loop's ``‖K(I+PK)⁻¹‖∞`` was within 10 % of the models').
    tracking_floor, step_samples
        Performance floor of :func:`unfalsify.certify_loop` (one number, or one per output channel).
    reference_horizon : int or None
        Horizon of the reference model ``P̂_ref`` on which every design must certify too; its predictor
        comes from ``predictor_for``, or a least-squares fit on the window when no predictor is given.
        An explicit value wins.  Default (None): the longest horizon the fitting record supports with
        :data:`unfalsify.REFERENCE_COLUMNS` = 10 columns per regressor, ``n − 2h + 1 ≥ 10·h(2m + l)``
        (``n`` the record the given predictor was fitted on, or the window), at most
        :data:`unfalsify.REFERENCE_HORIZON_CAP` = 60 and at least ``2i``; ``2i`` when ``n`` is unknown
        (``predictor_for`` without ``predictor``) or the longer predictor is not persistently exciting.
        Over a short horizon a slow mode that flips or shrinks the plant's DC gain is invisible (the
        plant looks like its fast part); the longest well-determined horizon sees it.  The horizon used
        is ``RobustDesignResult.reference_horizon``.
    require_reference : bool
        Without a reference model the loop is not certified (default): measured on an integrating
        plant with a resonance (i = 10), certificates on P̂ alone failed on the true plant, while P̂ and
        P̂_ref together never did on the plants tried.  ``False`` certifies on P̂ alone (weaker).
    uncertainty : {"auto", "additive", "coprime"}
        The family the loop is certified for.  ``"additive"``: ``P̂ + Δ``, ``‖Δ‖∞ ≤ (1 + margin)δ``.
        ``"coprime"``: ``(M̂ + Δ_M)⁻¹(N̂ + Δ_N)``, ``‖[Δ_N Δ_M]‖∞ ≤ (1 + margin)ε`` around P̂'s FIR factors
        (:mod:`unfalsify.coprime`), finite for an integrating plant, whose ``‖P − P̂‖∞`` is infinite.
        ``"auto"`` (default): additive, and the coprime form when the data refute the additive premise
        (each form's premise is tested in its own terms; the result says which one certified).
    untested : {"warn", "refuse"}
        What a premise these data cannot test does (:func:`unfalsify.untested_premises`: an input with two values, or 0
        and ±a, up to noise, shows no saturation or dead zone; records too short for
        :func:`unfalsify.check_time_invariance` show no change of the plant).  ``"warn"`` (default): the loop is
        certified on that assumption, which ``result.assumed`` states and :class:`UntestedPremiseWarning` repeats.
        ``"refuse"``: not certified, the reason names the fix (several input amplitudes; a longer validation record).
        Measured on the adversarial catalogue's saturation case (a ±1 PRBS, seeds 0–9): four of the ten loops ``"warn"``
        certifies fail the true-plant judge.
    feedthrough : bool
        The plant has a direct feedthrough (``y_k`` responds to ``u_k``).  Default False: strictly proper, and a
        correlation of the input's and the output's innovations at lag 0 is read as feedback
        (:func:`unfalsify.check_feedback`), which an open-loop record of a plant with a feedthrough also shows.
        ``True``: the feedback test leaves lag 0 out, and ``assumed`` states that feedback within the sample is not
        tested (:data:`unfalsify.FEEDTHROUGH_STATEMENT`).

    Examples
    --------
    Made with keywords (the other fields keep their defaults) and passed to :func:`robust_design_from_data`; here
    on the setting of its example (a FIR plant, ``i = 3``, a 45-sample window, the predictors fitted on the
    whole record):

    >>> import warnings
    >>> import numpy as np
    >>> import synthesis as sy
    >>> from unfalsify import robust_design_from_data
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(300)
    >>> y = np.convolve(u, [0.0, 1.0, 0.5])[:300] + 0.01 * rng.standard_normal(300)
    >>> W1, W2 = sy.makeweight(10.0, (0.3, 1.0), 0.5, 1.0), sy.makeweight(0.1, (2.0, 0.3), 1.0, 1.0)
    >>> fits = {"predictor": sy.fit_predictor(u, y, 3), "predictor_for": lambda h: sy.fit_predictor(u, y, h)}
    >>> opts = CertificateOptions(margin=0.5, untested="refuse")
    >>> with warnings.catch_warnings():
    ...     warnings.simplefilter("ignore")  # NotCertifiedWarning or UntestedPremiseWarning
    ...     rd = robust_design_from_data(u[:45], y[:45], 3, W1, W2, "auto", dt=1.0, certificate=opts, **fits)
    >>> rd.certificate.margin
    0.5

    With ``untested="refuse"`` a premise these data cannot test refuses the certificate, and the reason says so
    (``rd.assumed`` states them: here P̂'s output error tested in sample, and one time-invariant plant, which a
    45-sample window is too short to test):

    >>> len(rd.assumed) > 0, rd.certified, "untested='refuse'" in rd.premise_reason
    (True, False, True)

    A bad value raises :class:`~synthesis.validation.DataError` naming the field:

    >>> CertificateOptions(uncertainty="multiplicative")
    Traceback (most recent call last):
        ...
    synthesis.exceptions.DataError: unknown uncertainty 'multiplicative'; use one of 'auto', 'additive', 'coprime'
    """

    margin: float = CERTIFICATE_MARGIN
    tracking_floor: float | tuple = TRACKING_FLOOR
    step_samples: int = STEP_SAMPLES
    reference_horizon: int | None = None
    require_reference: bool = True
    uncertainty: str = "auto"
    untested: str = "warn"
    feedthrough: bool = False

    def __post_init__(self):
        _positive_real(self.margin, "margin", allow_equal=True)
        tracking_floors(self.tracking_floor, None)  # their count is the plant's outputs, not known yet
        _check_step_samples(self.step_samples)
        if self.reference_horizon is not None:
            check_horizon(self.reference_horizon, name="reference_horizon (CertificateOptions)")
        check_flag(self.require_reference, "require_reference")
        check_flag(self.feedthrough, "feedthrough")
        if self.uncertainty not in UNCERTAINTY_FORMS:
            raise DataError(f"unknown uncertainty {self.uncertainty!r}; use one of "
                            f"{', '.join(repr(u) for u in UNCERTAINTY_FORMS)}")
        if self.untested not in UNTESTED_RULES:
            raise DataError(f"unknown untested {self.untested!r}; use one of "
                            f"{', '.join(repr(u) for u in UNTESTED_RULES)}")


@dataclass(frozen=True)
class EstimationOptions:
    """How :func:`estimate_delta` solves (7.5), passed to :func:`unfalsify.subspace_unfalsify`.

    Attributes
    ----------
    form : {"conditioned", "thesis"}
    solver : str
        cvxpy solver of the cvxpy backend.
    solver_options : dict or None
    backend : {"structured", "cvxpy"} or None
        None: ``"structured"`` for the conditioned form (faster, O(i²j) memory), the cvxpy models otherwise.

    Examples
    --------
    Made with keywords (the other fields keep their defaults) and passed to :func:`robust_design_from_data`; here
    on the setting of its example (a FIR plant, ``i = 3``, a 45-sample window, the predictors fitted on the
    whole record):

    >>> import warnings
    >>> import numpy as np
    >>> import synthesis as sy
    >>> from unfalsify import robust_design_from_data
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(300)
    >>> y = np.convolve(u, [0.0, 1.0, 0.5])[:300] + 0.01 * rng.standard_normal(300)
    >>> W1, W2 = sy.makeweight(10.0, (0.3, 1.0), 0.5, 1.0), sy.makeweight(0.1, (2.0, 0.3), 1.0, 1.0)
    >>> fits = {"predictor": sy.fit_predictor(u, y, 3), "predictor_for": lambda h: sy.fit_predictor(u, y, h)}
    >>> opts = EstimationOptions(backend="cvxpy")  # the cvxpy model and CLARABEL, not the structured solver
    >>> with warnings.catch_warnings():
    ...     warnings.simplefilter("ignore")  # NotCertifiedWarning or UntestedPremiseWarning
    ...     rd = robust_design_from_data(u[:45], y[:45], 3, W1, W2, "auto", dt=1.0, estimation=opts,
    ...                                  search=False, **fits)
    >>> rd.unfalsification.backend, rd.unfalsification.certificate.verify()
    ('cvxpy', True)

    The default (``backend=None``: the structured solver for the conditioned form) finds the same δ;
    :func:`estimate_delta` takes the options too:

    >>> from unfalsify import estimate_delta
    >>> unf = estimate_delta(u[:45], y[:45], 3, "auto", predictor=fits["predictor"],
    ...                      estimation=EstimationOptions())
    >>> unf.backend, bool(np.isclose(unf.delta, rd.unfalsification.delta, rtol=1e-3))
    ('structured', True)

    A bad value raises :class:`~synthesis.validation.DataError` naming the field:

    >>> EstimationOptions(backend="scs")
    Traceback (most recent call last):
        ...
    synthesis.exceptions.DataError: backend must be None or one of ('cvxpy', 'structured'), got 'scs'
    """

    form: str = "conditioned"
    solver: str = "CLARABEL"
    solver_options: dict | None = None
    backend: str | None = None

    def __post_init__(self):
        check_form(self.form)
        if not isinstance(self.solver, str):
            raise DataError(f"solver must be the name of a cvxpy solver (e.g. 'CLARABEL'), got {self.solver!r}")
        check_solver_options(self.solver_options)
        if self.backend is not None and self.backend not in BACKENDS:
            raise DataError(f"backend must be None or one of {BACKENDS}, got {self.backend!r}")


#: the keywords of earlier releases and the option field each sets
_LEGACY = {
    "gamma_ratio": ("design", "gamma_ratio"), "margin": ("design", "margin"), "w3_rule": ("design", "w3_rule"),
    "causal": ("design", "causal"), "certificate_margin": ("certificate", "margin"),
    "tracking_floor": ("certificate", "tracking_floor"), "step_samples": ("certificate", "step_samples"),
    "reference_horizon": ("certificate", "reference_horizon"),
    "require_reference": ("certificate", "require_reference"), "form": ("estimation", "form"),
    "solver": ("estimation", "solver"), "solver_options": ("estimation", "solver_options"),
    "backend": ("estimation", "backend"),
}


def _gather_options(design, certificate, estimation, legacy: dict):
    """The three option objects, with the earlier releases' keywords applied to their fields."""
    unknown = sorted(set(legacy) - set(_LEGACY))
    if unknown:
        raise TypeError(f"robust_design_from_data() got unexpected keyword argument(s) {', '.join(unknown)}")
    groups = {"design": design or DesignOptions(), "certificate": certificate or CertificateOptions(),
              "estimation": estimation or EstimationOptions()}
    for name, kind in (("design", DesignOptions), ("certificate", CertificateOptions),
                       ("estimation", EstimationOptions)):
        if not isinstance(groups[name], kind):
            raise DataError(f"{name} must be a {kind.__name__}, got {groups[name]!r}")
    for key, value in legacy.items():
        group, field = _LEGACY[key]
        groups[group] = dataclasses.replace(groups[group], **{field: value})
    return groups["design"], groups["certificate"], groups["estimation"]
