"""Independent reference for the TVC actuator tests: the analytic step response of the
second-order actuator model (not the code under test)."""

import numpy as np


def analytic_step(u, t, wn, zeta):
    """β, β̇ of ω²/(s² + 2ζωs + ω²) for a step u at t = 0 from rest (0 < ζ < 1); t scalar or
    array [s]."""
    wd = wn * np.sqrt(1.0 - zeta ** 2)
    e = np.exp(-zeta * wn * t)
    beta = u * (1.0 - e * (np.cos(wd * t) + zeta * wn / wd * np.sin(wd * t)))
    beta_dot = u * wn ** 2 / wd * e * np.sin(wd * t)
    return beta, beta_dot
