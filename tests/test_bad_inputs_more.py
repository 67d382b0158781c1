"""Bad input found by a fuzz of the public API of ``synthesis`` and ``unfalsify`` (2026-11-29), one argument at a
time: each case below had returned a silent NaN or meaningless answer, or raised an exception of numpy, Python or a
solver; now the toolkit's ``ValueError`` subclass names the problem and the fix."""
from __future__ import annotations

import warnings

import control
import numpy as np
import pytest

import synthesis as sy
import unfalsify as uf
from synthesis import DataError


def _record(n=240, seed=0):
    rng = np.random.default_rng(seed)
    u = np.sign(rng.standard_normal(n))
    return u, np.convolve(u, [0.0, 0.5, 0.3, 0.1])[:n] + 0.02 * rng.standard_normal(n)


@pytest.fixture(scope="module")
def case():
    u, y = _record()
    pred = sy.fit_predictor(u, y, 3, dt=1.0)
    return {"u": u, "y": y, "pred": pred, "model": uf.predictor_model(pred), "F": uf.coprime_factors(pred),
            "K": control.ss([], [], [], [[0.2, -0.2]], 1.0)}


@pytest.mark.parametrize("level", [0.0, 3.0])
@pytest.mark.parametrize("call", [
    lambda u, y: uf.arx_unfalsify(u[:40], y[:40], 2, 2, 0.01),
    lambda u, y: uf.subspace_unfalsify(u[:40], y[:40], 3, 0.01),
    lambda u, y: uf.subspace_unfalsify(u[:40], y[:40], 3, 0.01, backend="structured"),
], ids=["arx", "subspace-cvxpy", "subspace-structured"])
def test_a_constant_output_is_refused_by_the_programs(call, level):
    """A dead sensor or the wrong column: a zero output had given δ = NaN with status 'optimal' (cvxpy), and a
    constant one δ = 15468 (ARX) or δ = 0 (subspace) -- numbers about no plant.  estimate_delta already refused both
    with this message; the programs themselves now do."""
    u, y = _record()
    flat = np.full_like(y, level)
    with pytest.raises(DataError, match=rf"the output is constant \({level:g}\) on every sample.*sensor"):
        call(u, flat)
    with pytest.raises(DataError, match=r"the output is constant"):
        uf.estimate_delta(u[:40], flat[:40], 3, 0.01)  # the front end's refusal, unchanged: the same sentence
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert np.isfinite(call(u, y).delta)  # a moving output still answers


def test_the_premise_programs_refuse_a_constant_output_and_a_zero_input(case):
    """output_error_unfalsify had returned δ = 0 for a constant output (its error −P̂u, a FIR response of u, was
    taken for noise by the σ fit), coprime_unfalsify an ε for a constant output or a zero input."""
    u, y = case["u"][:80], case["y"][:80]
    flat = np.full_like(y, 3.0)
    with pytest.raises(DataError, match=r"the output is constant \(3\) on every sample of the output-error record"):
        uf.output_error_unfalsify(case["model"], u, flat, 3, held_out=True)
    with pytest.raises(DataError, match=r"the output is constant \(3\)"):
        uf.coprime_unfalsify(case["F"], u, flat, held_out=True, sigma=0.005)
    with pytest.raises(DataError, match=r"the input is zero on every sample.*PRBS"):
        uf.coprime_unfalsify(case["F"], np.zeros_like(u), y, held_out=True, sigma=0.005)
    # the premise test turns the refusal into its reason: not confirmed, and it says why
    test = uf.check_premise(case["model"], case["u"][:60], case["y"][:60], 3, 0.05, dt=1.0,
                            validation=(u, flat))
    assert not test.ok and "the output is constant" in test.reason
    # second route: on the same data with a moving output both answer, and the premise test with no complaint
    assert uf.output_error_unfalsify(case["model"], u, y, 3, held_out=True).delta >= 0.0
    assert uf.coprime_unfalsify(case["F"], u, y, held_out=True, sigma=0.005).epsilon >= 0.0


@pytest.mark.parametrize("bad", [None, "0.1", np.array([0.01]), 0.01 + 0j, 0.0, 1.0, float("nan"), True])
@pytest.mark.parametrize("test", [
    lambda u, y, level: uf.check_feedback(u, y, level=level),
    lambda u, y, level: uf.check_time_invariance(u, y, order=3, level=level),
], ids=["check_feedback", "check_time_invariance"])
def test_significance_levels_are_checked(test, bad):
    """``float(level)`` had raised TypeError on None, an array or a complex number, and passed the text '0.1'."""
    u, y = _record()
    with pytest.raises(DataError, match=r"level must be a (real|finite) number in \(0, 1\), got"):
        test(u, y, bad)
    test(u, y, np.float64(0.01))  # numpy's floats are real numbers


