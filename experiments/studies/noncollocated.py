"""§6.2: non-collocated off-line design on the three-disk plant (output ``y3``, 64 Hz).

Pipeline (``python -m experiments noncollocated``):

1. *Experiment* (Fig. 6.2): the ZOH model of ``P_{y3,u}`` at 64 Hz is driven by two cycles of a
   PRBS.  The thesis uses a 16 s PRBS (1024 samples); a maximum-length sequence has period
   ``2¹⁰ − 1 = 1023``, so we take the 10-bit sequence (±1 V) and repeat it periodically to
   ``n = 2048`` samples (two cycles plus two samples).  The real hardware's data are replaced by
   the model with modest noise: white Gaussian process noise σ = 0.05 V at the plant input and
   sensor noise σ = 0.01 rad on ``y3`` (the §6.3 sensor-noise level).
2. Subspace predictor with ``i = 64`` (``j = n − 2i + 1 = 1921``), weights of
   :data:`experiments.lab.torsional_setup.NONCOLLOCATED` (Fig. 6.3), ``γ_min`` (3.8) and the central
   controller (5.3)–(5.4) at ``γ = 1.35 γ_min`` (thesis: γ_min = 1.7, γ = 2.3 on real data).
3. Step response of that controller on the true (noise-free) plant: 10–90 % rise time, ringing
   frequency and steady-state error (thesis, Fig. 6.4: 0.11 s, 3.5 Hz, 18 %).
4. Model-based comparator: the discrete ∞-horizon H∞ mixed-sensitivity controller for the ZOH
   model with the same weights, ``γ_opt`` (thesis 2.24) and its controller at ``γ = 1.35 γ_opt``;
   its noise-free step response is ``y_ideal`` (Fig. 6.5).
5. Bode plots of both controllers (Fig. 6.7).  The subspace controller has two inputs ``[r; y]``
   (it is not a function of ``e = r − y`` alone, because ``y`` also enters its past-data state), so
   both of its channels are plotted: ``u/r`` (``y = 0``) and ``u/(−y)`` (``r = 0``); the model-based
   controller is an error-feedback ``u/e``.

``--quick`` runs the same pipeline with the same ``n`` and ``i`` (the whole design takes well under a
second) but skips the seed-robustness table and uses a coarser frequency grid: with ``i ≤ 40`` or
``n = 1024`` the design does not reliably stabilise the plant (measured: e.g. ``n = 1024, i = 24``
gave closed-loop spectral radii 1.003–1.019 for seeds 0–4), so a smaller problem would not test the
same thing.  The full run adds a table over :data:`N_SEEDS` noise seeds (γ_min spread, fraction of
designs that stabilise the true plant).
"""
from __future__ import annotations

import time
from pathlib import Path

import control as ct
import numpy as np

from synthesis.validation import DataError

from ..lab import simulate
from ..lab.plants import THREE_DISK_DT as DT
from ..lab.report import Report, save_figure, write_csv, write_json
from ..lab.torsional_setup import NONCOLLOCATED

__all__ = ["run", "step_metrics", "closed_loop_system", "THESIS"]

#: Values reported in thesis §6.2 (real hardware for the subspace design).
THESIS = {
    "gamma_min": 1.7,
    "gamma": 2.3,
    "gamma_opt_model": 2.24,
    "gamma_model": 3.0,
    "rise_time_s": 0.11,
    "ringing_hz": 3.5,
    "steady_state_error": 0.18,
}

PRBS_BITS = 10
PRBS_AMPLITUDE = 1.0  # V
PROCESS_NOISE = 0.05  # V, at the plant input
SENSOR_NOISE = 0.01  # rad, on y3
GAMMA_RATIO = 1.35
STEP_SECONDS = 4.0
N_SEEDS = 20


