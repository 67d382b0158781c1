"""``python -m experiments mimo-pipeline``: the §7.4 certificate for several inputs and outputs, judged on the true plant.

Plants with two channels on at least one side (2 × 2 coupled lags, a 2 × 2 two-mass structure with
lightly damped modes, a 2 × 1 and a 1 × 2 plant), each under four excitations: independent white PRBS
on every input (the case the pipeline should certify), low-pass Gaussian noise on every input (little
power where the loop may be sensitive), one input silent (not persistently exciting: must refuse), and
two nearly collinear inputs (``u₂ = 0.95 u₁ + 0.05 e``: the data barely separate the channels).

Each run: a record of ``RECORD`` samples and a second, held-out experiment of ``HELD_OUT`` samples;
:func:`unfalsify.robust_design_from_data` in record mode (``window="auto"``, ``sigma="auto"``,
``validation=`` the second experiment; the tracking floor 0.1 on the first ``m`` outputs, the others
not tracked -- one input cannot track two independent references) with the design CLI's default weights
on every channel (:func:`experiments.studies.design_cli.default_weights`: ``makeweight(100, (ω_N/30, 1), 0.2,
dt)`` and ``makeweight(0.05, (ω_N/10, 0.3), 1, dt)``, ω_N = π/dt; 0.01 on an output that is not tracked),
stacked by :func:`synthesis.diagonal_weight`.
Independently of the pipeline, the loop it returns is judged on the true plant: stability, the
proven ``δ·‖K(I + PK)⁻¹‖∞`` (largest singular value), a step on each reference channel alone, and the
premise the certificate rests on, ``‖P − P̂‖∞/δ``.  A *false certificate* is a certified loop the
judge fails; a *silent failure* a loop neither certified nor warned about.

``--quick``: the 2 × 2 coupled lags under PRBS and with a silent channel, one seed, the output-error program
on 150 held-out samples.
"""
from __future__ import annotations

import time
import warnings
from dataclasses import dataclass
from pathlib import Path

import control
import numpy as np
import scipy.signal

import synthesis
import unfalsify as uf

from ..lab.report import Report, finish_report, write_csv
from .adversarial import verdict
from .design_cli import default_weights
from .robust_pipeline import premise_ratio, result_premise_ratio, true_factors

__all__ = ["run", "summary_lines", "PLANTS", "EXCITATIONS", "judge", "make_record", "Case"]

#: samples of the design record and of the held-out second experiment
RECORD, HELD_OUT = 1500, 600
#: output noise (rms) on every channel
NOISE = 0.02
HORIZON = 6


def coupled_lags(dt: float = 1.0) -> control.StateSpace:
    """2 × 2: first-order lags (poles 0.9, 0.7) mixed by a full matrix (DC gain [[1, 0.4], [0.3, 0.8]])."""
    a = np.array([0.9, 0.7])
    G = np.array([[1.0, 0.4], [0.3, 0.8]])
    return control.ss(np.diag(a), np.diag(1 - a), G, np.zeros((2, 2)), dt)


def two_mass(dt: float = 0.5) -> control.StateSpace:
    """2 × 2: two masses, springs to ground and between them, force on each, position of each (ZOH)."""
    k1, k2, kc, c = 1.0, 1.5, 0.8, 0.15
    K = np.array([[k1 + kc, -kc], [-kc, k2 + kc]])
    A = np.block([[np.zeros((2, 2)), np.eye(2)], [-K, -c * np.eye(2)]])
    B = np.vstack([np.zeros((2, 2)), np.eye(2)])
    C = np.hstack([np.eye(2), np.zeros((2, 2))])
    return control.c2d(control.ss(A, B, C, np.zeros((2, 2))), dt, "zoh")


def tall(dt: float = 1.0) -> control.StateSpace:
    """2 × 1: one input seen by two lags (poles 0.8, 0.6), DC gains 1 and 0.5."""
    a = np.array([0.8, 0.6])
    return control.ss(np.diag(a), (1 - a).reshape(2, 1), np.diag([1.0, 0.5]), np.zeros((2, 1)), dt)


def wide(dt: float = 1.0) -> control.StateSpace:
    """1 × 2: two lags (poles 0.85, 0.5) summed into one output, DC gains 1 and 0.6."""
    a = np.array([0.85, 0.5])
    return control.ss(np.diag(a), np.diag(1 - a), np.array([[1.0, 0.6]]), np.zeros((1, 2)), dt)


PLANTS = {"coupled_lags": coupled_lags, "two_mass": two_mass, "tall_2x1": tall, "wide_1x2": wide}


def _prbs(n: int, m: int, rng) -> np.ndarray:
    return np.sign(rng.standard_normal((n, m)))


def _lowpass(n: int, m: int, rng) -> np.ndarray:
    b, a = scipy.signal.butter(4, 0.1)                      # cut-off a tenth of Nyquist
    x = scipy.signal.lfilter(b, a, rng.standard_normal((n + 200, m)), axis=0)[200:]
    return x / np.std(x, axis=0)


