"""Common mistakes fail with a message that names the fix (issue "From a data file to a saved,
certified controller", item 5)."""
import warnings

import numpy as np
import pytest

import synthesis
import unfalsify as uf
from synthesis import DataError

TRANSPOSED = r"time runs along axis 0: pass {}\.T \(shape \(500, {}\)\)"


@pytest.mark.parametrize("m", [1, 2])
def test_time_along_axis_1_names_the_transpose(m):
    rng = np.random.default_rng(0)
    wide, good = rng.standard_normal((m, 500)), rng.standard_normal((500, m))
    with pytest.raises(DataError, match=TRANSPOSED.format("u", m)):
        synthesis.fit_predictor(wide, good, 10)
    with pytest.raises(DataError, match=TRANSPOSED.format("y", m)):
        synthesis.fit_predictor(good, wide, 10)
    with pytest.raises(DataError, match=TRANSPOSED.format("u", m)):
        synthesis.hankel_gram(wide, good, 10)
    with pytest.raises(DataError, match=TRANSPOSED.format("u", m)):
        synthesis.RecursivePredictor.from_data(wide, good, 10)
    if m == 1:
        with pytest.raises(DataError, match=TRANSPOSED.format("u", 1)):
            uf.subspace_data(wide, good, 10)
        with pytest.raises(DataError, match=TRANSPOSED.format("y", 1)):
            uf.arx_least_squares(good, wide, 2, 2)


def test_short_windows_and_single_samples_are_still_accepted():
    # the past window of a controller and one new MIMO sample may have more channels than rows
    rng = np.random.default_rng(0)
    u, y = rng.standard_normal((300, 3)), rng.standard_normal((300, 3))
    rp = synthesis.RecursivePredictor.from_data(u, y, 2)
    rp.push(rng.standard_normal((1, 3)), rng.standard_normal((1, 3)))
    assert rp.n_columns == 298
    pred = synthesis.fit_predictor(u, y, 2)
    assert pred.past_vector(u[-2:], y[-2:]).shape == (12,)  # (2, 3) windows: more channels than rows
    # a 1-D signal is one channel, never "transposed"
    assert synthesis.fit_predictor(u[:, 0], y[:, 0], 5).m == 1


def _fir(n=300, seed=0):
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(n)
    return u, np.convolve(u, [0.0, 1.0, 0.5])[:n] + 0.01 * rng.standard_normal(n)


def test_weights_at_another_sample_time_than_the_data_fail_without_dt():
    u, y = _fir()
    W1 = synthesis.makeweight(100.0, (0.5, 1.0), 0.5, 0.1)
    W2 = synthesis.makeweight(0.05, (2.0, 0.3), 10.0, 0.1)
    pred = synthesis.fit_predictor(u, y, 4, dt=0.2)  # the data's sample time travels with the predictor
    assert pred.dt == 0.2
    for call in (lambda: synthesis.hinf_design(pred, W1, W2), lambda: synthesis.gamma_min(pred, W1, W2),
                 lambda: synthesis.performance_map(pred, W1, W2)):
        with pytest.raises(synthesis.WeightError, match=r"sample time 0.1 but the data's is 0.2.*tustin\(W, 0.2\)"):
            call()
    with pytest.raises(synthesis.WeightError, match="Predictor.dt.*drop dt="):
        synthesis.hinf_design(pred, W1, W2, dt=0.1)  # two different data sample times
    ok = synthesis.fit_predictor(u, y, 4, dt=0.1)
    assert synthesis.hinf_design(ok, W1, W2).dt == 0.1
    assert synthesis.hinf_design(ok, W1, W2, dt=0.1).dt == 0.1
    # static weights take the data's sample time
    assert synthesis.hinf_design(ok, 1.0, 0.1).controller.dt == 0.1
    # without dt anywhere the mismatch cannot be seen: the arrays carry no sample time
    assert synthesis.hinf_design(synthesis.fit_predictor(u, y, 4), W1, W2).dt == 0.1
    with pytest.raises(DataError, match="dt must be"):
        synthesis.fit_predictor(u, y, 4, dt=0.0)


