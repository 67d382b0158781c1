"""Is a record closed-loop?  unfalsify.check_feedback and what the §7.4 pipeline does with it."""
import warnings

import control
import pytest

import unfalsify as uf
from experiments.lab.plants import third_order
from experiments.lab.servo_setup import design_weights
from experiments.lab.signals import prbs
from experiments.lab.simulate import closed_loop, collect_data
from synthesis import DataError


def _closed_loop_record(dither, sensor=0.2, seed=0):
    """The third-order plant under u = r − y, r a ±dither PRBS: with dither 0.05 the sensor noise dominates u."""
    P = third_order()
    res = closed_loop(P, control.ss(control.tf([1.0], [1.0], P.dt)), dither * prbs(1200, seed=seed),
                      process_noise=0.05, sensor_noise=sensor, seed=100 + seed)
    return P, res.u[:, 0], res.y_measured[:, 0]


def test_a_closed_loop_record_whose_input_is_mostly_fed_back_noise_is_refused():
    # measured before the check: certified, and the loop is unstable on the true plant (P̂ biased towards −1/K; the
    # held-out third, from the same loop, shares the bias)
    P, u, y = _closed_loop_record(0.05)
    W = design_weights()
    with pytest.warns(uf.NotCertifiedWarning, match="largely the loop's response to the output's noise"):
        r = uf.robust_design_from_data(u, y, 10, W["W11"], W["W21"], "auto", dt=P.dt, window=(0, 49), search=False,
                                       certificate=uf.CertificateOptions(uncertainty="additive"))
    assert not r.certified and r.feedback.detected and r.feedback.correlation < -uf.FEEDBACK_REFUSED
    assert r.feedback.lag == 0 and "Record in open loop" in r.reason
    assert any(a.startswith("the record is that of a closed loop") for a in r.assumed)


def test_open_loop_records_are_not_flagged_and_a_strong_reference_is_only_stated():
    P = third_order()
    for seed in range(5):
        d = collect_data(P, prbs(1200, seed=seed), process_noise=0.05, sensor_noise=0.2, seed=100 + seed)
        t = uf.check_feedback(d.u, d.y)
        assert not t.detected and t.p_value > 1e-3 and t.statement == t.reason == ""
    # feedback with a reference of amplitude 0.2 against noise 0.2: detected and stated, not refused by itself
    _, u, y = _closed_loop_record(0.2, sensor=0.05)
    t = uf.check_feedback(u, y)
    assert t.detected and uf.FEEDBACK_NOTED <= abs(t.correlation) < uf.FEEDBACK_REFUSED and t.reason == ""


def test_check_feedback_checks_its_input():
    u = prbs(300, seed=0)
    assert uf.check_feedback(u, u) is None  # too short for ten rows per parameter of the ARX(16) fit
    with pytest.raises(DataError, match="level"):
        uf.check_feedback(u, u, level=1.0)
    with pytest.raises(DataError):
        uf.check_feedback(u, u[:-1])


def test_a_feedback_record_without_a_reference_names_the_feedback_not_noise_free_data():
    # u = −y exactly (r = 0): the predictor fits the window to rounding, which had been reported as noise-free data
    _, u, y = _closed_loop_record(0.0)
    W = design_weights()
    with pytest.raises(DataError, match="feedback loop without a reference") as info:
        uf.robust_design_from_data(u, y, 10, W["W11"], W["W21"], "auto", dt=0.1, window=(0, 49), search=False)
    assert "fits this window to rounding" not in str(info.value)  # not the noise-free reason alone
    # noise-free open-loop data keep their own reason
    d = collect_data(third_order(), prbs(1200, seed=0))
    with pytest.raises(DataError, match="noise-free"):
        uf.robust_design_from_data(d.u, d.y, 10, W["W11"], W["W21"], "auto", dt=0.1, window=(0, 49), search=False)


