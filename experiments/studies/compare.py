"""Model-free design against what a practitioner would do: identify a model, then design on it.

``python -m experiments compare``: for each plant × data length × noise seed, one open-loop PRBS
experiment, and from the *same* data and the *same* weights W1, W2:

* **model-free nominal** (Thm 3.1, the LTI controller (5.3)–(5.4)) at the plant's fixed horizon
  (§5.4: i = 20 at 10 Hz; §6.2: i = 64 on the three-disk plant), γ = 1.1 γ_min and γ = 1.35 γ_min;
* **model-free, i from the data**: :func:`synthesis.choose_horizon` (γ = 1.1 γ_min and 1.35 γ_min; its
  checks are on data-based models, not on the plant, and a run with no candidate passing them is noted);
* **model-free robust** (§7.4, :func:`unfalsify.robust_design_from_data`) at the small size of
  ``robust-pipeline`` (i = 10, j = 30, a held-out second experiment) on every plant (on the three-disk
  plant i = 10 is a 0.16 s horizon: the size the structured (7.5) solve keeps to seconds);
* **identify-then-design**: :func:`synthesis.arx_id` (order by AIC; by hold-out output error) and
  :func:`synthesis.subspace_id` at the model-free horizon (order by the noise floor; by hold-out
  output error; the physical order), each followed by :func:`synthesis.discrete_mixsyn` at
  γ = 1.1 γ_opt;
* a **physics model** with stated parameter errors (:data:`PHYSICS_ERRORS`) and
  :func:`synthesis.discrete_mixsyn`, and the **ideal**: ``discrete_mixsyn`` on the true plant
  (both once per plant: they do not use the data).

Every controller is judged on the **true plant**, independently of how it was designed: closed-loop
stability (spectral radius), the weighted norm of the reference channel ‖[W1 (1 − T_yr); W2 T_ur]‖∞
(what the model-free design minimises; proven upper side of :func:`synthesis.hinf_norm`), the weighted
norm of the feedback loop ‖[W1 S; W2 K_y S]‖∞ with S = (I − P K_y)⁻¹ (the feedback part K_y of a
``[r; y]`` controller; the two norms coincide for error feedback ``u = K(r − y)``, not for the two-input
model-free controllers), the additive robustness radius 1/‖K_y(I − P K_y)⁻¹‖∞ (proven bound), unit-step
metrics, and the design time.

The report adds the thesis's Figs. 6.6/6.7 on the three-disk non-collocated plant (§6.2): a
physics model whose first resonance is 5 % high gives a model-based loop that is unstable on the
true plant, where the model-free loop from 2048 samples works; step responses and the two
controllers' Bode plots side by side, and a scan of other few-percent errors.

``--quick``: three plants (servo, non-minimum phase, three-disk), one seed, one data length, the
robust pipeline skipped (it takes seconds per run; ``robust-pipeline --quick`` exercises it).
"""
from __future__ import annotations

import dataclasses
import math
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

import control
import numpy as np

import synthesis

from ..lab.plants import THREE_DISK, nonminimum_phase, resonant, servo, three_disk
from ..lab.report import Report, finish_report, save_figure, write_csv
from ..lab.servo_setup import design_weights
from ..lab.signals import prbs
from ..lab.simulate import closed_loop_system, collect_data
from ..lab.torsional_setup import torsional_weights
from .noncollocated import step_metrics

__all__ = ["run", "evaluate", "PLANTS", "PHYSICS_ERRORS", "METHODS", "Config", "summary_lines"]

#: methods in report order: key -> label
METHODS = {
    "mf_1.1": "model-free nominal, γ = 1.1 γ_min",
    "mf_1.35": "model-free nominal, γ = 1.35 γ_min",
    "mf_auto": "model-free, i by choose_horizon (1.1 γ_min)",
    "mf_auto_1.35": "model-free, i by choose_horizon (1.35 γ_min)",
    "mf_robust": "model-free robust (§7.4)",
    "arx_aic": "ARX (AIC) + mixsyn",
    "arx_val": "ARX (hold-out) + mixsyn",
    "sid_floor": "N4SID (noise floor) + mixsyn",
    "sid_val": "N4SID (hold-out) + mixsyn",
    "sid_true": "N4SID (physical order) + mixsyn",
    "physics": "physics model + mixsyn",
    "ideal": "ideal: true plant + mixsyn",
}

MODEL_BASED_RATIO = 1.1

#: the physics models' stated parameter errors (the model a practitioner builds from a data sheet)
PHYSICS_ERRORS = {
    "servo": "1.1/(s(s + 1.2)): gain +10 %, pole −1 → −1.2 (+20 %)",
    "resonant": "ω = 2.1 rad/s (+5 %), ζ = 0.1 (×2)",
    "nonminimum_phase": "2.42/1.2·(1.2 − s)/((s + 1.1)(s + 2.2)): zero +20 %, poles +10 %, DC gain kept",
    "three_disk_y3": "first resonance ω_p1 = 16.64 rad/s (+5 %), everything else as §6.1",
}