def test_predictor_dt_reaches_the_robust_pipeline():
    u, y = _fir(400, 1)
    W1 = synthesis.makeweight(100.0, (0.5, 1.0), 0.5, 0.1)
    W2 = synthesis.makeweight(0.05, (2.0, 0.3), 10.0, 0.1)
    pred = synthesis.fit_predictor(u, y, 4, dt=0.2)
    with pytest.raises(synthesis.WeightError, match="data's is 0.2"):
        uf.robust_design_from_data(u[:40], y[:40], 4, W1, W2, 0.005, predictor=pred, search=False)


def test_predictor_dt_reaches_the_models_and_the_lqg_design():
    # predictor_model, coprime_factors and lqg_design had ignored Predictor.dt (lqg: a controller with dt=True)
    u, y = _fir(300, 1)
    pred = synthesis.fit_predictor(u, y, 3, dt=0.5)
    assert uf.predictor_model(pred).dt == 0.5 and uf.predictor_model(pred, 0.5).dt == 0.5
    assert uf.coprime_factors(pred).dt == 0.5
    assert synthesis.lqg_design(pred, 1.0, 0.01).controller.dt == 0.5
    for call in (lambda: uf.predictor_model(pred, 1.0), lambda: uf.coprime_factors(pred, 1.0),
                 lambda: uf.predictor_model(pred, True), lambda: synthesis.lqg_design(pred, 1.0, 0.01, dt=0.2)):
        with pytest.raises(DataError, match=r"fitted on data sampled at 0.5 \(Predictor.dt\).*drop dt="):
            call()
    with pytest.raises(DataError, match="carries no sample time: pass dt="):
        uf.predictor_model(synthesis.fit_predictor(u, y, 3))
    # the premise test reads its frequencies with dt: one that contradicts the model's is refused
    model = uf.predictor_model(synthesis.fit_predictor(u[:200], y[:200], 3), 1.0)
    with pytest.raises(DataError, match=r"dt = 0.5 but the model P̂ has sample time 1.0.*pass dt=1.0"):
        uf.check_premise(model, u[:45], y[:45], 3, 0.05, dt=0.5)
    assert uf.check_premise(uf.predictor_model(pred), u[:45], y[:45], 3, 0.05, dt=0.5).frf.dt == 0.5


@pytest.mark.parametrize("call", [
    "ex.prbs(0)",
    "ex.white_noise(10, sigma=-1.0)",
    "ex.collect_data(ex.servo(), np.r_[1.0, np.nan])",
    "ex.collect_data(ex.servo(), np.ones(10), sensor_noise=-1.0)",
    "ex.resonant(zeta=2.0)",
    "sy.cholupdate(np.eye(2), np.ones(3))",
    "sy.fit_predictor(np.random.default_rng(0).standard_normal(100), np.zeros(100), 3, method='svd')",
    "uf.toeplitz_norm(np.ones(4), method='svd')",
    "uf.solvers.resolve('subspace', 'cvxpy', 'primal_dual')",
    "uf.subspace_unfalsify(np.ones(60), np.ones(60), 3, 0.1, backend='structured', form='thesis')",
    "uf.toeplitz_norm(np.r_[1.0, np.nan])",  # had raised numpy's LinAlgError (SVD did not converge)
    "uf.untested_premises(np.r_[1.0, np.nan])",  # had returned () (every premise testable)
    # a fuzz of the experiments' helpers (2026-11-29): numpy's or python-control's bare errors, or NaN poles
    "ex.collect_data(ex.servo(), np.array(['1', 'x']))",
    "ex.closed_loop(ex.servo(), ex.servo(), 1j * np.ones(10))",
    "ex.step_sequence(10, ['a', 'b'], hold=2)",
    "ex.damped_pair(None, 1.0)",
    "ex.damped_pair(0.5, float('nan'))",
    "ex.damped_pair(1.5, 1.0)",
    "ex.zoh('P', 0.1)",
    "ex.zoh(ex.servo(), 0.1)",  # already discrete
    "ex.zoh(ex.third_order(continuous=True), 'x')",
])
def test_bad_input_raises_the_toolkits_error_not_a_plain_value_error(call):
    """Every bad input names its problem through the toolkit's ValueError subclass (DataError), including the
    experiments' signal and simulation helpers and the option strings of the solvers (they had raised plain
    ValueError)."""
    import experiments as ex
    import unfalsify as uf

    with pytest.raises(DataError):
        eval(call, {"ex": ex, "sy": synthesis, "uf": uf, "np": np})