# ---------------------------------------------------------------------------------------------
def step_metrics(t, y, r: float = 1.0, settle_fraction: float = 0.25) -> dict:
    """Rise time, ringing frequency and steady-state error of a step response.

    Parameters
    ----------
    t, y : array_like, shape (n,)
        Time (s) and output of the response to a step of size ``r`` applied at ``t[0]``.
    r : float
        Step size.
    settle_fraction : float
        The final value ``y_∞`` is the mean of the last ``settle_fraction`` of the record.

    Returns
    -------
    dict
        ``final_value``; ``steady_state_error = (r − y_∞)/r``; ``rise_time_s``: time from 10 % to
        90 % of ``y_∞`` (first crossings); ``ringing_hz``: mean frequency of the oscillation of
        ``y − y_∞`` after the 90 % crossing, from its zero crossings (``nan`` with fewer than
        three); ``overshoot``: ``max(y)/y_∞ − 1``.  ``nan`` where undefined (unstable loop).
    """
    t = np.asarray(t, float).reshape(-1)
    y = np.asarray(y, float).reshape(-1)
    if t.shape != y.shape or t.size < 8:
        raise DataError("t and y must be 1-D arrays of the same length (>= 8 samples)")
    nan = float("nan")
    tail = y[int((1 - settle_fraction) * y.size):]
    yf = float(np.mean(tail))
    out = {"final_value": yf, "steady_state_error": (r - yf) / r, "rise_time_s": nan, "ringing_hz": nan,
           "overshoot": nan}
    if not np.all(np.isfinite(y)) or yf * r <= 0 or np.max(np.abs(y)) > 1e3 * abs(r):
        return out
    t10 = _first_crossing(t, y, 0.1 * yf)
    t90 = _first_crossing(t, y, 0.9 * yf)
    out["rise_time_s"] = t90 - t10
    out["overshoot"] = float(np.max(y) / yf - 1.0)
    after = t >= t90
    d = y[after] - yf
    tc = _zero_crossings(t[after], d)
    if tc.size >= 3:
        out["ringing_hz"] = float((tc.size - 1) / (2.0 * (tc[-1] - tc[0])))
    return out


def _first_crossing(t, y, level) -> float:
    idx = np.flatnonzero((y[:-1] - level) * (y[1:] - level) <= 0)
    idx = idx[(y[idx + 1] != y[idx]) | (y[idx] == level)]
    if idx.size == 0:
        return float("nan")
    k = idx[0]
    if y[k + 1] == y[k]:
        return float(t[k])
    return float(t[k] + (level - y[k]) * (t[k + 1] - t[k]) / (y[k + 1] - y[k]))


def _zero_crossings(t, d) -> np.ndarray:
    s = np.sign(d)
    idx = np.flatnonzero(s[:-1] * s[1:] < 0)
    return t[idx] - d[idx] * (t[idx + 1] - t[idx]) / (d[idx + 1] - d[idx])


def closed_loop_system(plant: ct.StateSpace, controller: ct.StateSpace) -> ct.StateSpace:
    """Closed loop ``r → [y; u]`` of a strictly proper plant and a controller (§6 plants are).

    The controller has inputs ``[r; y]`` (subspace controller, (5.3)–(5.4)) or ``e = r − y``
    (error feedback).  Used for closed-loop poles and for frequency responses of the weighted
    closed loop; the construction is :func:`experiments.simulate.closed_loop_system`.
    """
    if np.any(np.asarray(plant.D) != 0):
        raise DataError("closed_loop_system needs a strictly proper plant (D = 0)")
    return simulate.closed_loop_system(plant, controller)


def _weighted_norm_on_grid(plant, controller, W1, W2, omega) -> float:
    """``max_ω σ̄([W1 (1 − T_yr); W2 T_ur](e^{jωT}))``: the ∞-horizon level the loop achieves."""
    cl = closed_loop_system(plant, controller)
    G = _freq_response(cl, omega)  # (2, 1, nω): y/r, u/r
    z1 = _freq_response(W1, omega)[0, 0] * (1.0 - G[0, 0])
    z2 = _freq_response(W2, omega)[0, 0] * G[1, 0]
    return float(np.max(np.sqrt(np.abs(z1) ** 2 + np.abs(z2) ** 2)))


def _weighted_norm_bracket(plant, controller, W1, W2) -> str:
    """``‖[W1 (1 − T_yr); W2 T_ur]‖∞`` as a bracket with a proven upper side (:func:`synthesis.hinf_norm`)."""
    from synthesis import hinf_norm

    cl = closed_loop_system(plant, controller)
    z1 = ct.ss(W1) * (1 - cl[0, 0])
    z2 = ct.ss(W2) * cl[1, 0]
    Z = ct.append(z1, z2) * ct.ss(np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((2, 0)), np.ones((2, 1)), cl.dt)
    return str(hinf_norm(Z))