def _physics(name: str, dt: float):
    if name == "servo":
        return control.ss(control.c2d(control.tf([1.1], [1.0, 1.2, 0.0]), dt))
    if name == "resonant":
        return resonant(zeta=0.1, omega=2.1, dt=dt)
    if name == "nonminimum_phase":
        return control.ss(control.c2d(control.tf([-2.42 / 1.2, 2.42], np.polymul([1, 1.1], [1, 2.2])), dt))
    if name == "three_disk_y3":
        return three_disk("y3", dt=dt, params=dataclasses.replace(THREE_DISK, omega_p1=THREE_DISK.omega_p1 * 1.05))
    raise KeyError(name)


@dataclass(frozen=True)
class PlantSetup:
    """One plant of the comparison: the true plant, its weights and its experiment."""

    factory: object
    horizon: int            # model-free horizon (§5.4 / §6.2)
    process_noise: float
    sensor_noise: float
    lengths: tuple          # full run
    quick_length: int
    step_seconds: float
    prbs_bits: int | None   # None: a seeded PRBS; else the periodic max-length sequence of §6.2
    weights: str            # "servo" (§5.4 W11/W21) or "noncollocated" (§6.2)

    def plant_and_weights(self):
        P = self.factory()
        if self.weights == "servo":
            W = design_weights(float(P.dt))
            return P, W["W11"], W["W21"]
        W1, W2 = torsional_weights(self.weights, float(P.dt))
        return P, W1, W2


PLANTS = {
    "servo": PlantSetup(servo, 20, 0.05, 0.05, (500, 1000, 2000), 1000, 20.0, None, "servo"),
    "resonant": PlantSetup(resonant, 20, 0.05, 0.05, (500, 1000, 2000), 1000, 20.0, None, "servo"),
    "nonminimum_phase": PlantSetup(nonminimum_phase, 20, 0.05, 0.05, (500, 1000, 2000), 1000, 20.0, None, "servo"),
    "three_disk_y3": PlantSetup(lambda: three_disk("y3"), 64, 0.05, 0.01, (1024, 2048, 4096), 2048, 4.0, 10,
                                "noncollocated"),
}

#: length of the Fig. 6.6 step run (s): the model-based loop's unstable pole has modulus ≈ 1.003 (e-fold in ≈ 5 s)
FIG66_SECONDS = 15.0

#: robust pipeline size (as ``robust-pipeline``): horizon, (7.5) columns, held-out samples
ROBUST_SIZE = (10, 30, 500)


@dataclass(frozen=True)
class Config:
    plants: tuple = tuple(PLANTS)
    seeds: tuple = (0, 1, 2, 3, 4)
    quick: bool = False
    robust: bool = True

    @classmethod
    def quick_config(cls) -> "Config":
        return cls(plants=("servo", "nonminimum_phase", "three_disk_y3"), seeds=(0,), quick=True, robust=False)

    def lengths(self, plant: str) -> tuple:
        return (PLANTS[plant].quick_length,) if self.quick else PLANTS[plant].lengths


# ---------------------------------------------------------------------------------------------
def _ry(K, l: int):
    """A controller as inputs ``[r; y]``: error feedback ``u = K e`` becomes ``[K, −K]``."""
    K = control.ss(K)
    if K.ninputs == 2 * l:
        return K
    return control.ss(K.A, np.hstack([K.B, -K.B]), K.C, np.hstack([K.D, -K.D]), K.dt)