def test_true_false_options_refuse_strings():
    """``causal="no"`` is a truthy string: it had designed the causal law, the opposite of what was asked."""
    import control

    rng = np.random.default_rng(0)
    u = rng.standard_normal(200)
    y = np.convolve(u, [0.0, 0.5, 0.3])[:200] + 0.01 * rng.standard_normal(200)
    pred = synthesis.fit_predictor(u, y, 4)
    W = control.tf([1.0, 0.2], [1.0, -0.5], 1.0)
    for call in (lambda: synthesis.gamma_min(pred, W, W, causal="no"),
                 lambda: synthesis.hinf_design(pred, W, W, causal="no"),
                 lambda: uf.DesignOptions(causal="no"), lambda: uf.DesignSearch(causal=("no",))):
        with pytest.raises(DataError, match="causal must be True or False"):
            call()
    assert synthesis.gamma_min(pred, W, W, causal=np.bool_(True)) == synthesis.gamma_min(pred, W, W, causal=True)


@pytest.mark.parametrize("call, name", [
    ("uf.coprime_unfalsify(F, u[200:260], y[200:260], held_out='no')", "held_out"),
    ("uf.output_error_unfalsify(P, u[200:], y[200:], 3, held_out='no')", "held_out"),
    ("uf.subspace_unfalsify(u[:20], y[:20], 2, 0.02, eliminate_L='no')", "eliminate_L"),
    ("uf.subspace_unfalsify(u[:30], y[:30], 2, 0.02, backend='structured', progress='no')", "progress"),
    ("uf.arx_unfalsify(u[:30], y[:30], 1, 1, 0.02, progress='no')", "progress"),  # cvxpy: had been ignored
    ("sy.subspace_id(u, y, 6, feedthrough='no')", "feedthrough"),
    ("uf.unfalsified_gain_result(u[:20], y[:20], exact='no')", "exact"),
    ("uf.unfalsified_gain_result(u[:20], y[:20], warn='no')", "warn"),
    ("uf.deconvolve(u[:20], y[:20], exact='no')", "exact"),
    ("sy.as_weight(0.0, 'W3', allow_zero='no')", "allow_zero"),
    ("sy.cholupdate(np.eye(2), [1.0, 0.0], lower='no')", "lower"),
    ("sy.choldowndate(np.eye(2), [0.1, 0.0], lower='no')", "lower"),
])
def test_more_true_false_options_refuse_strings(call, name):
    """``held_out="no"`` and its kin are truthy strings: each had been read as True (``lower="no"`` updated the
    factor as a lower one, ``allow_zero="no"`` accepted a zero weight)."""
    rng = np.random.default_rng(0)
    u = rng.standard_normal(300)
    y = np.convolve(u, [0.0, 1.0, 0.5])[:300] + 0.01 * rng.standard_normal(300)
    env = {"uf": uf, "sy": synthesis, "np": np, "u": u, "y": y,
           "F": uf.coprime_factors(synthesis.fit_predictor(u, y, 2), 1.0),
           "P": uf.predictor_model(synthesis.fit_predictor(u[:200], y[:200], 3), 1.0)}
    error = synthesis.WeightError if name == "allow_zero" else DataError
    with pytest.raises(error, match=f"{name} must be True or False, got 'no'"):
        eval(call, env)
    # exact=None (choose by conditioning) stays allowed, and numpy's bools are bools
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert uf.unfalsified_gain_result(u[:20], y[:20], exact=None).gamma > 0
    np.testing.assert_array_equal(synthesis.cholupdate(np.eye(2), [1.0, 0.0], lower=np.False_),
                                  synthesis.cholupdate(np.eye(2), [1.0, 0.0], lower=False))