def _freq_response(sys, omega) -> np.ndarray:
    """Frequency response of a discrete system at ``e^{jωT}``, shape ``(outputs, inputs, len(omega))``."""
    return np.asarray(ct.frequency_response(sys, omega, squeeze=False).frdata)


# ---------------------------------------------------------------------------------------------
def _model_based(plant, W1, W2, ratio: float):
    """∞-horizon model-based discrete H∞ mixed-sensitivity design (helper of ``synthesis``)."""
    from synthesis import discrete_mixsyn

    design = discrete_mixsyn(plant, W1, W2, gamma_ratio=ratio)
    return design.gamma_opt, design


def _compute(opts):
    import synthesis

    from ..lab import plants, signals, simulate

    rng = np.random.default_rng(opts.seed)
    seeds = rng.integers(0, 2**31, size=2)
    n = 2048
    i = 64
    P = plants.three_disk("y3", dt=DT)
    W1, W2 = NONCOLLOCATED.discrete(DT)

    u = signals.prbs(n, PRBS_BITS, amplitude=PRBS_AMPLITUDE)
    data = simulate.collect_data(P, u, process_noise=PROCESS_NOISE, sensor_noise=SENSOR_NOISE, seed=int(seeds[0]))

    t0 = time.perf_counter()
    pred = synthesis.fit_predictor(data.u, data.y, i)
    sub = synthesis.hinf_design(pred, W1, W2, gamma_ratio=GAMMA_RATIO)
    t_sub = time.perf_counter() - t0

    t0 = time.perf_counter()
    gamma_opt, model = _model_based(P, W1, W2, GAMMA_RATIO)
    t_model = time.perf_counter() - t0

    n_step = int(round(STEP_SECONDS / DT))
    r = np.ones(n_step)
    res_sub = simulate.closed_loop(P, sub.controller, r)
    res_model = simulate.closed_loop(P, model.controller, r)
    return dict(P=P, W1=W1, W2=W2, data=data, n=n, i=i, pred=pred, sub=sub, t_sub=t_sub, gamma_opt=gamma_opt,
                model=model, t_model=t_model, res_sub=res_sub, res_model=res_model)


def _seed_spread(P, u, i, W1, W2, seeds) -> list[dict]:
    """γ_min and closed-loop spectral radius of the design for several noise realisations."""
    import synthesis
    from tqdm import tqdm

    from ..lab import simulate

    rows = []
    for seed in tqdm(seeds, desc="noncollocated: noise seeds", leave=False):
        d = simulate.collect_data(P, u, process_noise=PROCESS_NOISE, sensor_noise=SENSOR_NOISE, seed=int(seed))
        des = synthesis.hinf_design(synthesis.fit_predictor(d.u, d.y, i), W1, W2, gamma_ratio=GAMMA_RATIO)
        rho = _spectral_radius(closed_loop_system(P, des.controller))
        rows.append({"seed": int(seed), "gamma_min": float(des.gamma_min), "spectral_radius": rho})
    return rows


def _spectral_radius(sys) -> float:
    return float(np.max(np.abs(np.linalg.eigvals(np.asarray(sys.A, float)))))


def _slowest_time_constant(sys, dt: float) -> float:
    """``−dt / ln|λ|`` for the closed-loop pole of largest modulus (s); ``inf`` if unstable."""
    rho = _spectral_radius(sys)
    return float(-dt / np.log(rho)) if rho < 1 else float("inf")