def evaluate(P, W1, W2, K, step_seconds: float) -> dict:
    """Judge a controller on the true plant ``P``.

    Parameters
    ----------
    P : control.StateSpace
        The true discrete plant (SISO).
    W1, W2 : discrete weights
        The design's weights (on ``e`` and ``u``).
    K : control.StateSpace
        Controller with inputs ``[r; y]`` or ``e = r − y``.
    step_seconds : float
        Length of the unit-step run.

    Returns
    -------
    dict
        ``stable``, ``spectral_radius``, ``weighted_norm`` (proven upper bound of the reference
        channel's ‖[W1 (1 − T_yr); W2 T_ur]‖∞, ∞ if unstable), ``feedback_weighted_norm`` (proven upper
        bound of the feedback loop's ‖[W1 S; W2 K_y S]‖∞, S = (I − P K_y)⁻¹; the same number for error
        feedback), ``additive_radius`` (1/‖K_y(I − P K_y)⁻¹‖∞ with its proven norm bound, 0 if unstable),
        ``rise_time_s``, ``overshoot`` (fraction), ``steady_state_error``.
    """
    l = P.noutputs
    K = _ry(K, l)
    cl = closed_loop_system(P, K)                           # r → [y; u]
    A = np.asarray(cl.A, float)
    rho = float(np.max(np.abs(np.linalg.eigvals(A)))) if A.size else 0.0
    out = {"stable": bool(rho < 1.0), "spectral_radius": rho, "weighted_norm": float("inf"),
           "feedback_weighted_norm": float("inf"), "additive_radius": 0.0, "rise_time_s": float("nan"),
           "overshoot": float("nan"), "steady_state_error": float("nan")}
    if not out["stable"]:
        return out
    dt = float(P.dt)
    out["weighted_norm"] = _reference_norm(cl, W1, W2, dt)
    Ky = K[:, l:]
    # a [r; y] controller's reference channel is not its loop's sensitivity: the loop is u = K_y y alone,
    # i.e. error feedback with −K_y (measured: servo, i = 20, 1.28 on r against 4.27 on the loop)
    one_dof = np.allclose(K.B[:, :l], -K.B[:, l:]) and np.allclose(K.D[:, :l], -K.D[:, l:])
    out["feedback_weighted_norm"] = out["weighted_norm"] if one_dof else _reference_norm(
        closed_loop_system(P, _ry(-Ky, l)), W1, W2, dt)
    Kd = control.ss(Ky.A, np.hstack([Ky.B, Ky.B]), Ky.C, np.hstack([Ky.D, Ky.D]), dt)   # inputs [d; y]
    M = closed_loop_system(P, Kd)[l:, :]                   # d → u: K_y (I − P K_y)⁻¹
    peak = float(synthesis.hinf_norm(M).upper)
    out["additive_radius"] = 1.0 / peak if peak > 0 else float("inf")
    n = int(round(step_seconds / dt))
    Ad, Bd, Cd, Dd = (np.asarray(X, float) for X in control.ssdata(cl))
    x = np.zeros(Ad.shape[0])
    y = np.empty(n)
    for k in range(n):
        y[k] = Cd[0] @ x + Dd[0, 0]
        x = Ad @ x + Bd[:, 0]
    m = step_metrics(np.arange(n) * dt, y)
    out.update(rise_time_s=m["rise_time_s"], overshoot=m["overshoot"], steady_state_error=m["steady_state_error"])
    return out


def _reference_norm(cl, W1, W2, dt: float) -> float:
    """Proven upper bound of ‖[W1 e; W2 u]‖∞ from ``r`` of a SISO closed loop ``cl: r → [y; u]``."""
    sel = control.ss(np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((2, 0)), np.array([[1.0], [0.0]]), dt)
    mix = control.ss(np.zeros((0, 0)), np.zeros((0, 2)), np.zeros((2, 0)), np.array([[-1.0, 0.0], [0.0, 1.0]]), dt)
    E = sel + mix * cl                                      # r → [e; u]
    Z = control.append(control.ss(W1), control.ss(W2)) * E
    return float(synthesis.hinf_norm(Z).upper)


def _timed(fn):
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        value = fn()
    return value, time.perf_counter() - t0


def _experiment(setup: PlantSetup, P, n: int, seed: int):
    u = prbs(n, setup.prbs_bits) if setup.prbs_bits else prbs(n, seed=seed)
    return collect_data(P, u, process_noise=setup.process_noise, sensor_noise=setup.sensor_noise, seed=seed + 100)


def _robust(setup, P, W1, W2, data, seed):
    import unfalsify as uf

    i, j, held_n = ROBUST_SIZE
    u, y = data.u[:, 0], data.y[:, 0]
    held = collect_data(P, prbs(held_n, seed=seed + 50), process_noise=setup.process_noise,
                        sensor_noise=setup.sensor_noise, seed=seed + 150)
    n = 2 * i + j - 1
    pred = synthesis.fit_predictor(u, y, i)
    A, _, Yf = uf.subspace_data(u[:n], y[:n], i)
    rms = float(np.linalg.norm(Yf - np.hstack([pred.Lw, pred.Lu]) @ A) / np.sqrt(Yf.size))
    rd = uf.robust_design_from_data(u[:n], y[:n], i, W1, W2, 0.5 * rms, predictor=pred, dt=float(P.dt),
                                    predictor_for=lambda h: synthesis.fit_predictor(u, y, h),
                                    search=uf.DesignSearch(horizons=(2 * i,)),
                                    validation=(held.u[:, 0], held.y[:, 0]))
    return rd.controller, f"certified: {'yes' if rd.certified else 'no'}", bool(rd.certified)


def _mixsyn(model, W1, W2):
    return synthesis.discrete_mixsyn(model, W1, W2, gamma_ratio=MODEL_BASED_RATIO).controller


