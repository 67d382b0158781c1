"""§5.4 design example: the effect of ``W1, W2, i, j, γ`` on the servo (5.5)/(5.6).

One noisy data set (PRBS ±1, process noise σ = 0.05 at the plant input, sensor noise
σ = 0.05) serves every design, as in the thesis; the closed-loop step responses are noise
free.  Writes ``design_example.md``, the figures (Figs 5.2–5.12), ``design_example.json``
and one CSV per table under ``--out``.

Tables: 5.1 (weights; thesis values printed beside ours, plus the spread of γ_min over
data seeds), 5.2 (i, j fixed), 5.3 (i, n fixed; i = 300 is underdetermined), 5.4 (j),
5.5 (γ/γ_min), and a step-metrics table for every closed loop (diverging loops are
reported "unstable", from the closed-loop eigenvalues, and clipped in the plots).
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import control
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from tqdm import tqdm  # noqa: E402

from synthesis import InfeasibleGammaError, fit_predictor, gamma_min, hinf_design  # noqa: E402

from ..lab.plants import SERVO_DT, servo  # noqa: E402
from ..lab.report import Report, finish_report, save_figure, write_csv  # noqa: E402
from ..lab.servo_setup import (  # noqa: E402
    DESIGNS,
    THESIS_TABLE_5_1,
    StepResult,
    continuous_weights,
    design_weights,
    plot_steps,
    collect_warnings,
    servo_data,
    step_metrics_rows,
    step_response,
)

__all__ = ["run", "Config", "NOMINAL_I", "NOMINAL_J", "NOMINAL_N"]

NOMINAL_I = 20
NOMINAL_J = 1000
NOMINAL_N = 2 * NOMINAL_I + NOMINAL_J - 1  # 1039
#: Table 5.5's thesis values: γ/γ_min -> γ
THESIS_TABLE_5_5 = {1e10: 8.80e9, 2.0: 1.760, 1.5: 1.320, 1.1: 0.968, 1.0268: 0.903}


@dataclass(frozen=True)
class Config:
    """Sweep sizes (the thesis's, or a reduced set for ``--quick``)."""

    horizons: tuple = (300, 80, 25, 20, 13, 10, 8)
    columns: tuple = (8000, 1000, 100, 75, 60)
    ratios: tuple = (1e10, 2.0, 1.5, 1.1, 1.0268)
    seeds: int = 20  # data seeds for the Table 5.1 spread
    noise_free_horizon: int = 300  # Fig. 5.10
    step_horizon_omit: tuple = (300,)  # the thesis omits i = 300 from Figs 5.5-5.8
    n_steps: int = 300  # 30 s step responses

    @classmethod
    def quick(cls) -> "Config":
        return cls(horizons=(20, 8), columns=(1000, 100), ratios=(2.0, 1.1, 1.0268), seeds=5,
                   noise_free_horizon=20, step_horizon_omit=())

    @property
    def n_total(self) -> int:
        """Length of the one data set: the longest any case needs (always the full sweep's)."""
        full = Config()
        return max(2 * max(full.horizons) + NOMINAL_J - 1, 2 * NOMINAL_I + max(full.columns) - 1)


# ---------------------------------------------------------------------------------------------
@dataclass
class Case:
    """One design of a sweep: data size, γ rule, outcome."""

    label: str
    i: int
    j: int
    gamma_min: float = float("nan")
    gamma: float = float("nan")
    note: str = ""
    design: object = None
    step: StepResult | None = None

    @property
    def n(self) -> int:
        return 2 * self.i + self.j - 1

    @property
    def ok(self) -> bool:
        return self.design is not None


def _fit(data, i: int, j: int, *, clean: bool = False):
    """Predictor from the first n = 2i + j − 1 samples; None with a reason if underdetermined."""
    n_reg = 3 * i  # i(2m + l), SISO
    if j < n_reg:
        return None, (f"not possible: underdetermined (j = {j} columns < i(2m+l) = {n_reg} regressors)")
    key = (id(data), i, j, clean)
    if key not in _PREDICTORS:
        n = 2 * i + j - 1
        u = data.u[:n]
        y = data.y_clean[:n] if clean else data.y[:n]
        _PREDICTORS[key] = fit_predictor(u, y, i)
    return _PREDICTORS[key], ""


#: predictors fitted during one run (the sweeps share i = 300, j = 1000 etc.); cleared by run()
_PREDICTORS: dict = {}


def _make_case(label, data, i, j, W1, W2, plant, n_steps, *, gamma=None, ratio=1.1, clean=False,
               simulate=True) -> Case:
    case = Case(label, i, j)
    pred, why = _fit(data, i, j, clean=clean)
    if pred is None:
        case.note = why
        return case
    case.gamma_min = gamma_min(pred, W1, W2)
    try:
        case.design = hinf_design(pred, W1, W2, gamma=gamma, gamma_ratio=ratio)
    except InfeasibleGammaError:
        case.gamma = float(gamma)
        case.note = f"not possible: γ = {gamma:g} ≤ γ_min = {case.gamma_min:.4g}"
        return case
    case.gamma = case.design.gamma
    if simulate:
        case.step = step_response(plant, case.design.controller, n_steps)
    return case


# ---------------------------------------------------------------------------------------------
def run(opts) -> dict:
    """Run the §5.4 design example; write the report under ``opts.out``; return a summary."""
    cfg = Config.quick() if opts.quick else Config()
    _PREDICTORS.clear()
    out = Path(opts.out)
    out.mkdir(parents=True, exist_ok=True)
    t_start = time.perf_counter()
    W = design_weights()
    plant = servo()
    data = servo_data(cfg.n_total, seed=opts.seed)
    W1, W2 = W["W11"], W["W21"]
    rep = Report("§5.4 design example: servo 1/(s(s+1)) at 10 Hz")
    rep.text(
        f"Data: one open-loop experiment of {data.n} samples (PRBS ±1, unity power; white Gaussian process "
        f"noise σ = {data.sigma_process} at the plant input and sensor noise σ = {data.sigma_sensor}; "
        f"seed {opts.seed}). Each design uses its first n = 2i + j − 1 samples. Nominal design i = {NOMINAL_I}, "
        f"j = {NOMINAL_J}, γ = 1.1 γ_min, W1 = W11, W2 = W21 (the OCR's `0.01/s` read as `0.01/5`, Tustin at 10 Hz). "
        "Closed-loop step responses are noise free; a loop is marked unstable when the spectral radius of "
        "its closed-loop state matrix is ≥ 1." + (" **Quick mode: reduced sweeps.**" if opts.quick else ""))
    summary: dict = {"seed": opts.seed, "quick": bool(opts.quick), "n_data": data.n}
    all_steps: dict[str, StepResult] = {}
    figures: list[str] = []
    warn_log: list[str] = []

    with collect_warnings() as log:
        # ---- Figs 5.2, 5.3 -------------------------------------------------------------
        figures.append(_fig_data(data, out))
        figures.append(_fig_weights(W, out))
        rep.section("Data and weights (Figs 5.2, 5.3)")
        rep.table(["weight", "continuous DC gain", "continuous high-frequency gain"],
                  [[k, dc, hf] for k, (dc, hf) in _continuous_dc_gains().items()])
        rep.figure(out / "fig5_2_data.png", "Fig. 5.2: output data (first n = 1039 samples)")
        rep.figure(out / "fig5_3_weights.png", "Fig. 5.3: inverse discrete weights |1/W(e^{jωT})|")

        # ---- Table 5.1, Fig 5.4 ---------------------------------------------------------
        t51, spread, steps51 = _table_5_1(data, W, plant, cfg, opts.seed)
        all_steps.update({f"T5.1 {k}": v for k, v in steps51.items()})
        summary["table_5_1"] = t51
        summary["table_5_1_seed_spread"] = spread
        rep.section("Table 5.1: weights (i = 20, j = 1000)")
        rep.table(["design", "W1", "W2", "γ_min (ours)", "γ_min (thesis)", "rel. diff", "γ = 1.1 γ_min (ours)",
                   "γ (thesis)"],
                  [[d, r["W1"], r["W2"], r["gamma_min"], r["thesis_gamma_min"],
                    f"{100 * r['rel_diff']:+.1f} %", r["gamma"], r["thesis_gamma"]] for d, r in t51.items()])
        rep.text(f"\nSpread of γ_min over {cfg.seeds} data seeds (seed {opts.seed} … {opts.seed + cfg.seeds - 1}; "
                 "same PRBS length and noise levels):\n")
        rep.table(["design", "mean", "std", "min", "max", "thesis"],
                  [[d, s["mean"], s["std"], s["min"], s["max"], THESIS_TABLE_5_1[d][0]] for d, s in spread.items()])
        fig, ax = plt.subplots(figsize=(7, 4))
        plot_steps(ax, steps51, "Fig. 5.4: step responses for W1, W2 designs")
        figures.append(str(save_figure(fig, out / "fig5_4_steps_weights.png")))
        rep.figure(out / "fig5_4_steps_weights.png", "Fig. 5.4: step responses for the three weight designs")
        write_csv(out / "table5_1.csv", ["design", "W1", "W2", "gamma_min", "thesis_gamma_min", "gamma",
                                         "thesis_gamma"],
                  [[d, r["W1"], r["W2"], r["gamma_min"], r["thesis_gamma_min"], r["gamma"], r["thesis_gamma"]]
                   for d, r in t51.items()])

        # ---- Tables 5.2, 5.3 (i sweeps), Figs 5.5-5.8 -------------------------------------
        n_fixed = NOMINAL_N
        sweeps = {
            "j": [(i, NOMINAL_J) for i in cfg.horizons],
            "n": [(i, n_fixed + 1 - 2 * i) for i in cfg.horizons],
        }
        i_cases: dict[str, dict[str, list[Case]]] = {}
        jobs = [(key, rule, i, j) for key, ij in sweeps.items() for rule in ("ratio", "gamma") for i, j in ij]
        for key, rule, i, j in tqdm(jobs, desc="i sweeps", leave=False):
            case = _make_case(f"i = {i}", data, i, j, W1, W2, plant, cfg.n_steps,
                              gamma=1.1 if rule == "gamma" else None)
            i_cases.setdefault(key, {}).setdefault(rule, []).append(case)
        for key, table, fa, fb, what in (("j", "5.2", "5_5", "5_6", f"j = {NOMINAL_J} fixed"),
                                         ("n", "5.3", "5_7", "5_8", f"n = {n_fixed} fixed")):
            ratio_cases, gamma_cases = i_cases[key]["ratio"], i_cases[key]["gamma"]
            rows = [[c.label, c.j, c.n, _num(c.gamma_min), _num(c.gamma) if c.ok else c.note,
                     _verdict(c) if c.ok else "—", _verdict(g) if c.ok else "—"]
                    for c, g in zip(ratio_cases, gamma_cases)]
            rep.section(f"Table {table}: γ_min, γ for various i ({what})")
            rep.table(["i", "j", "n", "γ_min", "γ = 1.1 γ_min", "closed loop (γ = 1.1 γ_min)",
                       "closed loop (γ = 1.1)"], rows)
            summary[f"table_{table.replace('.', '_')}"] = [_case_json(c) for c in ratio_cases]
            summary[f"table_{table.replace('.', '_')}_gamma_1_1"] = [_case_json(c) for c in gamma_cases]
            write_csv(out / f"table{table.replace('.', '_')}.csv", ["i", "j", "n", "gamma_min", "gamma", "note"],
                      [[c.i, c.j, c.n, c.gamma_min, c.gamma, c.note] for c in ratio_cases])
            for cases, fnum, title in ((ratio_cases, fa, "constant γ/γ_min = 1.1"),
                                       (gamma_cases, fb, "constant γ = 1.1")):
                steps = {c.label: c.step for c in cases if c.step is not None and c.i not in cfg.step_horizon_omit}
                all_steps.update({f"T{table} {c.label}, {title}": c.step for c in cases if c.step is not None})
                fig, ax = plt.subplots(figsize=(7, 4))
                plot_steps(ax, steps, f"Fig. {fnum.replace('_', '.')}: various i, {title}, {what}")
                name = f"fig{fnum}_steps_i_{key}_{'ratio' if cases is ratio_cases else 'gamma'}.png"
                figures.append(str(save_figure(fig, out / name)))
                rep.figure(out / name, f"Fig. {fnum.replace('_', '.')}: step responses, various i, {title}, {what}")
            omitted = [c.label for c in ratio_cases if c.ok and c.i in cfg.step_horizon_omit]
            if omitted:
                rep.text(f"({', '.join(omitted)} omitted from the step figures, as in the thesis; its metrics are in the "
                         "step-metrics table.)")

        # ---- Figs 5.9, 5.10 (pole-zero loci) ---------------------------------------------
        pz_cases = [c for c in i_cases["j"]["ratio"] if c.ok]
        figures.append(_fig_pz(pz_cases, out / "fig5_9_pz_i.png", "Fig. 5.9: controller poles (x) and zeros (o)"))
        rep.section("Controller pole-zero loci (Figs 5.9, 5.10)")
        rep.text("Poles and zeros of the controller's feedback channel y → u (the r → u channel has the same "
                 "poles).")
        rep.figure(out / "fig5_9_pz_i.png", "Fig. 5.9: pole and zero locations for various i (j = 1000)")
        i_nf = cfg.noise_free_horizon
        noisy = next((c for c in pz_cases if c.i == i_nf), None) or _make_case(
            f"i = {i_nf}", data, i_nf, NOMINAL_J, W1, W2, plant, cfg.n_steps, simulate=False)
        clean = _make_case(f"i = {i_nf}, noise-free data", data, i_nf, NOMINAL_J, W1, W2, plant, cfg.n_steps,
                           simulate=False, clean=True)
        noisy_lbl = Case(f"i = {i_nf}, noisy data", noisy.i, noisy.j, design=noisy.design)
        figures.append(_fig_pz([noisy_lbl, clean], out / "fig5_10_pz_noise.png",
                               f"Fig. 5.10: noise and pole-zero convergence, i = {i_nf}"))
        rep.figure(out / "fig5_10_pz_noise.png",
                   f"Fig. 5.10: i = {i_nf}, noisy vs noise-free data (γ_min {noisy.gamma_min:.4g} vs "
                   f"{clean.gamma_min:.4g})")
        summary["pole_zero"] = {c.label: _pz_stats(c.design) for c in pz_cases + [clean] if c.ok}
        rep.text("Poles at the origin are the y_p delay line of (5.3) (an FIR action on y). For the other poles: "
                 "their median radius and the distance to the nearest zero (small = a nearly cancelling pair, "
                 "removable by order reduction). The roots of these high-degree controllers are numerically "
                 "sensitive (clusters of roots of a degree-600 polynomial), so read the loci qualitatively.\n")
        rep.table(["design", "controller order", "poles at 0", "max \\|pole\\|", "median \\|other pole\\|",
                   "median pole-zero distance", "other poles with a zero within 0.03"],
                  [[k, v["order"], v["poles_at_origin"], v["max_abs_pole"], v["median_abs_other_pole"],
                    v["median_pz_distance"], f"{100 * v['share_within_0.03']:.0f} %"]
                   for k, v in summary["pole_zero"].items()])

        # ---- Table 5.4, Fig 5.11 ---------------------------------------------------------
        j_cases = [_make_case(f"j = {j}", data, NOMINAL_I, j, W1, W2, plant, cfg.n_steps)
                   for j in tqdm(cfg.columns, desc="j sweep", leave=False)]
        rep.section(f"Table 5.4: γ_min, γ for various j (i = {NOMINAL_I})")
        rep.table(["j", "n", "γ_min", "γ = 1.1 γ_min", "closed loop"],
                  [[c.label, c.n, _num(c.gamma_min), _num(c.gamma) if c.ok else c.note, _verdict(c)]
                   for c in j_cases])
        summary["table_5_4"] = [_case_json(c) for c in j_cases]
        write_csv(out / "table5_4.csv", ["i", "j", "n", "gamma_min", "gamma", "note"],
                  [[c.i, c.j, c.n, c.gamma_min, c.gamma, c.note] for c in j_cases])
        all_steps.update({f"T5.4 {c.label}": c.step for c in j_cases if c.step is not None})
        fig, ax = plt.subplots(figsize=(7, 4))
        plot_steps(ax, {c.label: c.step for c in j_cases if c.step is not None},
                   "Fig. 5.11: various j (i = 20, γ = 1.1 γ_min)")
        figures.append(str(save_figure(fig, out / "fig5_11_steps_j.png")))
        rep.figure(out / "fig5_11_steps_j.png", "Fig. 5.11: step responses for various j")

        # ---- Table 5.5, Fig 5.12 ---------------------------------------------------------
        g_cases = [_make_case(f"γ/γ_min = {r:g}", data, NOMINAL_I, NOMINAL_J, W1, W2, plant, cfg.n_steps, ratio=r)
                   for r in tqdm(cfg.ratios, desc="γ sweep", leave=False)]
        rep.section("Table 5.5: γ/γ_min and γ (nominal design)")
        rep.table(["γ/γ_min", "γ (ours)", "γ (thesis)", "closed loop"],
                  [[f"{r:g}", c.gamma, THESIS_TABLE_5_5.get(r, "—"), _verdict(c)] for r, c in zip(cfg.ratios, g_cases)])
        summary["table_5_5"] = [dict(_case_json(c), ratio=r, thesis_gamma=THESIS_TABLE_5_5.get(r))
                                for r, c in zip(cfg.ratios, g_cases)]
        write_csv(out / "table5_5.csv", ["ratio", "gamma", "thesis_gamma", "stable"],
                  [[r, c.gamma, THESIS_TABLE_5_5.get(r, ""), c.step.stable if c.step else ""]
                   for r, c in zip(cfg.ratios, g_cases)])
        all_steps.update({f"T5.5 {c.label}": c.step for c in g_cases if c.step is not None})
        fig, ax = plt.subplots(figsize=(7, 4))
        plot_steps(ax, {c.label: c.step for c in g_cases if c.step is not None}, "Fig. 5.12: various γ")
        figures.append(str(save_figure(fig, out / "fig5_12_steps_gamma.png")))
        rep.figure(out / "fig5_12_steps_gamma.png", "Fig. 5.12: step responses for various γ")

        warn_log = sorted({f"{w.category.__name__}: {str(w.message).splitlines()[0]}" for w in log})

    # ---- step metrics for every closed loop --------------------------------------------------
    headers, rows = step_metrics_rows(all_steps)
    rep.section("Step metrics of every closed loop (noise free, unit step, 30 s)")
    rep.table(headers, rows)
    write_csv(out / "step_metrics.csv", [h.replace("\\|", "|") for h in headers], rows)
    summary["step_metrics"] = {k: v.metrics() for k, v in all_steps.items()}
    _PREDICTORS.clear()
    return finish_report(rep, summary, out, "design_example", warn_log=warn_log, figures=figures, t_start=t_start,
                         warnings_heading="Warnings raised during the sweeps (expected)")


# ---------------------------------------------------------------------------------------------
def table_5_1(data, W, plant=None, n_steps: int = 300, simulate: bool = True) -> tuple[dict, dict]:
    """γ_min, γ = 1.1 γ_min of Designs 1–3 at i = 20, j = 1000 (and their step responses)."""
    u, y = data.u[:NOMINAL_N], data.y[:NOMINAL_N]
    pred = fit_predictor(u, y, NOMINAL_I)
    rows, steps = {}, {}
    for name, (w1, w2) in DESIGNS.items():
        des = hinf_design(pred, W[w1], W[w2])
        g_thesis, gam_thesis = THESIS_TABLE_5_1[name]
        rows[name] = {"W1": w1, "W2": w2, "gamma_min": des.gamma_min, "gamma": des.gamma,
                      "thesis_gamma_min": g_thesis, "thesis_gamma": gam_thesis,
                      "rel_diff": des.gamma_min / g_thesis - 1.0}
        if simulate:
            steps[name] = step_response(plant if plant is not None else servo(), des.controller, n_steps)
    return rows, steps


def _table_5_1(data, W, plant, cfg, seed):
    rows, steps = table_5_1(data, W, plant, cfg.n_steps)
    vals = {d: [] for d in DESIGNS}
    for s in tqdm(range(seed, seed + cfg.seeds), desc="Table 5.1 seeds", leave=False):
        d_s = data if s == seed else servo_data(cfg.n_total, seed=s)
        pred = fit_predictor(d_s.u[:NOMINAL_N], d_s.y[:NOMINAL_N], NOMINAL_I)
        for name, (w1, w2) in DESIGNS.items():
            vals[name].append(gamma_min(pred, W[w1], W[w2]))
    spread = {d: {"mean": float(np.mean(v)), "std": float(np.std(v, ddof=1)) if len(v) > 1 else 0.0,
                  "min": float(np.min(v)), "max": float(np.max(v)), "values": [float(x) for x in v]}
              for d, v in vals.items()}
    return rows, spread, steps


def _num(x):
    return x if np.isfinite(x) else "—"


def _verdict(c: Case) -> str:
    if not c.ok:
        return c.note or "—"
    if c.step is None:
        return "(not simulated)"
    return "stable" if c.step.stable else "**unstable**"


def _case_json(c: Case) -> dict:
    d = {"label": c.label, "i": c.i, "j": c.j, "n": c.n,
         "gamma_min": c.gamma_min if np.isfinite(c.gamma_min) else None,
         "gamma": c.gamma if np.isfinite(c.gamma) else None, "note": c.note}
    if c.step is not None:
        d["stable"] = c.step.stable
        d["spectral_radius"] = c.step.spectral_radius
    return d


def _feedback_channel(K: control.StateSpace) -> control.StateSpace:
    """The y → u channel of a controller with inputs [r; y]."""
    return control.ss(K.A, np.asarray(K.B)[:, 1:], K.C, np.asarray(K.D)[:, 1:], K.dt)


def _poles_zeros(design):
    Ky = _feedback_channel(design.controller)
    return np.linalg.eigvals(np.asarray(Ky.A)), np.asarray(control.zeros(Ky))


def _pz_stats(design) -> dict:
    """Pole-zero summary: poles at the origin (the y_p delay line), and for the others their radius and
    the distance to the nearest zero (small = a nearly cancelling pair, removable by order reduction)."""
    p, z = _poles_zeros(design)
    zf = z[np.isfinite(z)]
    at_origin = np.abs(p) < 1e-3
    other = p[~at_origin]
    dist = np.array([np.min(np.abs(zf - pk)) for pk in other]) if zf.size else np.zeros(0)
    return {"order": int(p.size), "n_zeros": int(zf.size), "poles_at_origin": int(np.count_nonzero(at_origin)),
            "max_abs_pole": float(np.max(np.abs(p))),
            "median_abs_other_pole": float(np.median(np.abs(other))) if other.size else float("nan"),
            "median_pz_distance": float(np.median(dist)) if dist.size else float("nan"),
            "share_within_0.03": float(np.mean(dist < 0.03)) if dist.size else float("nan")}


def _fig_pz(cases, path: Path, title: str) -> str:
    n = len(cases)
    cols = min(4, n)
    rows = -(-n // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(3.2 * cols, 3.2 * rows), squeeze=False)
    th = np.linspace(0, 2 * np.pi, 256)
    for ax, c in zip(axes.flat, cases):
        p, z = _poles_zeros(c.design)
        z = z[np.isfinite(z) & (np.abs(z) < 3)]
        ax.plot(np.cos(th), np.sin(th), color="0.6", lw=0.8, label="unit circle")
        ms = 4 if p.size < 100 else 2
        ax.plot(p.real, p.imag, "x", ms=ms, label="poles")
        ax.plot(z.real, z.imag, "o", ms=ms, mfc="none", mew=0.6, label="zeros")
        ax.set_aspect("equal")
        ax.set_xlim(-1.6, 1.6)
        ax.set_ylim(-1.6, 1.6)
        ax.set_title(c.label, fontsize=9)
        ax.set_xlabel("Re z (z-plane, dimensionless)", fontsize=8)
        ax.set_ylabel("Im z", fontsize=8)
        ax.grid(True, alpha=0.3)
    for ax in list(axes.flat)[n:]:
        ax.axis("off")
    axes.flat[0].legend(fontsize=7, loc="lower left")
    fig.suptitle(title)
    return str(save_figure(fig, path))


def _fig_data(data, out: Path) -> str:
    n = NOMINAL_N
    t = np.arange(n) * data.dt
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(8, 4.5), sharex=True, gridspec_kw={"height_ratios": [3, 1]})
    a1.plot(t, data.y[:n], lw=0.8, label="measured y (noisy)")
    a1.plot(t, data.y_clean[:n], lw=0.8, alpha=0.7, label="noise-free response")
    a1.set_ylabel("y (servo output)")
    a1.legend(fontsize=8)
    a1.set_title("Fig. 5.2: output data used for the design examples")
    a2.step(t, data.u[:n], where="post", lw=0.6)
    a2.set_ylabel("u (PRBS)")
    a2.set_xlabel("time (s)")
    return str(save_figure(fig, out / "fig5_2_data.png"))


def _fig_weights(W: dict, out: Path) -> str:
    w = np.logspace(-3, np.log10(np.pi / SERVO_DT), 400)
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 4))
    for ax, names in ((a1, ("W11", "W12")), (a2, ("W21", "W22"))):
        for name in names:
            mag = np.abs(np.asarray(W[name](np.exp(1j * w * SERVO_DT))).reshape(-1))
            ax.loglog(w, 1.0 / mag, label=f"1/{name}")
        ax.set_xlabel("ω (rad/s)")
        ax.set_ylabel("magnitude (absolute)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
    a1.set_title("inverse performance weights 1/W1")
    a2.set_title("inverse control weights 1/W2")
    fig.suptitle("Fig. 5.3: discrete-time weights (Tustin, 10 Hz), inverse magnitude")
    return str(save_figure(fig, out / "fig5_3_weights.png"))


def _continuous_dc_gains() -> dict:
    """DC and high-frequency gains of the continuous weights (report sanity line)."""
    return {k: (float(np.real(control.dcgain(v))), float(np.real(np.asarray(v(1e9j)).item())))
            for k, v in continuous_weights().items()}


def summary_lines(s: dict) -> list[str]:
    """Key numbers of a run (printed by ``python -m experiments design-example``)."""
    lines = ["Table 5.1   γ_min ours / thesis"]
    for name, r in s.get("table_5_1", {}).items():
        lines.append(f"  {name}: {r['gamma_min']:.3f} / {r['thesis_gamma_min']:.3f}  ({100 * r['rel_diff']:+.1f} %)")
    if s.get("warnings"):
        lines.append(f"{len(s['warnings'])} warning(s) raised, listed in the report")
    return lines