def run(opts) -> dict:
    """Run the §6.2 experiment; write ``noncollocated.md``, figures, CSV/JSON/NPZ under ``opts.out``."""
    out = Path(opts.out)
    out.mkdir(parents=True, exist_ok=True)
    c = _compute(opts)
    P, sub, model = c["P"], c["sub"], c["model"]
    omega = np.logspace(-1, np.log10(np.pi / DT) - 1e-3, 300 if opts.quick else 1000)

    cl_sub = closed_loop_system(P, sub.controller)
    cl_model = closed_loop_system(P, model.controller)
    rho_sub = _spectral_radius(cl_sub)
    rho_model = _spectral_radius(cl_model)
    spread = [] if opts.quick else _seed_spread(P, c["data"].u, c["i"], c["W1"], c["W2"],
                                                 np.arange(N_SEEDS) + 1000 * (opts.seed + 1))
    hinf_sub = _weighted_norm_on_grid(P, sub.controller, c["W1"], c["W2"], omega) if rho_sub < 1 else float("inf")
    hinf_model = _weighted_norm_on_grid(P, model.controller, c["W1"], c["W2"], omega)

    m_sub = step_metrics(c["res_sub"].t, c["res_sub"].y[:, 0])
    m_ideal = step_metrics(c["res_model"].t, c["res_model"].y[:, 0])

    np.savez(
        out / "controllers.npz",
        dt=DT,
        K_sub_A=np.asarray(sub.controller.A), K_sub_B=np.asarray(sub.controller.B),
        K_sub_C=np.asarray(sub.controller.C), K_sub_D=np.asarray(sub.controller.D),
        K_model_A=np.asarray(model.controller.A), K_model_B=np.asarray(model.controller.B),
        K_model_C=np.asarray(model.controller.C), K_model_D=np.asarray(model.controller.D),
        gamma_sub=sub.gamma, gamma_model=model.gamma,
    )
    write_csv(out / "data.csv", ["t", "u", "y3"],
              np.column_stack([c["data"].t, c["data"].u[:, 0], c["data"].y[:, 0]]))
    write_csv(out / "step.csv", ["t", "r", "y_subspace", "y_ideal", "u_subspace", "u_ideal"],
              np.column_stack([c["res_sub"].t, c["res_sub"].r[:, 0], c["res_sub"].y[:, 0],
                               c["res_model"].y[:, 0], c["res_sub"].u[:, 0], c["res_model"].u[:, 0]]))

    figs = _figures(out, c, omega)

    summary = {
        "experiment": "noncollocated",
        "quick": bool(opts.quick),
        "seed": int(opts.seed),
        "n": c["n"],
        "i": c["i"],
        "j": int(c["pred"].n_columns),
        "predictor_rank": int(c["pred"].rank),
        "weights": NONCOLLOCATED.describe(),
        "noise": {"process_sigma_V": PROCESS_NOISE, "sensor_sigma_rad": SENSOR_NOISE},
        "prbs": {"nbits": PRBS_BITS, "period": 2**PRBS_BITS - 1, "amplitude_V": PRBS_AMPLITUDE},
        "subspace": {
            "gamma_min": float(sub.gamma_min),
            "gamma": float(sub.gamma),
            "controller_order": int(sub.controller.nstates),
            "closed_loop_spectral_radius": rho_sub,
            "slowest_time_constant_s": _slowest_time_constant(cl_sub, DT),
            "weighted_closed_loop_hinf_on_grid": hinf_sub,
            "weighted_closed_loop_hinf_bracket": (_weighted_norm_bracket(P, sub.controller, c["W1"], c["W2"])
                                                  if rho_sub < 1 else "inf (unstable)"),
            "step": m_sub,
            "design_seconds": c["t_sub"],
        },
        "model_based": {
            "gamma_opt": float(c["gamma_opt"]),
            "gamma": float(model.gamma),
            "controller_order": int(model.controller.nstates),
            "closed_loop_spectral_radius": rho_model,
            "slowest_time_constant_s": _slowest_time_constant(cl_model, DT),
            "norm_reported_by_design": float(model.norm),
            "epsilon": float(model.epsilon),
            "weighted_closed_loop_hinf_on_grid": hinf_model,
            "weighted_closed_loop_hinf_bracket": _weighted_norm_bracket(P, model.controller, c["W1"], c["W2"]),
            "step": m_ideal,
            "design_seconds": c["t_model"],
        },
        "seed_spread": spread,
        "thesis": THESIS,
        "files": sorted({p.name for p in out.iterdir()} | {"noncollocated.json", "noncollocated.md"}),
    }
    summary["report"] = str(out / "noncollocated.md")
    write_json(out / "noncollocated.json", summary)
    _write_report(out, summary, figs)
    return summary


def summary_lines(s: dict) -> list[str]:
    """Key numbers of a run (printed by ``python -m experiments noncollocated``)."""
    sub, mb = s["subspace"], s["model_based"]
    return [f"subspace: γ_min = {sub['gamma_min']:.3f} (thesis {s['thesis']['gamma_min']}), γ = {sub['gamma']:.3f}, "
            f"closed-loop spectral radius {sub['closed_loop_spectral_radius']:.6f}",
            f"model-based: γ_opt = {mb['gamma_opt']:.3f}, γ = {mb['gamma']:.3f}",
            f"step: rise time {sub['step']['rise_time_s']:.3g} s, overshoot {100 * sub['step']['overshoot']:.1f} %"]


