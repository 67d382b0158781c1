"""A clipped sensor, seen in the record: unfalsify.clipped_outputs and the §7.4 pipeline's refusal."""
import numpy as np
import pytest

import unfalsify as uf
from experiments.lab.plants import third_order
from experiments.lab.servo_setup import design_weights
from experiments.lab.simulate import collect_data


def _uniform_record(seed=1):
    """The third-order plant under a uniform multilevel input in [−1, 1] (no two-level premise to state)."""
    u = np.random.default_rng(seed).uniform(-1.0, 1.0, 1200)
    d = collect_data(third_order(), u, process_noise=0.05, sensor_noise=0.05, seed=100 + seed)
    return u, d.y[:, 0]


def test_a_record_whose_output_is_clipped_is_refused():
    # measured before the check (a script, the output clipped at 50 %, seed 1, validation protocol): certified, and
    # without its δ margin on the plant (true δ‖K(I+PK)⁻¹‖∞ = 1.34). This quick run (no search, additive form) had
    # refused the record too, for the small gain; the refusal now names the clipping, whatever the loop
    u, y = _uniform_record()
    limit = 0.5 * np.max(np.abs(y))
    clipped = np.clip(y, -limit, limit)
    W = design_weights()
    with pytest.warns(uf.NotCertifiedWarning, match="clipped sensor"):
        r = uf.robust_design_from_data(u, clipped, 10, W["W11"], W["W21"], "auto", dt=0.1, window=(0, 49),
                                       search=False, certificate=uf.CertificateOptions(uncertainty="additive"))
    assert not r.certified and "Record within the sensor's range" in r.premise_reason
    assert "output 0 sits at its smallest value" in r.premise_reason


def test_unclipped_and_quantised_outputs_are_not_flagged():
    _, y = _uniform_record()
    assert uf.clipped_outputs(y) == ""
    step = 0.05 * np.ptp(y)  # a coarse sensor repeats every value, its extremes no more than the rest
    assert uf.clipped_outputs(np.round(y / step) * step) == ""
    two = np.column_stack([y, np.clip(y, None, 0.5 * np.max(y))])
    assert uf.clipped_outputs(two).startswith("output 1 sits at its largest value")


def test_a_record_at_rest_at_its_ends_is_not_called_clipped():
    """A noise-free record at rest for its first 50 samples under a 0/1 input sits at its smallest value, 0, there:
    that run is rest, not a sensor's limit (it had been refused as clipped).  Clipping later in the record is still
    found."""
    u = np.r_[np.zeros(50), (np.random.default_rng(0).standard_normal(950) > 0).astype(float), np.zeros(40)]
    y = np.zeros(u.size)
    for k in range(1, u.size):
        y[k] = 0.8 * y[k - 1] + 0.5 * u[k - 1]
    y[-40:] = y[-41]  # and held at its last value
    assert uf.clipped_outputs(y) == ""
    assert uf.clipped_outputs(np.clip(y, None, 0.8 * np.max(y))).startswith("output 0 sits at its largest value")
