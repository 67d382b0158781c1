"""Result objects print short, compare by value and cannot be changed behind their back (issue #13, item 4)."""
import dataclasses

import control
import numpy as np
import pytest

import synthesis as sy
from synthesis._repr import result, short_repr, values_equal


@pytest.fixture(scope="module")
def fit():
    rng = np.random.default_rng(0)
    n = 600
    u = rng.standard_normal(n)
    y = np.convolve(u, [0.0, 0.5, 0.3, 0.1])[:n] + 0.02 * rng.standard_normal(n)
    s = control.tf("s")
    W1 = sy.tustin(100 * (0.01 / 5) * (s + 5) / (s + 0.01), 1.0)
    W2 = sy.tustin(0.05 * (10 / 0.5) * (s + 0.5) / (s + 10), 1.0)
    return u, y, W1, W2


def test_hinf_design_repr_shows_shapes_not_dumps(fit):
    u, y, W1, W2 = fit
    design = sy.hinf_design(sy.fit_predictor(u, y, 10), W1, W2)
    text = repr(design)
    assert len(text) < 1500, len(text)
    assert "array([" not in text and "\n" not in text
    assert "gain=<array (10, 22) float64>" in text
    assert f"gamma={design.gamma:.4g}" in text
    assert "controller=<StateSpace: 1 output(s), 2 input(s)" in text


def test_predictor_equality_is_by_value(fit):
    u, y, _, _ = fit
    p, q = sy.fit_predictor(u, y, 10), sy.fit_predictor(u, y, 10)
    assert p is not q and p == q and hash(p) == hash(q)
    assert p != sy.fit_predictor(u, y, 9)
    assert p != sy.fit_predictor(u[:-1], y[:-1], 10)
    assert p != "not a predictor"
    assert dataclasses.replace(p) == p
    assert {p, q} == {p}


def test_design_equality_compares_controllers_by_matrices(fit):
    u, y, W1, W2 = fit
    pred = sy.fit_predictor(u, y, 10)
    a, b = sy.hinf_design(pred, W1, W2), sy.hinf_design(pred, W1, W2)
    assert a == b
    assert a != sy.hinf_design(pred, W1, W2, gamma_ratio=1.5)


def test_arrays_of_results_are_read_only_copies(fit):
    u, y, W1, W2 = fit
    pred = sy.fit_predictor(u, y, 10)
    design = sy.hinf_design(pred, W1, W2)
    for arr in (pred.Lw, pred.Lu, pred.singular_values, design.gain, design.disturbance_gain):
        assert not arr.flags.writeable
        with pytest.raises(ValueError, match="read-only"):
            arr[0] = 1.0
    # the caller's array is copied, not frozen in place
    Lw = np.zeros((2, 2))
    p2 = dataclasses.replace(pred, Lw=Lw)
    assert Lw.flags.writeable and not p2.Lw.flags.writeable


@result
@dataclasses.dataclass(frozen=True, eq=False)
class _Toy:
    a: np.ndarray
    pair: tuple
    x: float = float("nan")


def test_mixin_on_a_toy_class():
    t = _Toy(np.arange(3.0), (np.ones(2), "s"))
    assert repr(t) == "_Toy(a=<array (3,) float64>, pair=(<array (2,) float64>, 's'), x=nan)"
    assert not t.pair[0].flags.writeable
    assert t == _Toy(np.arange(3.0), (np.ones(2), "s"))  # NaN == NaN for results
    assert t != _Toy(np.arange(4.0), (np.ones(2), "s"))
    with pytest.raises(dataclasses.FrozenInstanceError):
        t.x = 1.0


def test_every_result_class_uses_the_mixin():
    import unfalsify as uf
    from synthesis.hinfnorm import NormBracket, NormTest
    from synthesis.riccati import GeneralizedPlant, RiccatiLaw

    classes = [sy.Predictor, sy.HinfDesign, sy.LqgDesign, sy.MinimaxSolution, NormBracket, NormTest,
               GeneralizedPlant, RiccatiLaw, uf.ArxResult, uf.SubspaceResult, uf.GainResult,
               uf.RobustDesignResult, uf.AdditiveRobustness]
    for cls in classes:
        assert getattr(cls, "__result_class__", False), cls.__name__


def test_helpers():
    assert values_equal(np.array([1.0, np.nan]), np.array([1.0, np.nan]))
    assert not values_equal(np.zeros(2), np.zeros(3))
    assert not values_equal(np.zeros(2), [0.0, 0.0])
    G = control.ss(0.5, 1, 1, 0, 1.0)
    assert values_equal(G, control.ss(0.5, 1, 1, 0, 1.0)) and not values_equal(G, control.ss(0.5, 1, 1, 0, 0.5))
    assert short_repr(G) == "<StateSpace: 1 output(s), 1 input(s), 1 state(s), dt=1.0>"
    assert short_repr(tuple(range(10))).endswith("… (10 items))")


def test_deferred_fields_are_read_only_once_computed_and_not_computed_by_the_constructor():
    import numpy as np

    from synthesis import fit_predictor
    from synthesis._lazy import _is_pending

    rng = np.random.default_rng(0)
    u = rng.standard_normal(400)
    y = np.convolve(u, [0.0, 0.5, 0.2])[:400] + 0.01 * rng.standard_normal(400)
    p = fit_predictor(u, y, 5)
    if p.solver == "triangular":  # the fast route defers its SVD; the constructor must not force it
        assert _is_pending(p, "singular_values")
    sv = p.singular_values
    assert not sv.flags.writeable and not p.Lw.flags.writeable