def _figures(out, c, omega):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figs = {}
    data = c["data"]
    fig, ax = plt.subplots(2, 1, figsize=(8, 5), sharex=True)
    ax[0].step(data.t, data.u[:, 0], where="post", lw=0.6)
    ax[0].set_ylabel("u (V)")
    ax[0].set_title("Fig 6.2 (simulated): identification data, two PRBS cycles")
    ax[1].plot(data.t, data.y[:, 0], lw=0.8)
    ax[1].set_ylabel("y3 (rad)")
    ax[1].set_xlabel("t (s)")
    figs["data"] = save_figure(fig, out / "fig6_2_data.png")

    w1 = _freq_response(c["W1"], omega)[0, 0]
    w2 = _freq_response(c["W2"], omega)[0, 0]
    p = _freq_response(c["P"], omega)[0, 0]
    fig, ax = plt.subplots(figsize=(8, 5))
    ax.semilogx(omega, 20 * np.log10(1 / np.abs(w1)), label="1/|W1|")
    ax.semilogx(omega, 20 * np.log10(1 / np.abs(w2)), label="1/|W2|")
    ax.semilogx(omega, 20 * np.log10(np.abs(p)), label="|P_y3,u| (ZOH model)")
    ax.axhline(0, color="k", lw=0.5)
    ax.set_xlabel("ω (rad/s)")
    ax.set_ylabel("magnitude (dB)")
    ax.set_title("Fig 6.3: control specification (Tustin weights, 64 Hz) and plant")
    ax.grid(True, which="both", lw=0.3)
    ax.legend()
    figs["spec"] = save_figure(fig, out / "fig6_3_spec.png")

    rs, rm = c["res_sub"], c["res_model"]
    fig, ax = plt.subplots(figsize=(8, 4))
    ax.plot(rs.t, rs.r[:, 0], "k--", lw=0.8, label="r")
    ax.plot(rs.t, rs.y[:, 0], label="y (subspace controller)")
    ax.plot(rm.t, rm.y[:, 0], label="y_ideal (model-based ∞-horizon)")
    ax.set_xlabel("t (s)")
    ax.set_ylabel("y3 (rad)")
    ax.set_title("Fig 6.5: step response on the true plant (noise free)")
    ax.legend()
    ax.grid(True, lw=0.3)
    figs["step"] = save_figure(fig, out / "fig6_5_step.png")

    Ks = _freq_response(c["sub"].controller, omega)
    Km = _freq_response(c["model"].controller, omega)
    curves = [("K_sub: u/r (y = 0)", Ks[0, 0]), ("K_sub: u/(−y) (r = 0)", -Ks[0, 1]),
              ("K_model: u/e", Km[0, 0])]
    fig, ax = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    for name, h in curves:
        ax[0].semilogx(omega, 20 * np.log10(np.abs(h)), label=name)
        ax[1].semilogx(omega, np.degrees(np.unwrap(np.angle(h))), label=name)
    ax[0].set_ylabel("magnitude (dB)")
    ax[1].set_ylabel("phase (deg)")
    ax[1].set_xlabel("ω (rad/s)")
    ax[0].set_title("Fig 6.7: subspace vs model-based controller")
    ax[0].legend()
    for a in ax:
        a.grid(True, which="both", lw=0.3)
    figs["controllers"] = save_figure(fig, out / "fig6_7_controllers.png")
    return figs