@pytest.mark.parametrize("call, name", [
    ("sy.block_hankel(np.arange(9.0), 2.0, 3)", "rows"),
    ("sy.block_hankel(np.arange(9.0), 2, 3, start=np.True_)", "start"),
    ("sy.RecursivePredictor(3, 1.5, 1)", "m"),
    ("sy.arx_id(np.ones(50), np.ones(50), max_order=2.0)", "max_order"),
    ("uf.arx_least_squares(np.ones(50), np.ones(50), 1.0, 2)", "na"),
    ("uf.CertificateOptions(step_samples=100.0)", "step_samples"),
    ("sy.diagonal_weight(control.tf([1.0], [1.0, -0.5], 1.0), channels=2.0)", "channels"),
    # hankel_order: 3.0 and '3' had raised numpy's TypeError, -1 its ValueError, 0 had returned []
    ("sy.hankel_order(3.0, 1, 1)", "horizon"),
    ("sy.hankel_order('3', 1, 1)", "horizon"),
    ("sy.hankel_order(-1, 1, 1)", "horizon"),
    ("sy.hankel_order(0, 1, 1)", "horizon"),
    ("sy.hankel_order(2, 1, 0)", "l"),
])
def test_counts_refuse_floats_and_bools_with_one_message(call, name):
    """Every count (rows, channels, orders, lengths) goes through one check, ``synthesis.validation.check_count``:
    a float or a bool is refused with the same sentence, not rounded (they had five wordings)."""
    import control

    with pytest.raises(DataError, match=f"{name} must be an integer ≥ [0-9]+, got"):
        eval(call, {"sy": synthesis, "uf": uf, "np": np, "control": control})


@pytest.mark.parametrize("call, fragment", [
    ("uf.subspace_unfalsify(u[:20], y[:20], 2, 0.02, predictor='x')", "predictor must be a synthesis.Predictor"),
    ("uf.estimate_delta(u[:20], y[:20], 2, 0.02, estimation='x')", "estimation must be an EstimationOptions"),
    ("uf.estimate_delta(u[:20], y[:20], 2, 0.02, estimation={'backend': 'cvxpy'})",
     "estimation must be an EstimationOptions"),
    ("uf.estimate_delta(u[:20], y[:20], 2, 0.02, predictor='x')", "predictor must be a synthesis.Predictor"),
    ("uf.output_error_unfalsify(P, u[200:260], y[200:260], 3, held_out=True, options='x')",
     "options must be a PremiseOptions"),
    ("uf.check_premise(P, u[:45], y[:45], 3, 0.05, dt=1.0, options='x')", "options must be a PremiseOptions"),
    ("uf.check_excitation(P, K, None)", "frf must be a FrequencyResponseEstimate"),
    ("uf.check_excitation(P, K, 'x')", "frf must be a FrequencyResponseEstimate"),
    ("uf.check_excitation(P, K, frf, low_band='x')", "low_band must be a LowBandEstimate"),
    ("uf.check_excitation(P, K, frf, factors='x')", "factors must be a CoprimeFactors"),
    ("uf.coprime_channel('x', K)", "factors must be a CoprimeFactors"),
    ("uf.coprime_unfalsify('F', u[200:260], y[200:260], held_out=True)", "factors must be a CoprimeFactors"),
    ("uf.check_coprime_premise('F', u[200:260], y[200:260], 0.01)", "factors must be a CoprimeFactors"),
    ("uf.coprime_gap('F', [0.1], [1.0])", "factors must be a CoprimeFactors"),
    ("uf.coprime_distance('F', P)", "factors must be a CoprimeFactors"),
    ("uf.error_gap('F', F_low)", "factors must be a CoprimeFactors"),
    ("uf.error_gap(F, 'x')", "est must be a FrequencyResponseEstimate or LowBandEstimate"),
    ("uf.additive_weight_fixed_point('p', 1.0, 0.1, 0.05)", "pred must be a synthesis.Predictor"),
    ("uf.robust_design_from_data(u, y, 3, 1.0, 0.1, 0.02, predictor='x')", "predictor must be a synthesis.Predictor"),
    ("uf.robust_design_from_data(u, y, 3, 1.0, 0.1, 0.02, predictor_for='x')", "predictor_for must be a callable"),
    ("uf.robust_design_from_data(u, y, 3, 1.0, 0.1, 0.02, premise='x')", "premise must be a PremiseOptions"),
])
def test_objects_of_the_wrong_type_raise_input_type_error(call, fragment):
    """A string, None or a dict where an option object, an estimate, a predictor or coprime factors belong had failed
    deep inside with an AttributeError (``'str' object has no attribute 'Lw'``), or silently as the defaults (an empty
    dict for ``estimation``); now InputTypeError (a DataError and a TypeError) names the type expected."""
    import control
    from synthesis.validation import InputTypeError

    rng = np.random.default_rng(0)
    u = rng.standard_normal(300)
    y = np.convolve(u, [0.0, 1.0, 0.5])[:300] + 0.01 * rng.standard_normal(300)
    F = uf.coprime_factors(synthesis.fit_predictor(u, y, 2), 1.0)
    env = {"uf": uf, "u": u, "y": y, "F": F, "K": control.ss([], [], [], [[0.5, -0.5]], 1.0),
           "P": uf.predictor_model(synthesis.fit_predictor(u[:200], y[:200], 3), 1.0),
           "frf": uf.frequency_response_estimate(u, y),
           "F_low": uf.LowBandEstimate(frequency=np.array([0.0, 1.0]), response=np.array([0.1, 0.1]),
                                       radius=np.array([0.02, 0.02]), confidence=0.99, window=16, degree=2,
                                       samples=100, dt=1.0)}
    with pytest.raises(InputTypeError, match=fragment) as caught:
        eval(call, env)
    assert isinstance(caught.value, TypeError) and ", got " in str(caught.value)