def _case(name: str, setup: PlantSetup, P, W1, W2, n: int, seed: int, cfg: Config) -> list[dict]:
    """Every data-based method on one experiment; one record per method."""
    dt = float(P.dt)
    data = _experiment(setup, P, n, seed)
    u, y = data.u, data.y
    i = setup.horizon
    recs = []

    def add(method, fn):
        try:
            (K, note, *extra), seconds = _timed(fn)
        except Exception as exc:  # a route that fails on these data is a result, not a crash
            recs.append({"plant": name, "n": n, "seed": seed, "method": method, "failed": True,
                         "note": f"{type(exc).__name__}: {exc}"[:200], "design_seconds": float("nan"),
                         **evaluate_failed()})
            return
        rec = {"plant": name, "n": n, "seed": seed, "method": method, "failed": False, "note": note,
               "design_seconds": seconds, **evaluate(P, W1, W2, K, setup.step_seconds)}
        if extra:
            rec["certified"] = extra[0]
        recs.append(rec)

    def mf(ratio):
        d = synthesis.hinf_design(synthesis.fit_predictor(u, y, i, dt=dt), W1, W2, gamma_ratio=ratio, dt=dt)
        return d.controller, f"i = {i}, γ_min = {d.gamma_min:.4g}"

    def auto(ratio):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", synthesis.HorizonChoiceWarning)  # the note below reports it
            c = synthesis.choose_horizon(u, y, W1, W2, dt=dt, gamma_ratio=ratio)
        note = "" if c.ok else " (no candidate passed the checks on the data's models)"
        return c.design.controller, f"i = {c.horizon}{note}"

    def arx(order):
        m = synthesis.arx_id(u, y, order=order, max_order=15, dt=dt)
        return _mixsyn(m.model, W1, W2), f"order {m.order}"

    def sid(order):
        m = synthesis.subspace_id(u, y, i, order=order, dt=dt)
        return _mixsyn(m.model, W1, W2), f"order {m.order}"

    add("mf_1.1", lambda: mf(1.1))
    add("mf_1.35", lambda: mf(1.35))
    add("mf_auto", lambda: auto(1.1))
    add("mf_auto_1.35", lambda: auto(1.35))
    if cfg.robust:
        add("mf_robust", lambda: _robust(setup, P, W1, W2, data, seed))
    add("arx_aic", lambda: arx("aic"))
    add("arx_val", lambda: arx("validation"))
    add("sid_floor", lambda: sid("floor"))
    add("sid_val", lambda: sid("validation"))
    add("sid_true", lambda: sid(P.nstates))
    return recs


def evaluate_failed() -> dict:
    return {"stable": False, "spectral_radius": float("nan"), "weighted_norm": float("inf"),
            "feedback_weighted_norm": float("inf"), "additive_radius": 0.0,
            "rise_time_s": float("nan"), "overshoot": float("nan"), "steady_state_error": float("nan")}


def _per_plant(name, setup, P, W1, W2) -> list[dict]:
    """The physics model and the ideal: no data, once per plant."""
    dt = float(P.dt)
    recs = []
    for method, model, note in (("physics", _physics(name, dt), PHYSICS_ERRORS[name]), ("ideal", P, "true plant")):
        K, seconds = _timed(lambda: _mixsyn(model, W1, W2))
        recs.append({"plant": name, "n": 0, "seed": -1, "method": method, "failed": False, "note": note,
                     "design_seconds": seconds, **evaluate(P, W1, W2, K, setup.step_seconds)})
    return recs


# ---------------------------------------------------------------------------------------------
def _median(values):
    v = [x for x in values if x is not None and math.isfinite(x)]
    return float(np.median(v)) if v else float("nan")


def aggregate(records: list[dict]) -> list[dict]:
    """Per plant × method: stable runs, medians over the stable runs, radius relative to the ideal."""
    ideal = {r["plant"]: r["additive_radius"] for r in records if r["method"] == "ideal"}
    out = []
    for plant in dict.fromkeys(r["plant"] for r in records):
        for method in METHODS:
            rs = [r for r in records if r["plant"] == plant and r["method"] == method]
            if not rs:
                continue
            st = [r for r in rs if r["stable"]]
            rad = _median([r["additive_radius"] for r in st])
            cert = [r for r in rs if "certified" in r]
            out.append({"plant": plant, "method": method, "runs": len(rs), "stable": len(st),
                        "failed": sum(r["failed"] for r in rs),
                        "certified": sum(r["certified"] for r in cert) if cert else None,
                        "certified_unstable": sum(r["certified"] and not r["stable"] for r in cert) if cert else None,
                        "weighted_norm": _median([r["weighted_norm"] for r in st]),
                        "feedback_weighted_norm": _median([r["feedback_weighted_norm"] for r in st]),
                        "additive_radius": rad,
                        "radius_vs_ideal": rad / ideal[plant] if ideal.get(plant) else float("nan"),
                        "rise_time_s": _median([r["rise_time_s"] for r in st]),
                        "overshoot_pct": 100 * _median([r["overshoot"] for r in st]),
                        "design_seconds": _median([r["design_seconds"] for r in rs])})
    return out