def _write_report(out, s, figs):
    rep = Report("§6.2 Non-collocated off-line design (three-disk plant, y3, 64 Hz)")
    rep.text(
        f"Simulated experiment: ZOH model of P_y3,u at 64 Hz, 10-bit PRBS (period 1023) of ±{PRBS_AMPLITUDE:g} V "
        f"repeated to n = {s['n']} samples, process noise σ = {PROCESS_NOISE} V at the plant input, "
        f"sensor noise σ = {SENSOR_NOISE} rad. Horizon i = {s['i']}, j = {s['j']}. Seed {s['seed']}."
        + (" **Quick mode** (smaller i and n)." if s["quick"] else "")
    )
    rep.section("Weights (chosen; the thesis gives Fig. 6.3 only as a plot)", s["weights"])
    sub, mb, th = s["subspace"], s["model_based"], s["thesis"]
    rep.section("γ")
    rep.table(["quantity", "this run", "thesis"], [
        ["γ_min (subspace, finite horizon)", sub["gamma_min"], f"{th['gamma_min']} (real data)"],
        ["γ = 1.35 γ_min", sub["gamma"], th["gamma"]],
        ["γ_opt (model-based ∞-horizon)", mb["gamma_opt"], th["gamma_opt_model"]],
        ["γ = 1.35 γ_opt", mb["gamma"], th["gamma_model"]],
    ])
    rep.section("Step response on the true plant (noise free)")
    rep.text("Overshoot in percent of the final value (the JSON keeps the fraction).")
    ms, mi = sub["step"], mb["step"]
    rep.table(["metric", "subspace K (y)", "model-based K (y_ideal)", "thesis (hardware)"], [
        ["rise time 10–90 % (s)", ms["rise_time_s"], mi["rise_time_s"], th["rise_time_s"]],
        ["ringing (Hz)", ms["ringing_hz"], mi["ringing_hz"], th["ringing_hz"]],
        ["steady-state error", ms["steady_state_error"], mi["steady_state_error"], th["steady_state_error"]],
        ["overshoot (%)", 100 * ms["overshoot"], 100 * mi["overshoot"], "–"],
    ])
    rep.section("Closed loop on the true plant")
    rep.table(["controller", "order", "max |closed-loop pole|", "slowest time constant (s)",
               "‖[W1 S; W2 K S]‖∞ (grid)", "‖[W1 S; W2 K S]‖∞ [attained, proven bound]", "γ used"], [
        ["subspace", sub["controller_order"], f"{sub['closed_loop_spectral_radius']:.6f}", sub["slowest_time_constant_s"],
         sub["weighted_closed_loop_hinf_on_grid"], sub["weighted_closed_loop_hinf_bracket"], sub["gamma"]],
        ["model-based", mb["controller_order"], f"{mb['closed_loop_spectral_radius']:.6f}", mb["slowest_time_constant_s"],
         mb["weighted_closed_loop_hinf_on_grid"], mb["weighted_closed_loop_hinf_bracket"], mb["gamma"]],
    ])
    rep.text(
        "\nThe subspace controller's level γ is a finite-horizon (i-step) bound on predicted data; the "
        "∞-horizon weighted norm it achieves on the true plant is shown for comparison. For the "
        "two-input subspace controller S = 1 − T_yr and K S = T_ur (transfers from r). "
        "The 'steady-state error' is the mean error over the last quarter of the "
        f"{STEP_SECONDS:g} s record: both loops have a very slow closed-loop pole (time constants above), "
        "because the controllers nearly cancel the plant's integrator (the model-based controller has a "
        "zero near z = 1, see its falling low-frequency gain in Fig 6.7), so the error creeps to zero only "
        "over tens of seconds — the same mechanism can explain the 18 % the thesis observed."
    )
    if s["seed_spread"]:
        g = np.array([r["gamma_min"] for r in s["seed_spread"]])
        rho = np.array([r["spectral_radius"] for r in s["seed_spread"]])
        rep.section(f"Spread over {len(g)} noise seeds (same PRBS, i = {s['i']})")
        rep.table(["γ_min min", "γ_min median", "γ_min max", "fraction stabilising the true plant",
                   "max spectral radius"],
                  [[float(g.min()), float(np.median(g)), float(g.max()), float(np.mean(rho < 1)), f"{rho.max():.6f}"]])
        inside = "inside" if g.min() <= THESIS["gamma_min"] <= g.max() else "outside"
        rep.text(f"\nThe thesis's γ_min = {THESIS['gamma_min']} (real data) lies {inside} this spread.")
    rep.section("Figures")
    rep.figure(figs["data"], "Fig 6.2: identification data (simulated)")
    rep.figure(figs["spec"], "Fig 6.3: 1/|W1|, 1/|W2| and the plant")
    rep.figure(figs["step"], "Fig 6.5: y (subspace) vs y_ideal (model-based)")
    rep.figure(figs["controllers"],
               "Fig 6.7: Bode of K_sub (both channels: u/r with y = 0 and u/(−y) with r = 0) and K_model (u/e)")
    return rep.write(out / "noncollocated.md")