@pytest.mark.parametrize("kw, fragment", [
    (dict(xtol=0), r"xtol \(brentq's absolute tolerance on c, relative to max\(c, 1\)\) must be a finite number > 0"),
    (dict(delta="x"), "delta must be a finite number >= 0, got 'x'"),
    (dict(max_doublings=2.5), "max_doublings must be an integer ≥ 1, got 2.5"),
    (dict(margin="0.1"), "margin must be a finite number >= 0"),
    (dict(gamma_ratio=1.0), r"gamma_ratio \(the design needs γ > γ_min_a\) must be a finite number > 1"),
    (dict(causal="no"), "causal must be True or False"),
])
def test_additive_weight_fixed_point_checks_its_numbers(kw, fragment):
    # xtol=0 had reached brentq's bare "xtol too small", delta="x" and max_doublings=2.5 numpy's/range's TypeErrors
    rng = np.random.default_rng(0)
    u = rng.standard_normal(200)
    y = np.convolve(u, [0.0, 1.0, 0.5])[:200] + 0.01 * rng.standard_normal(200)
    args = dict(delta=0.05)
    args.update(kw)
    with pytest.raises(DataError, match=fragment):
        uf.additive_weight_fixed_point(synthesis.fit_predictor(u, y, 2), 1.0, 0.1, args.pop("delta"), **args)


def test_horizons_and_predictors_of_the_premise_and_the_problem_are_checked():
    # int(horizon) had passed 3.5 and "3"; a string predictor reached SubspaceProblem's AttributeError
    import synthesis
    import unfalsify as uf

    rng = np.random.default_rng(0)
    u = np.sign(rng.standard_normal(300))
    y = np.convolve(u, [0.0, 0.5, 0.3])[:300] + 0.05 * rng.standard_normal(300)
    model = uf.predictor_model(synthesis.fit_predictor(u[:200], y[:200], 3, dt=1.0))
    for bad in (3.5, "3"):
        with pytest.raises(synthesis.DataError, match="horizon must be an integer"):
            uf.output_error_unfalsify(model, u[200:], y[200:], bad, held_out=True)
        with pytest.raises(synthesis.DataError, match="horizon must be an integer"):
            uf.check_premise(model, u[200:], y[200:], bad, 0.05, dt=1.0)
    with pytest.raises(synthesis.validation.InputTypeError, match="predictor must be a synthesis.Predictor"):
        uf.SubspaceProblem.from_data(u[:60], y[:60], 3, 0.01, predictor="x")


