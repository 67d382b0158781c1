"""Test data shared by the unfalsification tests: the servo as a rounded ARX(2, 2) model.

Servo 1/(s(s+1)) ZOH at 10 Hz, (5.6), coefficients rounded: generated with ``scipy.signal.lfilter``
so that the data do not depend on the package under test.
"""
import numpy as np
import scipy.signal

A_SERVO = [1.0, -1.904837, 0.904837]
B_SERVO = [0.0, 0.004837, 0.004679]


def servo_arx_data(n, seed, noise=0.03):
    """±1 random binary input and the ARX servo's output plus white noise of std ``noise`` (seeded)."""
    rng = np.random.default_rng(seed)
    u = np.sign(rng.standard_normal(n))
    y = scipy.signal.lfilter(B_SERVO, A_SERVO, u) + noise * rng.standard_normal(n)
    return u, y
