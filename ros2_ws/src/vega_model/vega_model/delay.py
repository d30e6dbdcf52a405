"""Time delays of the loop: Padé models for the synthesis, exact sampled delays for simulation.

Thesis §2.12.4: actuator 15 ms, sensors 12 ms, on-board computing 12 ms, 39 ms in total
with ±10 ms uncertainty, modelled there by a 2nd-order Padé approximation. Here:

* :class:`DelayParams` — the three delays from the ``delays`` section of vehicle.yaml;
* :func:`pade_ss` — the [n/n] Padé approximation of e^{−sτ} as a state-space model;
* :class:`DelayLine` — an exact delay of an integer number of physics steps, for the
  simulation (no approximation).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from vega_model.vehicle_data import VehicleData

__all__ = ["DelayParams", "pade_ss", "DelayLine"]


@dataclass(frozen=True)
class DelayParams:
    """Delays of the loop [s] (thesis §2.12.4).

    Attributes
    ----------
    actuator_s, sensor_s, computing_s
        TVC actuator, sensor (INS) and on-board computing delays [s].
    pade_order
        Order of the Padé approximation used for synthesis (thesis §2.12.4: 2).
    """

    actuator_s: float
    sensor_s: float
    computing_s: float
    pade_order: int

    def __post_init__(self):
        for name in ("actuator_s", "sensor_s", "computing_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f"DelayParams.{name} must be finite and >= 0, got {value!r}")
        if self.pade_order < 1:
            raise ValueError(f"DelayParams.pade_order must be >= 1, got {self.pade_order!r}")

    @property
    def total_s(self) -> float:
        """Total loop delay [s] (thesis: 39 ms nominal)."""
        return self.actuator_s + self.sensor_s + self.computing_s

    @classmethod
    def from_vehicle(cls, data: VehicleData) -> "DelayParams":
        """Delays from the ``delays`` section of the vehicle data file."""
        order = data["delays.pade_order"]
        if order != round(order):
            raise ValueError(f"delays.pade_order must be an integer, got {order!r}")
        return cls(actuator_s=data["delays.actuator_s"], sensor_s=data["delays.sensor_s"],
                   computing_s=data["delays.computing_s"], pade_order=int(round(order)))


def _pade_coefficients(order: int) -> np.ndarray:
    """Coefficients c_k, k = 0..n, of the [n/n] Padé denominator of e^{−x} in powers of x.

    D(x) = Σ c_k x^k, N(x) = Σ c_k (−x)^k, c_k = (2n−k)! n! / ((2n)! k! (n−k)!).
    """
    n = order
    return np.array([math.factorial(2 * n - k) * math.factorial(n)
                     / (math.factorial(2 * n) * math.factorial(k) * math.factorial(n - k))
                     for k in range(n + 1)])


def pade_ss(delay_s: float, order: int = 2):
    """State-space [n/n] Padé approximation of a pure delay e^{−sτ}.

    Parameters
    ----------
    delay_s
        Delay τ ≥ 0 [s].
    order
        Order n ≥ 1 (default 2, thesis §2.12.4).

    Returns
    -------
    A, B, C, D : numpy.ndarray
        Shapes n×n, n×1, 1×n, 1×1. For τ = 0: empty A, B, C and D = [[1]].

    Notes
    -----
    The approximation is N(sτ)/D(sτ) with the coefficients of :func:`_pade_coefficients`
    (the same transfer function as ``control.pade``). It is realised in controllable
    canonical form in the normalised variable x = sτ and the time scale is applied
    afterwards (A = A_x/τ, B = B_x/τ), which keeps the realisation well conditioned.
    """
    tau = float(delay_s)
    if not (math.isfinite(tau) and tau >= 0.0):
        raise ValueError(f"delay_s must be finite and >= 0, got {delay_s!r}")
    if int(order) != order or order < 1:
        raise ValueError(f"order must be an integer >= 1, got {order!r}")
    n = int(order)
    if tau == 0.0:
        return np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), np.ones((1, 1))
    c = _pade_coefficients(n)
    den = c / c[n]                              # monic in x, ascending powers
    num = c * (-1.0) ** np.arange(n + 1) / c[n]
    d = num[n]                                  # = (−1)^n
    A = np.zeros((n, n))
    A[:-1, 1:] = np.eye(n - 1)
    A[-1, :] = -den[:n]
    B = np.zeros((n, 1))
    B[-1, 0] = 1.0
    C = (num[:n] - d * den[:n]).reshape(1, n)
    return A / tau, B / tau, C, np.array([[d]])


class DelayLine:
    """Exact delay of ``delay_s`` = N·``dt_s`` for a signal sampled every ``dt_s``.

    ``push(v_k)`` returns v_{k−N}; before N values have been pushed it returns the
    initial value. N = 0 passes the value through.

    Parameters
    ----------
    delay_s
        Delay [s]; must be an integer multiple of ``dt_s`` within 1e-9·dt_s.
    dt_s
        Sample period [s].
    initial
        Output until the first pushed value emerges (any object, e.g. a float or a tuple).

    Raises
    ------
    ValueError
        If the delay is negative, not finite, or not an integer number of steps.
    """

    def __init__(self, delay_s: float, dt_s: float, initial=0.0):
        if not (math.isfinite(dt_s) and dt_s > 0.0):
            raise ValueError(f"dt_s must be finite and > 0, got {dt_s!r}")
        if not (math.isfinite(delay_s) and delay_s >= 0.0):
            raise ValueError(f"delay_s must be finite and >= 0, got {delay_s!r}")
        n = round(delay_s / dt_s)
        if abs(n * dt_s - delay_s) > 1e-9 * dt_s:
            raise ValueError(f"delay {delay_s!r} s is not an integer multiple of the "
                             f"step {dt_s!r} s")
        self.n_steps = int(n)
        self.delay_s = float(delay_s)
        self.dt_s = float(dt_s)
        self.reset(initial)

    def reset(self, initial=0.0) -> None:
        """Empty the line: the next N outputs are ``initial``."""
        self._buffer = [initial] * self.n_steps
        self._index = 0

    def push(self, value):
        """Insert the newest sample; return the sample pushed N steps before."""
        if self.n_steps == 0:
            return value
        i = self._index
        out = self._buffer[i]
        self._buffer[i] = value
        self._index = i + 1 if i + 1 < self.n_steps else 0
        return out