def test_a_signal_of_text_is_refused_not_parsed():
    from synthesis.validation import as_signal

    with pytest.raises(DataError, match="numeric array, got text"):
        as_signal(["1.5", "2.0", "3.0"], "u")  # numpy had parsed it
    assert as_signal([1.5, 2.0, 3.0], "u").shape == (3, 1)


def _line_case():
    import control

    rng = np.random.default_rng(0)
    u = rng.standard_normal(600)
    y = np.convolve(u, [0.0, 1.0, 0.5])[:600] + 0.1 * rng.standard_normal(600)
    model = uf.predictor_model(synthesis.fit_predictor(u, y, 3), 1.0)
    return dict(uf=uf, sy=synthesis, np=np, u=u, y=y, model=model, K=control.ss([], [], [], [[0.2, -0.2]], 1.0),
                P=control.ss(control.tf([0.1, 0.05], [1.0, -1.2, 0.5], 1.0)))


@pytest.mark.parametrize("call, fragment", [
    # the narrow-line tests had checked nothing: IndexError (a scalar record), TypeError (horizon 3.5),
    # ZeroDivisionError (dt = 0), LinAlgError (dt = nan)
    ("uf.hidden_line_gain(model, K, 1.0, y, 3, 1.0)", "u"),
    ("uf.hidden_line_gain(model, K, u, y, 3.5, 1.0)", "horizon must be an integer"),
    ("uf.hidden_line_gain(model, K, u, y, 3, 0.0)", "dt"),
    ("uf.residual_line(model, K, u, y, 3, float('nan'))", "dt"),
    ("uf.hidden_line_gain('P', K, u, y, 3, 1.0)", "model must be"),  # python-control's bare TypeError
    ("uf.glitch_note('P', u, y, 3)", "model must be"),
    ("uf.check_premise('P', u[:45], y[:45], 3, 0.05, dt=1.0)", "model must be"),
    ("uf.robust_design_from_data(u, y, 3, 1.0, 0.1, 0.02, dt='0.1')", "dt"),  # float('0.1') had passed
    ("uf.robust_design_from_data(u, y, 3, 1.0, 0.1, 0.02, dt='abc')", "dt"),  # numpy's bare ValueError
    ("uf.minimal_extension('abc', 8)", "real numbers"),
    ("uf.leaked_bins(u, 32)", "list of input records"),  # a bare record had been iterated sample by sample
    ("sy.load_controller(None)", "path must be a file name"),  # pathlib's TypeError
    ("sy.solve_minimax(np.eye(3), np.ones((3, 1)), None, 10.0)", "needs M_x"),  # AttributeError
    ("sy.solve_minimax(1e200 * np.eye(3), np.ones((3, 1)), np.ones((3, 1)), 10.0)", "squares overflow"),
    ("sy.minimax_gamma_min(1e200 * np.eye(3), np.ones((3, 1)))", "squares overflow"),  # LAPACK dsyevr failed
    ("sy.bounded_real_certificate(P, 1e300)", "too large to certify"),  # LinAlgError (γ² overflowed)
    ("sy.hinf_riccati(sy.generalized_plant(P, 100.0, 0.1), gamma=1e300, horizon=5)", "too large"),  # OverflowError
    ("sy.lqr_riccati(1e200 * P.A, P.B, P.C, P.D, 1.0, 0.1, horizon=5)", "overflowed"),  # LinAlgError (SVD)
])
def test_extreme_or_malformed_input_raises_the_toolkits_error(call, fragment):
    """Found by a fuzz of the public functions with one bad argument at a time (2026-11-29): each of these had
    raised an exception of numpy, pathlib or python-control (or the builtins'), not the toolkit's DataError."""
    with pytest.raises(DataError, match=fragment):
        eval(call, _line_case())