def _silent(n: int, m: int, rng) -> np.ndarray:
    u = _prbs(n, m, rng)
    u[:, -1] = 0.0
    return u


def _collinear(n: int, m: int, rng) -> np.ndarray:
    u = _prbs(n, m, rng)
    if m > 1:
        u[:, 1] = 0.95 * u[:, 0] + 0.05 * rng.standard_normal(n)
    return u


EXCITATIONS = {"prbs": _prbs, "lowpass": _lowpass, "silent_channel": _silent, "collinear": _collinear}


@dataclass(frozen=True)
class Case:
    plant: str
    excitation: str
    seed: int

    @property
    def name(self) -> str:
        return f"{self.plant}/{self.excitation}/s{self.seed}"


def make_record(case: Case):
    """``(P, (u, y), (u_v, y_v))``: the true plant, the design record and the held-out experiment."""
    P = PLANTS[case.plant]()
    rng = np.random.default_rng(1000 * case.seed + 7)
    signal = EXCITATIONS[case.excitation]

    def experiment(n):
        u = signal(n, P.ninputs, rng)
        y = control.forced_response(P, T=np.arange(n) * P.dt, U=u.T).outputs.reshape(P.noutputs, n).T
        return u, y + NOISE * rng.standard_normal(y.shape)

    return P, experiment(RECORD), experiment(HELD_OUT)


def _weights(P):
    W1, W2, _ = default_weights(float(P.dt))   # the design CLI's defaults, relative to the Nyquist frequency
    # outputs beyond the m that can be tracked get a small static weight: the design does not chase them
    W1s = [W1 if k < P.ninputs else 0.01 for k in range(P.noutputs)]
    return synthesis.diagonal_weight(*W1s), synthesis.diagonal_weight(W2, channels=P.ninputs)


def tracking_floor(P) -> tuple:
    """The floor per output: 0.1 on the first ``m`` outputs, ``inf`` (not tracked) on the others."""
    return tuple(uf.certify.TRACKING_FLOOR if k < P.ninputs else float("inf") for k in range(P.noutputs))


def judge(P, controller, delta: float, floor=None) -> dict:
    """The loop on the true plant, independent of the pipeline's models; ``fails`` lists what failed."""
    floors = uf.tracking_floors(tracking_floor(P) if floor is None else floor, P.noutputs)
    rob = uf.additive_robustness(P, controller)
    out = {"stable": bool(rob.stable), "small_gain": float(delta * rob.peak) if rob.stable else float("inf")}
    step = uf.step_metrics(uf.closed_loop_ry(P, controller))
    errors = step.output_errors(np.isfinite(floors))
    out["step_error"] = float(np.max(np.where(np.isfinite(floors), errors, 0.0)))
    fails = []
    if not rob.stable:
        fails.append("true loop unstable")
    else:
        if not out["small_gain"] < 1.0:
            fails.append(f"true δ‖M‖ = {out['small_gain']:.3g} ≥ 1")
        if not np.all(errors <= floors):
            fails.append(f"no tracking (step error {out['step_error']:.3g})")
    out["fails"], out["ok"] = fails, not fails
    return out


def _coprime_judge(P, rd, true: dict) -> tuple[dict, float]:
    """A coprime-factor certificate on the true plant: ``(judge, premise ratio)``.

    Any number of outputs: the small gain ``ε‖[K; I](M + NK)⁻¹‖∞`` with the plant factored like P̂
    (:func:`experiments.studies.robust_pipeline.true_factors`) joins the judge, and the premise ratio is the
    upper end of its bracket (:func:`~experiments.studies.robust_pipeline.result_premise_ratio`).  (Several outputs
    had been judged on stability and tracking only, with the pointwise distance over ε, the bracket's lower end.)
    """
    if true["stable"]:
        F = true_factors(P, like=rd.coprime.factors)
        gain = rd.epsilon * synthesis.hinf_norm(uf.coprime_channel(F, rd.controller)).upper
        true = dict(true, small_gain=float(gain))
        if not gain < 1.0:
            true["fails"] = true["fails"] + [f"true ε‖[K; I](M+NK)⁻¹‖∞ = {gain:.3g} ≥ 1"]
            true["ok"] = False
    return true, result_premise_ratio(P, rd)[0]


