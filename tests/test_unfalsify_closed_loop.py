"""The loop r → y keeps the controller's one state.

``u = C [r; y]`` shares the controller's state between its reference and feedback parts; a realisation as the
feedback loop through ``C_y`` in series with a separate ``C_r`` holds a second, open-loop copy of that state.  For an
open-loop unstable or integrating controller (common for H∞ designs and for tracking) that copy made the realisation
of a stable loop unstable: :func:`unfalsify.step_metrics` returned an infinite error and :func:`unfalsify.certify_loop`
refused the loop at its performance floor ("the controller does not track").  Second route: python-control's
``feedback`` of the same loop written with one controller of the error ``e = r − y``.
"""
import control
import numpy as np
import pytest

import unfalsify as uf
from synthesis import DataError

P = control.ss([[0.5]], [[1.0]], [[1.0]], [[0.0]], 1.0)  # 1/(z − 0.5)


def _error_controller(a, b, c, d):
    """``u = K_e (r − y)`` with ``K_e = d + c b/(z − a)``, as a controller with inputs ``[r; y]``."""
    return control.ss([[a]], [[b, -b]], [[c]], [[d, -d]], 1.0), control.ss([[a]], [[b]], [[c]], [[d]], 1.0)


@pytest.mark.parametrize("gains", [(1.2, 1.0, 0.6398, 1.3770),    # unstable controller pole 1.2, loop poles 0.50, 0.82
                                   (1.0, 1.0, 0.1, 0.3)])          # PI: an integrator, loop stable
def test_closed_loop_ry_of_a_stable_loop_with_an_unstable_or_integrating_controller(gains):
    K, Ke = _error_controller(*gains)
    reference = control.feedback(P * Ke, 1)
    assert np.max(np.abs(reference.poles())) < 1.0
    T = uf.closed_loop_ry(P, K)
    assert np.max(np.abs(T.poles())) < 1.0  # before: the controller's pole (1.2, or 1) once more
    np.testing.assert_allclose(np.sort(np.abs(T.poles())), np.sort(np.abs(reference.poles())), rtol=1e-9)
    y = np.asarray(control.step_response(reference, T=np.arange(300)).outputs).reshape(-1)
    m = uf.step_metrics(T, 300)
    assert m.final_error == pytest.approx(np.mean(np.abs(1.0 - y[-75:])), rel=1e-9, abs=1e-12)
    assert m.overshoot == pytest.approx(max(float(np.max(y)) - 1.0, 0.0), rel=1e-9, abs=1e-12)
    assert m.rise_samples == int(np.nonzero(y >= 0.9)[0][0])


def test_certify_loop_judges_the_step_of_the_loop_it_certifies():
    K, _ = _error_controller(1.2, 1.0, 0.6398, 1.3770)  # steady error 0.378 of the unit step
    cert = uf.certify_loop(P, K, 0.01, tracking_floor=0.5)
    assert cert.stable and cert.certified, cert.reason
    assert cert.step.final_error == pytest.approx(0.378, abs=1e-3)
    assert not uf.certify_loop(P, K, 0.01, tracking_floor=0.3).certified


def test_closed_loop_ry_with_feedthrough_and_several_channels():
    """Direct feedthrough on both sides (an algebraic loop, solved once) and a 2 × 2 plant against python-control."""
    rng = np.random.default_rng(3)
    Pm = control.ss(np.diag([0.5, -0.3]), rng.standard_normal((2, 2)), rng.standard_normal((2, 2)),
                    0.2 * rng.standard_normal((2, 2)), 0.1)
    Cr = control.ss([[0.9]], rng.standard_normal((1, 2)), rng.standard_normal((2, 1)), rng.standard_normal((2, 2)), 0.1)
    Ky = control.ss([], [], [], -0.2 * np.eye(2), 0.1)
    K = control.ss(Cr.A, np.hstack([Cr.B, np.zeros((1, 2))]), Cr.C, np.hstack([Cr.D, Ky.D]), 0.1)
    reference = control.feedback(Pm, Ky, sign=1) * Cr  # a static C_y: no state to share
    T = uf.closed_loop_ry(Pm, K)
    for w in (0.3, 1.7, 12.0):
        z = np.exp(1j * w * 0.1)
        np.testing.assert_allclose(T(z), reference(z), rtol=1e-10, atol=1e-12)
    assert T.nstates == 3


def test_closed_loop_ry_refuses_an_ill_posed_loop():
    K = control.ss([], [], [], [[0.0, 1.0]], 1.0)  # u = y and y = u: I − D_P D_y singular
    with pytest.raises(DataError, match="ill-posed"):
        uf.closed_loop_ry(control.ss([], [], [], [[1.0]], 1.0), K)


@pytest.mark.parametrize("gap", [1e-14, 3e-16])
def test_a_loop_that_cancels_to_rounding_is_ill_posed_in_the_realisation_and_at_dc(gap):
    """``1 − D_P D_y`` = 1e-14: a scalar's condition number is 1, so the realisation had been built with a gain of
    1e14 and the tracking check had read T(1) off it.  Both now call it ill-posed (one test of near-singularity)."""
    from unfalsify.tracking import _dc_errors_at_gain
    dy = (1.0 - gap) / 2.0
    K = control.ss([], [], [], [[0.0, dy]], 1.0)
    with pytest.raises(DataError, match="ill-posed"):
        uf.closed_loop_ry(control.ss([], [], [], [[2.0]], 1.0), K)
    assert np.isinf(_dc_errors_at_gain(K, 2.0, np.array([0.1]))).all()
    # a loop that does not cancel is unchanged: y = 2u, u = r − 0.25y, T = 2/(1 + 0.5)
    K_ok = control.ss([], [], [], [[1.0, -0.25]], 1.0)
    np.testing.assert_allclose(uf.closed_loop_ry(control.ss([], [], [], [[2.0]], 1.0), K_ok).D, [[2.0 / 1.5]])
    np.testing.assert_allclose(_dc_errors_at_gain(K_ok, 2.0, np.array([0.1])), [abs(1.0 - 2.0 / 1.5)])


@pytest.mark.parametrize("B, D, error", [([[1.0, -1.0]], [[0.5, -0.5]], 0.0),     # PI on r − y: tracks
                                         ([[0.0, -1.0]], [[0.5, 0.0]], 1.0),      # integrates y alone: T(1) = 0
                                         ([[1.0, 0.0]], [[0.0, -0.5]], np.inf)])  # integrates r alone: no steady state
def test_steady_error_at_a_static_gain_with_an_integrating_controller(B, D, error):
    """The tracking check's ``|1 − T(1)|`` at a static plant gain (the data's, or one of the coprime ball's) had read
    every controller with a pole at 1 as integral action (python-control's DC gain is then infinite in every entry):
    T(1) = 1 for all three.  Second route: python-control's step of the loop around the static plant 2."""
    from unfalsify.tracking import _dc_errors_at_gain

    K = control.ss([[1.0]], B, [[0.2]], D, 1.0)
    e = _dc_errors_at_gain(K, 2.0, np.array([0.1]))
    assert e[0] == pytest.approx(error, abs=1e-12) if np.isfinite(error) else np.isinf(e[0])
    if np.isfinite(error):  # python-control: the loop around the static plant 2, stepped
        T = uf.closed_loop_ry(control.ss([], [], [], [[2.0]], 1.0), K)
        y = np.asarray(control.step_response(T, T=np.arange(400)).outputs).reshape(-1)
        assert abs(1.0 - y[-1]) == pytest.approx(error, abs=1e-9)