def test_a_zero_bound_gives_a_reason_not_a_zero_division(case):
    """bound = (1 + margin)·δ is 0 for δ = 0; unconfirmed_premise and unconfirmed_coprime_premise divided by it."""
    u, y = case["u"], case["y"]
    test = uf.check_premise(case["model"], u[:60], y[:60], 3, 0.05, dt=1.0, validation=(u[100:], y[100:]))
    premise = uf.check_coprime_premise(case["F"], u[:80], y[:80], 0.02)
    assert test.upper > 0  # the regions reach beyond 0, so a zero bound is not confirmed
    for why in (uf.unconfirmed_premise(test, 0.0), uf.unconfirmed_coprime_premise(premise, 0.0)):
        assert why.startswith("the data do not confirm the premise") and "(infinitely many times that)" in why
    # a positive bound below the reach keeps its ratio: the second route is upper / bound itself
    bound = test.upper / 4
    assert f"({test.upper / bound:.3g} × that)" in uf.unconfirmed_premise(test, bound)


@pytest.mark.parametrize("line", [uf.hidden_line_gain, uf.residual_line])
def test_the_line_tests_refuse_a_dt_that_is_not_the_models(line, case):
    """dt had been taken as given: the line's frequency came out in the units of another sample time (π/3 for 2π/3
    rad/s at dt = 2 against P̂'s dt = 1), as check_premise refuses it."""
    u, y, model, K = case["u"], case["y"], case["model"], case["K"]
    with pytest.raises(DataError, match=r"dt = 2.0 but the model P̂ has sample time 1.0.*pass dt=1.0"):
        line(model, K, u, y, 3, 2.0)
    ok = line(model, K, u, y, 3, 1.0)
    # second route: a model built with dt=True has no sample time to contradict; its frequency scales with 1/dt
    free = control.ss(model.A, model.B, model.C, model.D, True)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        at2 = line(free, K, u, y, 3, 2.0)
    assert at2[0] == pytest.approx(ok[0], rel=1e-12)
    assert (np.isnan(at2[1]) and np.isnan(ok[1])) or at2[1] == pytest.approx(ok[1] / 2.0, rel=1e-12)


@pytest.mark.parametrize("update", [sy.cholupdate, sy.choldowndate])
def test_a_full_matrix_is_not_taken_for_a_triangular_factor(update):
    """A Gram matrix passed for its factor had returned a matrix that kept the other triangle: neither a factor nor
    the update of one."""
    G = np.array([[4.0, 2.0], [2.0, 3.0]])
    x = np.array([0.3, 0.1])
    with pytest.raises(DataError, match=r"must be lower triangular \(lower=True\).*np.linalg.cholesky\(G\)"):
        update(G, x)
    with pytest.raises(DataError, match=r"must be upper triangular \(lower=False\).*lower=True"):
        update(G, x, lower=False)
    # second route: the factor of G updated equals the factor of G ± x xᵀ
    L = np.linalg.cholesky(G)
    sign = 1.0 if update is sy.cholupdate else -1.0
    np.testing.assert_allclose(update(L, x), np.linalg.cholesky(G + sign * np.outer(x, x)), rtol=1e-12)
    np.testing.assert_allclose(update(L.T, x, lower=False), np.linalg.cholesky(G + sign * np.outer(x, x)).T,
                               rtol=1e-12)


@pytest.mark.parametrize("program", ["arx", "subspace"])
def test_a_solver_crash_is_the_toolkits_error(program):
    """CLARABEL's equilibration panics at sigma = 1e20 on data of unit size; pyo3's PanicException is a
    BaseException, which ``except Exception`` (and every caller's ``except ValueError``) lets through."""
    u, y = _record(40)
    with pytest.raises(uf.UnfalsificationError, match=r"solver CLARABEL crashed.*units of y.*backend='structured'"):
        if program == "arx":
            uf.arx_unfalsify(u, y, 2, 2, 1e20)
        else:
            uf.subspace_unfalsify(u, y, 3, 1e20)
    # second route: the structured backend answers the same problem: every output within the noise, δ = 0
    assert uf.subspace_unfalsify(u, y, 3, 1e20, backend="structured").delta == 0.0


@pytest.mark.parametrize("call, fragment", [
    (lambda: sy.makeweight(1.0, (0.5, 1.0), 1.0, 1.0), r"pass the number 1 itself as a static weight"),
    (lambda: sy.block_hankel(np.ones(5), 3, 10), r"needs rows \+ cols − 1 = 12: pass a longer x"),
    (lambda: uf.minimal_extension(np.ones((10, 1)), 20), r"e.g. h.ravel\(\) for a column"),
])
def test_messages_name_the_fix(call, fragment):
    """These had named no fix: "choose mag in (1, 1)" (an empty interval), "not enough samples for the requested block
    Hankel matrix", and a column of Markov parameters refused without saying which shape to pass."""
    with pytest.raises(DataError, match=fragment):
        call()
