"""INS sensor model: INS-location kinematics with bending, noise, sampling and latency.

The measured pitch, pitch rate, drift and drift rate are the kinematics at the INS
location (thesis Eqs. 2.33–2.36), computed by :func:`vega_model.dynamics.ins_outputs` —
the one implementation shared with the plant model — plus white Gaussian noise with the
standard deviations of thesis Eq. 4.18 (0.02°, 0.01°/s, 0.01 m, 0.001 m/s). The INS also
measures the longitudinal velocity the controller is scheduled on (thesis: ρ = v_x); its
noise level is an assumption (vehicle.yaml ``ins.noise_velocity_mps``).

Timing: the INS samples the truth at t_k = k / rate and the sample becomes available to
the flight software ``latency_s`` later (the 12 ms sensor delay of thesis §2.12.4);
:func:`sample_schedule` lists both times. In a lockstep simulation at the physics rate,
measure at the sample steps and pass the samples through a
:class:`vega_model.delay.DelayLine` of ``latency_s``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from vega_model.dynamics import ins_outputs_tuple
from vega_model.parameters import ModelParameters
from vega_model.vehicle_data import VehicleData

__all__ = ["InsParams", "InsSample", "InsSensor", "sample_schedule"]

# Samples' worth of noise drawn from the generator at a time (a performance detail only: the
# sequence is the same as five draws per sample).
_SAMPLE_BLOCK = 256


@dataclass(frozen=True)
class InsParams:
    """INS parameters (SI units).

    Attributes
    ----------
    rate_hz
        Output rate [Hz] (assumption, vehicle.yaml ``ins.rate_hz``).
    latency_s
        Time from sampling to availability [s] (thesis §2.12.4 sensor delay, 12 ms).
    sigma_theta_rad, sigma_theta_dot_radps, sigma_z_m, sigma_z_dot_mps
        1-σ white noise on θ_INS, θ̇_INS, z_INS, ż_INS (thesis Eq. 4.18).
    sigma_velocity_mps
        1-σ white noise on the measured longitudinal velocity (assumption).
    """

    rate_hz: float
    latency_s: float
    sigma_theta_rad: float
    sigma_theta_dot_radps: float
    sigma_z_m: float
    sigma_z_dot_mps: float
    sigma_velocity_mps: float

    def __post_init__(self):
        if not (math.isfinite(self.rate_hz) and self.rate_hz > 0.0):
            raise ValueError(f"InsParams.rate_hz must be finite and > 0, got {self.rate_hz!r}")
        for name in ("latency_s", "sigma_theta_rad", "sigma_theta_dot_radps", "sigma_z_m",
                     "sigma_z_dot_mps", "sigma_velocity_mps"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f"InsParams.{name} must be finite and >= 0, got {value!r}")

    @classmethod
    def from_vehicle(cls, data: VehicleData) -> "InsParams":
        """INS parameters from the ``ins`` and ``delays`` sections of the vehicle data file."""
        return cls(
            rate_hz=data["ins.rate_hz"],
            latency_s=data["delays.sensor_s"],
            sigma_theta_rad=data["ins.noise_pitch_rad"],
            sigma_theta_dot_radps=data["ins.noise_pitch_rate_radps"],
            sigma_z_m=data["ins.noise_drift_m"],
            sigma_z_dot_mps=data["ins.noise_drift_rate_mps"],
            sigma_velocity_mps=data["ins.noise_velocity_mps"],
        )


class InsSample(NamedTuple):
    """One INS measurement (SI units)."""

    theta_rad: float
    theta_dot_radps: float
    z_m: float
    z_dot_mps: float
    velocity_mps: float


class InsSensor:
    """Seeded INS measurement model.

    Parameters
    ----------
    params
        INS parameters.
    seed
        Seed of the ``numpy`` PCG64 generator of the noise (same seed, same noise).
    noise
        False gives the exact kinematics (no random draws).
    """

    def __init__(self, params: InsParams, seed: int = 0, noise: bool = True):
        self.params = params
        self.seed = int(seed)
        self.noise = bool(noise)
        self._sigma = np.array([params.sigma_theta_rad, params.sigma_theta_dot_radps,
                                params.sigma_z_m, params.sigma_z_dot_mps,
                                params.sigma_velocity_mps])
        self._sigma_f = tuple(self._sigma.tolist())
        self.reset()

    def reset(self) -> None:
        """Restart the noise sequence from the seed."""
        self._rng = np.random.Generator(np.random.PCG64(self.seed))
        self._noise: list[float] = []
        self._next = 0

    def measure(self, x_truth, model_params: ModelParameters, velocity_mps: float) -> InsSample:
        """Measure the truth state.

        Parameters
        ----------
        x_truth
            Plant state [θ, θ̇, z, ż, q1, q2, q̇1, q̇2].
        model_params
            Model parameters at the sample time (INS lever arm and mode shapes).
        velocity_mps
            True longitudinal velocity v_x [m/s] (the scheduling variable).

        Returns
        -------
        InsSample
            Thesis Eqs. 2.33–2.36 via :func:`vega_model.dynamics.ins_outputs`, plus
            N(0, σ²) noise per channel (Eq. 4.18) when ``noise`` is on.
        """
        th, thd, z, zd = ins_outputs_tuple(model_params, x_truth)
        v = float(velocity_mps)
        if not self.noise:
            return InsSample(th, thd, z, zd, v)
        # five draws per sample, taken from the generator in blocks (the same sequence as
        # standard_normal(5) per sample); y + σ·n as numpy's y += σ * n computes it
        i = self._next
        if i == len(self._noise):
            self._noise = self._rng.standard_normal(5 * _SAMPLE_BLOCK).tolist()
            i = 0
        n = self._noise
        s0, s1, s2, s3, s4 = self._sigma_f
        self._next = i + 5
        return InsSample(th + s0 * n[i], thd + s1 * n[i + 1], z + s2 * n[i + 2],
                         zd + s3 * n[i + 3], v + s4 * n[i + 4])


def sample_schedule(params: InsParams, t_end_s: float, t_start_s: float = 0.0):
    """Sample times t_k = k / rate in [t_start_s, t_end_s] and their availability times.

    Returns
    -------
    t_sample_s, t_available_s : numpy.ndarray
        ``t_available_s = t_sample_s + latency_s``.
    """
    rate = params.rate_hz
    eps = 1e-9  # [samples] rounding allowance, so that t_end = k / rate is included
    k0 = math.ceil(t_start_s * rate - eps)
    k1 = math.floor(t_end_s * rate + eps)
    t = np.arange(k0, k1 + 1) / rate
    return t, t + params.latency_s