def test_the_checked_entries_still_answer_on_good_input():
    env = _line_case()
    gain, freq = uf.hidden_line_gain(env["model"], env["K"], env["u"], env["y"], 3, 1.0)
    assert np.isfinite(gain) and 0 < freq < np.pi
    assert uf.hidden_line_gain(env["model"], env["K"], env["u"][:, None], env["y"][:, None], 3, 1.0) == (gain, freq)
    # a δ so small that 1/((1 + margin)δ) is beyond a bounded-real matrix: proven at the largest level one holds
    # (it had raised LinAlgError through bounded_real_certificate); the second route is the pencil test's bracket
    for delta in (1e-300, 1e-3):
        cert = uf.certify_loop(env["model"], env["K"], delta, tracking_floor=1e9)
        assert cert.certified and bool(cert.bounded_real) and cert.norm.upper < 1e3
        assert cert.bounded_real.gamma == min(1.0 / (1.1 * delta), 2.0 ** 200)
    assert np.isfinite(synthesis.lqr_riccati(env["P"].A, env["P"].B, env["P"].C, env["P"].D, 1.0, 0.1,
                                             horizon=5).gains).all()


def test_predict_and_the_recursive_options_refuse_text_and_arrays():
    """``Predictor.predict`` of text or complex vectors and ``RecursivePredictor(track=array)`` had raised numpy's
    bare ValueError or TypeError (a fuzz of the classes' methods, 2026-11-29)."""
    rng = np.random.default_rng(0)
    u = np.sign(rng.standard_normal(300))
    y = np.convolve(u, [0.0, 0.5, 0.3])[:300] + 0.02 * rng.standard_normal(300)
    pred = synthesis.fit_predictor(u, y, 4)
    for bad in ("x", 1j * np.ones(4)):
        with pytest.raises(DataError):
            pred.predict(bad, np.ones(4))
    with pytest.raises(DataError, match="unknown track"):
        synthesis.RecursivePredictor.from_data(u, y, 4, track=np.ones(3))
    assert pred.predict(pred.past_vector(u[-4:], y[-4:]), np.ones(4)).shape == (4, 1)


def test_a_predictor_of_other_channels_is_named():
    """estimate_delta / robust_design_from_data with a 2 × 2 predictor on one-input data had raised numpy's matmul
    ValueError in the window check (a fuzz of the several-channel front ends, 2026-11-29)."""
    rng = np.random.default_rng(0)
    u = np.sign(rng.standard_normal((300, 2)))
    y = np.column_stack([np.convolve(u[:, 0], [0, 0.5, 0.2])[:300], np.convolve(u[:, 1], [0, 0.3])[:300]])
    pred = synthesis.fit_predictor(u, y + 0.02 * rng.standard_normal(y.shape), 3)
    for call in (lambda: uf.estimate_delta(u[:60, :1], y[:60], 3, 0.001, predictor=pred),
                 lambda: uf.estimate_delta(u[:60, :1], y[:60], 3, "auto", predictor=pred)):
        with pytest.raises(DataError, match=r"predictor of horizon 3 for 1 input\(s\) and 2 output\(s\)"):
            call()


@pytest.mark.parametrize("level, outputs", [(0.0, 1), (5.0, 1), (0.0, 2)])
def test_a_constant_output_names_the_column_and_the_sensor(level, outputs):
    # a dead sensor or the wrong output column: a zero output had been refused as "sigma must be > 0" (σ = "auto" =
    # half a zero residual) and a constant one as noise-free data; neither names the slip
    rng = np.random.default_rng(0)
    u = rng.uniform(-1, 1, (600, outputs))
    y = np.convolve(u[:, 0], [0.0, 0.5, 0.3])[:600, None] + 0.01 * rng.standard_normal((600, outputs))
    y[:, -1] = level
    W = synthesis.makeweight(10.0, (0.5, 1.0), 0.5, 1.0)
    W1, W2 = (W, 0.1) if outputs == 1 else (synthesis.diagonal_weight(W, 2), 0.1 * np.eye(2))
    what = "the output" if outputs == 1 else "output 1"
    # the record mode's predictor fit (on the record's fitting part) sees it first
    where = "(window|record)"
    with pytest.raises(DataError, match=rf"{what} is constant \({level:g}\) on every sample of the {where}.*sensor"):
        uf.robust_design_from_data(u, y, 3, W1, W2, "auto", window="auto", dt=1.0)
    with pytest.raises(DataError, match=rf"{what} is constant"):
        uf.estimate_delta(u[:100], y[:100], 3, "auto")