def by_length(records: list[dict]) -> list[dict]:
    """Per plant × method × data length: stable runs and median radius (data-based methods only)."""
    out = []
    for plant in dict.fromkeys(r["plant"] for r in records):
        lengths = sorted({r["n"] for r in records if r["plant"] == plant and r["n"] > 0})
        for method in METHODS:
            cells = []
            for n in lengths:
                rs = [r for r in records if r["plant"] == plant and r["method"] == method and r["n"] == n]
                if not rs:
                    break
                st = [r for r in rs if r["stable"]]
                cells.append({"n": n, "stable": len(st), "runs": len(rs),
                              "additive_radius": _median([r["additive_radius"] for r in st])})
            if cells:
                out.append({"plant": plant, "method": method, "cells": cells})
    return out


def verdicts(agg: list[dict]) -> list[str]:
    """Where each method wins and loses, in words, from the aggregate table (nothing hard-coded)."""
    lines = []
    for plant in dict.fromkeys(a["plant"] for a in agg):
        rows = {a["method"]: a for a in agg if a["plant"] == plant}
        data_based = {k: v for k, v in rows.items() if k not in ("ideal", "physics")}
        always = [k for k, v in data_based.items() if v["stable"] == v["runs"]]
        best = max(always, key=lambda k: data_based[k]["additive_radius"]) if always else None
        mf = rows.get("mf_1.1")
        itd = [k for k in always if k.startswith(("arx", "sid"))]
        best_itd = max(itd, key=lambda k: data_based[k]["additive_radius"]) if itd else None
        text = f"**{plant}**: "
        ideal = rows.get("ideal")
        if best:
            b = data_based[best]
            text += (f"largest median robustness radius among the always-stable data-based methods: "
                     f"{METHODS[best]} ({b['additive_radius']:.3g}, {b['radius_vs_ideal']:.2f}× the ideal's; "
                     f"loop ‖[W1 S; W2 K_y S]‖∞ {b['feedback_weighted_norm']:.3g}"
                     + (f" vs the ideal's {ideal['feedback_weighted_norm']:.3g}" if ideal else "") + "). ")
        else:
            text += "no data-based method was stable in every run. "
        if mf is not None:
            text += f"Model-free nominal (1.1) stable in {mf['stable']}/{mf['runs']}"
            if best_itd and mf["stable"]:
                ratio = data_based[best_itd]["additive_radius"] / mf["additive_radius"]
                text += (f"; the best always-stable identify-then-design route ({METHODS[best_itd]}) has "
                         f"{ratio:.2g}× its radius")
            text += ". "
        rob = rows.get("mf_robust")
        if rob is not None and rob["certified"] is not None:
            text += (f"The robust pipeline certified {rob['certified']}/{rob['runs']} runs; certified but unstable "
                     f"on the true plant: {rob['certified_unstable']}. ")
        unstable = [f"{METHODS[k]} ({v['runs'] - v['stable']}/{v['runs']}"
                    + (f", {v['failed']} of them no design" if v["failed"] else "") + ")"
                    for k, v in rows.items() if v["stable"] < v["runs"]]
        text += ("Unstable on the true plant (or no controller designed) in some runs: " + "; ".join(unstable) + "."
                 if unstable else "Every method was stable in every run.")
        lines.append(text)
    return lines