def _feedthrough_record(D, seed=0):
    """The third-order plant with a direct feedthrough D added, in open loop under a ±1 PRBS."""
    P = control.parallel(third_order(), control.ss([], [], [], [[D]], 0.1))
    d = collect_data(P, prbs(1200, seed=seed), process_noise=0.05, sensor_noise=0.2, seed=100 + seed)
    return P, d.u[:, 0], d.y[:, 0]


def test_a_direct_feedthrough_is_not_read_as_feedback_once_declared():
    _, u, y = _feedthrough_record(0.5)
    default = uf.check_feedback(u, y)  # strictly proper assumed: the feedthrough looks like feedback at lag 0
    assert default.lag == 0 and abs(default.correlation) >= uf.FEEDBACK_REFUSED
    assert "direct feedthrough" in default.reason and "feedthrough=True" in default.reason
    declared = uf.check_feedback(u, y, feedthrough=True)
    assert declared.feedthrough and not declared.detected and declared.lag >= 1 and declared.p_value > 1e-3
    # a controller a sample late is still seen with lag 0 left out
    P = third_order()
    res = closed_loop(P, control.ss(control.tf([1.0], [1.0, 0.0], P.dt)), 0.05 * prbs(1200, seed=0),
                      process_noise=0.05, sensor_noise=0.2, seed=100)
    late = uf.check_feedback(res.u[:, 0], res.y_measured[:, 0], feedthrough=True)
    assert late.detected and late.lag == 1 and late.reason and "direct feedthrough" not in late.reason
    with pytest.raises(DataError, match="feedthrough"):
        uf.check_feedback(u, y, feedthrough="yes")


def test_the_pipeline_refuses_an_undeclared_feedthrough_and_states_a_declared_one():
    P, u, y = _feedthrough_record(0.5)
    W = design_weights()
    args = (u, y, 10, W["W11"], W["W21"], "auto")
    kw = dict(dt=P.dt, window=(0, 49), search=False)
    with pytest.warns(uf.NotCertifiedWarning, match="direct feedthrough"):
        r = uf.robust_design_from_data(*args, **kw, certificate=uf.CertificateOptions(uncertainty="additive"))
    assert not r.certified and "direct feedthrough" in r.premise_reason
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = uf.robust_design_from_data(*args, **kw, certificate=uf.CertificateOptions(uncertainty="additive",
                                                                                      feedthrough=True))
    assert r.feedback.feedthrough and not r.feedback.detected
    assert uf.FEEDTHROUGH_STATEMENT in r.assumed and "feedback" not in r.premise_reason
    with pytest.raises(DataError, match="feedthrough"):
        uf.CertificateOptions(feedthrough=1)


def test_noise_free_data_of_a_plant_with_a_feedthrough_name_both_causes():
    # u_k is recovered from y_k as under feedback within the sample: the message had named feedback alone
    P = control.parallel(third_order(), control.ss([], [], [], [[0.5]], 0.1))
    d = collect_data(P, prbs(1200, seed=0))
    W = design_weights()
    with pytest.raises(DataError, match="direct feedthrough") as info:
        uf.robust_design_from_data(d.u[:, 0], d.y[:, 0], 10, W["W11"], W["W21"], "auto", dt=0.1, window=(0, 49),
                                   search=False)
    assert "feedback loop without a reference" in str(info.value)


def test_an_open_loop_record_with_input_and_output_swapped_names_the_swap():
    # measured before the hint: a lightly damped plant's record with u and y exchanged was refused with the closed-loop
    # statement alone ("record in open loop"), which a user who did record in open loop cannot act on
    P = third_order()
    d = collect_data(P, prbs(1200, seed=0), process_noise=0.05, sensor_noise=0.05, seed=100)
    t = uf.check_feedback(d.y, d.u)  # the columns swapped
    assert t.detected and t.lag >= 1
    assert "input and output columns are swapped" in t.statement and "--u and --y" in t.statement
    # at lag 0 the alternative is a feedthrough, not a swap
    _, u, y = _closed_loop_record(0.05)
    lag0 = uf.check_feedback(u, y)
    assert lag0.detected and lag0.lag == 0 and "feedthrough" in lag0.statement
    assert "swapped" not in lag0.statement