def run_case(case: Case, premise: uf.PremiseOptions | None = None) -> dict:
    """One pipeline run and its true-plant verdict (``premise``: how the premise is tested, default options)."""
    P, (u, y), validation = make_record(case)
    W1, W2 = _weights(P)
    t0 = time.perf_counter()
    row = {"case": case.name, "plant": case.plant, "excitation": case.excitation, "seed": case.seed,
           "shape": f"{P.noutputs}×{P.ninputs}"}
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            rd = uf.robust_design_from_data(u, y, HORIZON, W1, W2, "auto", window="auto", validation=validation,
                                            dt=float(P.dt), premise=premise,
                                            certificate=uf.CertificateOptions(tracking_floor=tracking_floor(P)))
        except (synthesis.DataError, uf.UnfalsificationError) as exc:
            row.update(verdict=verdict(False, False, None, exc), certified=False, reason=str(exc),
                       seconds=time.perf_counter() - t0)
            return row
    warned = any(issubclass(w.category, uf.NotCertifiedWarning) for w in caught)
    coprime = rd.uncertainty == "coprime"
    true = judge(P, rd.controller, 0.0 if coprime else rd.delta)
    if coprime:
        true, ratio = _coprime_judge(P, rd, true)
    else:
        ratio = premise_ratio(P, rd.model, rd.delta)[0]
    row.update(verdict=verdict(rd.certified, warned, true), certified=bool(rd.certified), delta=float(rd.delta),
               uncertainty=rd.uncertainty, decided_by=rd.premise.decided_by, premise_ratio=ratio,
               true_small_gain=true["small_gain"], true_stable=true["stable"], true_step_error=true["step_error"],
               true_fails="; ".join(true["fails"]), reason=rd.reason, seconds=time.perf_counter() - t0)
    return row


_HEADERS = ["case", "shape", "verdict", "δ", "decided by", "‖P−P̂‖∞/δ", "true δ‖M‖", "true step error", "reason",
            "time [s]"]


def _row(r: dict) -> list:
    reason = r.get("reason", "") or "—"
    return [r["case"], r["shape"], r["verdict"], r.get("delta", float("nan")), r.get("decided_by", ""),
            r.get("premise_ratio", float("nan")), r.get("true_small_gain", float("nan")),
            r.get("true_step_error", float("nan")), reason if len(reason) < 200 else reason[:197] + "…",
            r["seconds"]]


def cases(quick: bool, seed: int = 0) -> list[Case]:
    """Every plant × excitation × two seeds; ``quick``: the coupled lags under PRBS and a silent channel."""
    if quick:
        return [Case("coupled_lags", e, seed) for e in ("prbs", "silent_channel")]
    return [Case(p, e, s) for p in PLANTS for e in EXCITATIONS for s in (seed, seed + 1)]


#: ``--quick``: the output-error program on the first 150 held-out samples (about 3 s for 2 × 2, not 30 s)
QUICK_PREMISE = uf.PremiseOptions(samples=150)


def summarise(rows: list[dict]) -> dict:
    verdicts = {v: sum(r["verdict"] == v for r in rows) for v in
                ("certified", "false_certificate", "not_certified", "refused_by_error", "refused_without_fix",
                 "silent_failure")}
    ratios = [r["premise_ratio"] for r in rows if r["verdict"] == "certified"]
    return {"runs": len(rows), "certified": verdicts["certified"], "false_certificates": verdicts["false_certificate"],
            "silent_failures": verdicts["silent_failure"], "verdicts": verdicts,
            "false_certificate_cases": [r["case"] for r in rows if r["verdict"] == "false_certificate"],
            "premise_ratio_certified": [min(ratios), max(ratios)] if ratios else []}


def summary_lines(summary: dict) -> list[str]:
    """Key numbers of a run, for the CLI and the report."""
    lines = [f"{summary['certified']} of {summary['runs']} runs certified",
             f"false certificates: {summary['false_certificates']} (must be 0)"
             + (f": {', '.join(summary['false_certificate_cases'])}" if summary["false_certificate_cases"] else ""),
             f"silent failures: {summary['silent_failures']} (must be 0)",
             "verdicts: " + ", ".join(f"{k} {v}" for k, v in summary["verdicts"].items() if v)]
    if summary["premise_ratio_certified"]:
        lo, hi = summary["premise_ratio_certified"]
        lines.append(f"premise ratio ‖P − P̂‖∞/δ of the certified loops: {lo:.3g}–{hi:.3g}")
    return lines


TITLE = "§7.4 certificate with several inputs and outputs, judged on the true plant"


def run(opts) -> dict:
    """Run the cases (``--quick``: one plant, one seed); write ``mimo_pipeline.md``/``.json``/``.csv``."""
    out = Path(opts.out)
    out.mkdir(parents=True, exist_ok=True)
    t_start = time.perf_counter()
    premise = QUICK_PREMISE if opts.quick else None
    rows = [run_case(c, premise) for c in cases(bool(opts.quick), int(getattr(opts, "seed", 0) or 0))]
    summary = {"quick": bool(opts.quick), **summarise(rows), "cases": rows}
    rep = Report(TITLE)
    rep.text(__doc__.split("\n\n", 1)[1].rsplit("``--quick``", 1)[0].strip())
    table = [_row(r) for r in rows]
    rep.table(_HEADERS, table)
    rep.section("Summary", "\n".join(f"- {line}" for line in summary_lines(summary)))
    write_csv(out / "mimo_pipeline.csv", _HEADERS, table)
    return finish_report(rep, summary, out, "mimo_pipeline", t_start=t_start)