# ---------------------------------------------------------------------------------------------
def _fig66(out: Path, seed: int, quick: bool) -> tuple[dict, dict]:
    """Figs. 6.6/6.7: physics model 5 % off at the first resonance vs the model-free loop (§6.2)."""
    setup = PLANTS["three_disk_y3"]
    P, W1, W2 = setup.plant_and_weights()
    dt = float(P.dt)
    data = _experiment(setup, P, 2048, seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sub = synthesis.hinf_design(synthesis.fit_predictor(data.u, data.y, 64, dt=dt), W1, W2, gamma_ratio=1.35,
                                    dt=dt)
        model = synthesis.discrete_mixsyn(_physics("three_disk_y3", dt), W1, W2, gamma_ratio=1.35)
    ev_sub = evaluate(P, W1, W2, sub.controller, setup.step_seconds)
    ev_model = evaluate(P, W1, W2, model.controller, setup.step_seconds)
    cl_model = closed_loop_system(P, _ry(model.controller, 1))
    ev = np.linalg.eigvals(np.asarray(cl_model.A, float))
    worst = ev[np.argmax(np.abs(ev))]
    # scan: which few-percent errors of the physics model break the loop
    scan = []
    for param in ("omega_p1", "omega_z1", "omega_p2"):
        for pct in ((-5, 5) if quick else (-5, -3, 3, 5, 10)):
            Pm = three_disk("y3", dt=dt, params=dataclasses.replace(
                THREE_DISK, **{param: getattr(THREE_DISK, param) * (1 + pct / 100)}))
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                Km = synthesis.discrete_mixsyn(Pm, W1, W2, gamma_ratio=1.35).controller
            cl = closed_loop_system(P, _ry(Km, 1))
            rho = float(np.max(np.abs(np.linalg.eigvals(np.asarray(cl.A, float)))))
            scan.append({"parameter": param, "error_pct": pct, "spectral_radius": rho, "stable": rho < 1})
    # step responses on the true plant, long enough to show the slow growth of the unstable loop
    n = int(round(FIG66_SECONDS / dt))
    ys = {}
    for key, K in (("model-free (i = 64, 1.35 γ_min)", sub.controller),
                   ("model-based on the physics model (ω_p1 +5 %)", model.controller)):
        cl = closed_loop_system(P, _ry(K, 1))
        ys[key] = control.forced_response(cl, T=np.arange(n) * dt, U=np.ones(n)).outputs[0]
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = np.arange(n) * dt
    fig, ax = plt.subplots(figsize=(8, 4))
    ax.plot(t, np.ones(n), "k--", lw=0.8, label="r")
    for key, yv in ys.items():
        ax.plot(t, np.clip(yv, -3, 3), label=key)
    ax.set_ylim(-3, 3)
    ax.set_xlabel("t (s)")
    ax.set_ylabel("y3 (rad), clipped to ±3")
    ax.set_title("Fig 6.6 (simulated): step on the true three-disk plant")
    ax.legend(fontsize=8)
    ax.grid(True, lw=0.3)
    f66 = save_figure(fig, out / "fig6_6_step.png")
    omega = np.logspace(-1, np.log10(np.pi / dt) - 1e-3, 300 if quick else 1000)
    Ks = np.asarray(control.frequency_response(sub.controller, omega, squeeze=False).frdata)
    Km = np.asarray(control.frequency_response(model.controller, omega, squeeze=False).frdata)
    curves = [("K_sub: u/(−y) (r = 0)", -Ks[0, 1]), ("K_model (physics, ω_p1 +5 %): u/e", Km[0, 0])]
    fig, axs = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    for label, h in curves:
        axs[0].semilogx(omega, 20 * np.log10(np.abs(h)), label=label)
        axs[1].semilogx(omega, np.degrees(np.unwrap(np.angle(h))), label=label)
    for w, style in ((THREE_DISK.omega_p1, ":"), (THREE_DISK.omega_p1 * 1.05, "-.")):
        for a in axs:
            a.axvline(w, color="gray", ls=style, lw=0.8)
    axs[0].set_ylabel("magnitude (dB)")
    axs[1].set_ylabel("phase (deg)")
    axs[1].set_xlabel("ω (rad/s); dotted: true ω_p1, dash-dot: the model's")
    axs[0].set_title("Fig 6.7: model-free vs model-based controller (feedback channels)")
    axs[0].legend(fontsize=8)
    for a in axs:
        a.grid(True, which="both", lw=0.3)
    f67 = save_figure(fig, out / "fig6_7_controllers.png")
    section = {"model_free": ev_sub, "model_based": ev_model, "gamma_min": float(sub.gamma_min),
               "gamma_opt_model": float(model.gamma_opt),
               "unstable_pole_rad_s": float(abs(np.angle(worst)) / dt), "unstable_pole_modulus": float(abs(worst)),
               "scan": scan, "physics_error": PHYSICS_ERRORS["three_disk_y3"]}
    return section, {"fig66": f66, "fig67": f67}


def _radius_figure(out: Path, agg: list[dict]):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    plants = list(dict.fromkeys(a["plant"] for a in agg))
    methods = [m for m in METHODS if any(a["method"] == m for a in agg)]
    fig, ax = plt.subplots(figsize=(12, 4.5))
    width = 0.8 / max(len(methods), 1)
    colors = plt.get_cmap("tab20").colors
    for k, m in enumerate(methods):
        for j, p in enumerate(plants):
            a = next((a for a in agg if a["plant"] == p and a["method"] == m), None)
            if a is None or not math.isfinite(a["radius_vs_ideal"]):
                continue
            always = a["stable"] == a["runs"]
            ax.bar(j + k * width, a["radius_vs_ideal"], width, color=colors[k % len(colors)],
                   hatch=None if always else "//", edgecolor="k" if not always else None, lw=0.3,
                   label=METHODS[m] if j == next(i for i, q in enumerate(plants) if any(
                       b["plant"] == q and b["method"] == m and math.isfinite(b["radius_vs_ideal"]) for b in agg))
                   else None)
    ax.axhline(1.0, color="k", lw=0.6, ls="--")
    ax.set_xticks(np.arange(len(plants)) + 0.4 - width / 2)
    ax.set_xticklabels(plants)
    ax.set_ylabel("median radius / ideal's (stable runs)")
    ax.set_xlabel("plant (hatched: unstable on the true plant in some runs; missing: in all)")
    ax.set_title("Additive robustness radius 1/‖K(I+PK)⁻¹‖∞ on the true plant, relative to the ideal design")
    ax.legend(fontsize=7, loc="center left", bbox_to_anchor=(1.0, 0.5))
    return save_figure(fig, out / "compare_radius.png")


# ---------------------------------------------------------------------------------------------
_AGG_HEADERS = ["plant", "method", "stable runs", "no design", "certified (unstable)",
                "median ‖[W1 e; W2 u]‖∞ from r", "median ‖[W1 S; W2 K_y S]‖∞ (loop)",
                "median radius 1/‖K(I+PK)⁻¹‖∞",
                "radius / ideal's", "median rise time (s)", "median overshoot (%)", "median design time (s)"]
_RUN_HEADERS = ["plant", "n", "seed", "method", "note", "stable", "spectral radius", "‖[W1 e; W2 u]‖∞ from r",
                "‖[W1 S; W2 K_y S]‖∞", "radius", "rise time (s)", "overshoot (%)", "ss error", "design time (s)"]


def run(opts) -> dict:
    """Run the comparison; write ``compare.md``, ``.json``, ``.csv`` and figures under ``opts.out``."""
    from tqdm import tqdm

    cfg = Config.quick_config() if opts.quick else Config()
    out = Path(opts.out)
    out.mkdir(parents=True, exist_ok=True)
    t_start = time.perf_counter()
    records: list[dict] = []
    cases = [(p, n, s + opts.seed) for p in cfg.plants for n in cfg.lengths(p) for s in cfg.seeds]
    built = {p: PLANTS[p].plant_and_weights() for p in cfg.plants}
    for p in cfg.plants:
        records += _per_plant(p, PLANTS[p], *built[p])
    for p, n, s in tqdm(cases, desc="compare", unit="case", leave=False):
        records += _case(p, PLANTS[p], *built[p], n, s, cfg)
    fig66, figs = _fig66(out, opts.seed, cfg.quick)
    agg = aggregate(records)
    lengths = by_length(records)
    wins = verdicts(agg)
    figs["radius"] = _radius_figure(out, agg)

    rep = Report("Model-free design against identify-then-design, judged on the true plant")
    rep.text(_intro(cfg))
    rep.section("Where each method wins and loses (from the table below)", "\n".join(f"- {w}" for w in wins))
    rep.section("Summary per plant and method")
    rep.table(_AGG_HEADERS, [[a["plant"], METHODS[a["method"]], f"{a['stable']}/{a['runs']}", a["failed"],
                              "–" if a["certified"] is None else f"{a['certified']} ({a['certified_unstable']})",
                              a["weighted_norm"], a["feedback_weighted_norm"],
                              a["additive_radius"], a["radius_vs_ideal"], a["rise_time_s"], a["overshoot_pct"],
                              a["design_seconds"]] for a in agg])
    rep.figure(figs["radius"], "Median additive robustness radius relative to the ideal design")
    rep.section("Stable runs and median radius by data length",
                "Each cell: stable runs / runs, median radius over the stable runs; n₁ < n₂ < n₃ are the plant's "
                "data lengths (in its name).")
    width = max((len(row["cells"]) for row in lengths), default=0)
    rows = []
    for row in lengths:
        ns = "/".join(str(c["n"]) for c in row["cells"])
        rows.append([f"{row['plant']} (n = {ns})", METHODS[row["method"]]] + [
            f"{c['stable']}/{c['runs']}, {c['additive_radius']:.3g}" for c in row["cells"]]
            + ["–"] * (width - len(row["cells"])))
    rep.table(["plant", "method"] + [f"n{chr(0x2081 + k)}" for k in range(width)], rows)
    rep.section("Physics models (stated parameter errors)",
                "\n".join(f"- {k}: {v}" for k, v in PHYSICS_ERRORS.items() if k in cfg.plants))
    _fig66_report(rep, fig66, figs)
    rep.section("Every run")
    run_rows = [[r["plant"], r["n"], r["seed"], r["method"], r["note"], r["stable"], r["spectral_radius"],
                 r["weighted_norm"], r["feedback_weighted_norm"], r["additive_radius"], r["rise_time_s"],
                 100 * r["overshoot"], r["steady_state_error"], r["design_seconds"]] for r in records]
    rep.table(_RUN_HEADERS, run_rows)
    write_csv(out / "compare.csv", _RUN_HEADERS, run_rows)
    summary = {"quick": bool(opts.quick), "seed": int(opts.seed), "plants": list(cfg.plants),
               "seeds": list(cfg.seeds), "lengths": {p: list(cfg.lengths(p)) for p in cfg.plants},
               "robust": ("run on every plant" if cfg.robust else
                          "skipped in --quick: seconds per run; python -m experiments robust-pipeline --quick runs it"),
               "physics_errors": {p: PHYSICS_ERRORS[p] for p in cfg.plants}, "aggregate": agg,
               "by_length": lengths, "verdicts": wins, "fig6_6": fig66, "runs": records}
    return finish_report(rep, summary, out, "compare", figures=figs.values(), t_start=t_start)


def _fig66_report(rep: Report, s: dict, figs: dict) -> None:
    mf, mb = s["model_free"], s["model_based"]
    rep.section("Thesis Figs. 6.6/6.7: the three-disk non-collocated plant (§6.2)")
    rep.text(f"Same 2048-sample experiment as `noncollocated`; model-free design at i = 64, γ = 1.35 γ_min "
             f"(γ_min = {s['gamma_min']:.3g}); model-based design (`discrete_mixsyn`, γ = 1.35 γ_opt, "
             f"γ_opt = {s['gamma_opt_model']:.3g}) on a physics model with {s['physics_error']}. On the true plant:")
    rep.table(["controller", "stable", "max |closed-loop pole|", "‖[W1 e; W2 u]‖∞ from r",
               "‖[W1 S; W2 K_y S]‖∞", "radius", "rise time (s)"], [
        ["model-free", mf["stable"], f"{mf['spectral_radius']:.6f}", mf["weighted_norm"],
         mf["feedback_weighted_norm"], mf["additive_radius"], mf["rise_time_s"]],
        ["model-based (physics model)", mb["stable"], f"{mb['spectral_radius']:.6f}", mb["weighted_norm"],
         mb["feedback_weighted_norm"], mb["additive_radius"], mb["rise_time_s"]]])
    rep.text(f"\nThe model-based loop's largest pole: modulus {s['unstable_pole_modulus']:.5f} at "
             f"{s['unstable_pole_rad_s']:.1f} rad/s (thesis, hardware: oscillation near 13 rad/s). "
             "Which few-percent errors of the physics model break the loop (max |closed-loop pole| on the true plant):")
    rep.table(["parameter", "error (%)", "max |pole|", "stable"],
              [[r["parameter"], r["error_pct"], f"{r['spectral_radius']:.6f}", r["stable"]] for r in s["scan"]])
    rep.figure(figs["fig66"], "Fig 6.6: step responses on the true plant")
    rep.figure(figs["fig67"], "Fig 6.7: the two controllers' feedback channels (Bode)")


def _intro(cfg: Config) -> str:
    lines = [f"Plants {', '.join(cfg.plants)}; seeds {', '.join(map(str, cfg.seeds))}; data lengths "
             + "; ".join(f"{p}: {', '.join(map(str, cfg.lengths(p)))}" for p in cfg.plants) + "."]
    lines.append("10 Hz plants: PRBS ±1 (seeded), process and sensor noise σ = 0.05, §5.4 weights W11/W21, "
                 "model-free horizon i = 20. Three-disk (y3, 64 Hz): periodic 10-bit PRBS, σ = 0.05 V at the input "
                 "and 0.01 rad on the sensor, §6.2 weights, i = 64 (subspace identification uses the same i).")
    lines.append("Identify-then-design and the physics/ideal rows use `discrete_mixsyn` at "
                 f"γ = {MODEL_BASED_RATIO} γ_opt. "
                 "All numbers are measured on the true plant (proven upper bounds of the norms; medians over "
                 "the stable runs): 'radius' is 1/‖K_y(I − P K_y)⁻¹‖∞ (K_y the feedback channel); "
                 "‖[W1 e; W2 u]‖∞ from r is the reference channel the model-free design minimises, "
                 "‖[W1 S; W2 K_y S]‖∞ with S = (I − P K_y)⁻¹ the feedback loop's mixed sensitivity. The two "
                 "coincide for the error-feedback (model-based) controllers, not for the two-input [r; y] "
                 "model-free ones.")
    robust = (f"i = {ROBUST_SIZE[0]}, j = {ROBUST_SIZE[1]}, a held-out {ROBUST_SIZE[2]}-sample experiment, on every "
              "plant (on the three-disk plant i = 10 is a 0.16 s horizon; (7.5) near the §6.2 horizon, (i, j) = "
              "(50, 500), takes 21–35 s per solve in bench-unfalsify)." if cfg.robust else
              "skipped in --quick (seconds per run); `robust-pipeline --quick` runs it.")
    lines.append("Model-free robust (§7.4): " + robust)
    return "\n\n".join(lines)


def summary_lines(s: dict) -> list[str]:
    """Key numbers of a run (printed by ``python -m experiments compare``)."""
    lines = []
    for a in s["aggregate"]:
        if a["method"] in ("mf_1.1", "mf_auto", "sid_true", "arx_aic", "ideal"):
            lines.append(f"{a['plant']}: {METHODS[a['method']]}: stable {a['stable']}/{a['runs']}, "
                         f"median radius {a['additive_radius']:.3g}")
    f = s["fig6_6"]
    lines.append(f"Fig 6.6: model-free stable {f['model_free']['stable']}, physics-model design stable "
                 f"{f['model_based']['stable']}")
    return lines
