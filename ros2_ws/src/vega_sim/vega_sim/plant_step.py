"""The truth side of the closed loop as step functions: parameters, wind and plant.

Plain Python, no ROS: the in-process simulation (:mod:`vega_sim.closed_loop`) and the SIL
plant node run this same code. Nothing here re-derives the physics: the equations are
:mod:`vega_model.dynamics`, the parameters :mod:`vega_model.parameters`, the wind
:mod:`vega_model.wind`.

* :class:`ParameterTrack` — model parameters along the flight, evaluated once per refresh
  interval (default: once per 10 ms frame, at its start — they vary slowly; the effect of
  refreshing every 1 ms is measured in tests/sim/test_closed_loop.py) and, for the linear plant,
  the exact zero-order-hold discretisation of :func:`vega_model.dynamics.linear_model`.
* :class:`PlantWind` — the wind along +z at the physics rate: :class:`vega_model.wind.WindModel`
  plus, optionally, the thesis' constant-driven Dryden filter (:func:`thesis_dryden_coefficients`).
* :class:`PlantStep` — the plant, linear or nonlinear, integrated one frame at a time from the
  actuator's physics-rate samples; publishes :class:`vega_bus.records.TruthOut` (the fields
  of ``vega_msgs/VehicleState``; re-exported here) at every frame time.

Inputs over one physics step [t_k, t_k+1] are held at their step means, from the actuator
samples at both ends: β̄ = (β_k + β_k+1)/2 (trapezoid), the rate likewise, and
β̈̄ = (β̇_k+1 − β̇_k)/dt, the exact mean of β̈ since β̇ is continuous (a command step makes β̈
jump inside the step). The wind is held at its value at the step start. The linear plant
propagates these held inputs exactly (ZOH); the nonlinear plant integrates them with RK4.
"""

from __future__ import annotations

import math
from functools import lru_cache
from collections.abc import Sequence
from typing import Mapping, NamedTuple

import numpy as np

from vega_core.errors import BadInput

from vega_bus.records import TruthOut

from vega_model.dynamics import (STATES, NonlinearModel, alpha_and_q_alpha, angle_of_attack,
                                 linear_model)
from vega_model.parameters import ModelContext, ModelParameters
from vega_model.vehicle_data import VehicleData
from vega_model.wind import (GustProfile, ProfileChange, WindModel, WindTable,
                             turbulence_params)

__all__ = [
    "PLANT_MODELS", "THESIS_DRYDEN_WEIGHT", "TruthOut", "LinearFrames", "parameters_at",
    "ParameterTrack", "parameter_track", "table_span_ms", "thesis_dryden_coefficients",
    "PlantWind", "PlantStep",
]

PLANT_MODELS = ("linear", "nonlinear")

# W_w: the thesis drove its Dryden filter with a constant 1 through this weight (thesis §4.5.1,
# "three standard deviations"; the same number as vega_lpv.weights.THESIS.wind_sigmas).
THESIS_DRYDEN_WEIGHT = 3.0

_N = len(STATES)
# Chunk of augmented matrices handed to one batched expm call (bounds the temporary memory).
_EXPM_CHUNK = 4096


class LinearFrames(NamedTuple):
    """The linear plant over whole frames: x(t_f+1) = H[f] [x(t_f); U_f].

    ``H[f] = [F | G]`` with F the frame's state transition and G the input matrix of
    ``U_f``, which stacks the held inputs ``[β̄, β̈̄, v_w]`` of the frame's physics steps,
    oldest first. ``q_alpha_x[e]`` and ``q_alpha_wind[e]`` are the Qα row of C and the wind
    entry of D at parameter entry ``e``.
    """

    H: np.ndarray
    q_alpha_x: np.ndarray
    q_alpha_wind: np.ndarray


def _expm_batched(m: np.ndarray) -> np.ndarray:
    """Matrix exponentials of a stack of small matrices (…, n, n).

    Scaling and squaring with a degree-10 Taylor polynomial (Horner form): with
    ‖M/2^s‖₁ ≤ 1/4 the truncation error is below 0.25^11/11! ≈ 6e-15. Batched numpy products
    only (tests/sim/test_closed_loop.py compares it with ``scipy.linalg.expm``): scipy's expm works
    matrix by matrix, which is ~10× slower for thousands of 11×11 matrices.
    """
    norm = float(np.abs(m).sum(axis=-2).max()) if m.size else 0.0
    s = max(0, math.ceil(math.log2(norm / 0.25))) if norm > 0.0 else 0
    x = m / 2.0 ** s
    eye = np.eye(m.shape[-1])
    e = eye + x / 10.0
    for k in range(9, 0, -1):
        e = eye + (x @ e) / k
    for _ in range(s):
        e = e @ e
    return e


def parameters_at(context: ModelContext, t_ms: int,
                  deviations: Mapping[str, float] | None = None) -> ModelParameters:
    """The truth model parameters at ``t_ms`` (perturbed by ``deviations`` if any is non-zero).

    The one evaluation every truth-side node uses (plant, wind, INS), so that they agree bit
    for bit: ``context.parameters(t_ms / 1000)``, then :meth:`ModelParameters.perturbed`.
    """
    p = context.parameters(t_ms / 1000.0)
    if deviations and any(deviations.values()):
        p = p.perturbed(deviations)
    return p


def table_span_ms(time_range_s: tuple[float, float], frame_ms: int) -> tuple[float, float]:
    """(earliest t_start, latest t_end) [ms] of a run on a flight-condition table whose times
    span ``time_range_s`` [s]: the run's parameters (:class:`ParameterTrack`) reach one frame
    past t_end. The one rule both :class:`ParameterTrack` and the scenario check
    (:mod:`vega_sim.scenario`) apply."""
    lo, hi = time_range_s
    return 1000.0 * lo, 1000.0 * hi - frame_ms


class ParameterView(NamedTuple):
    """The fields of a parameter set that the truth and the INS read every frame, under their
    :class:`ModelParameters` names (``l_cp_m`` = x_CP − x_CG and ``l_ins_m`` = x_INS − x_CG, the
    properties' operations): what :func:`vega_model.dynamics.alpha_and_q_alpha`,
    :func:`~vega_model.dynamics.angle_of_attack` and
    :func:`~vega_model.dynamics.ins_outputs_tuple` read, at ≈ 1/3 of a
    :class:`ModelParameters`' cost to build (a Monte Carlo flight builds 10 001)."""

    v_mps: float
    q_pa: float
    mach: float
    h_m: float
    rho_kgpm3: float
    l_cp_m: float
    psi_t_ins: tuple[float, float]
    psi_r_ins: tuple[float, float]
    l_ins_m: float


class _LazyParameters(Sequence):
    """The parameter sets of a track, each built on first access
    (:meth:`ModelContext.parameters_from_columns`, then kept)."""

    def __init__(self, context: ModelContext, columns: Mapping[str, np.ndarray], n: int):
        self._context, self._columns = context, columns
        self._items: list[ModelParameters | None] = [None] * n

    def __len__(self) -> int:
        return len(self._items)

    def __getitem__(self, index):
        if isinstance(index, slice):
            return [self[i] for i in range(*index.indices(len(self._items)))]
        p = self._items[index]
        if p is None:
            e = range(len(self._items))[index]
            p = self._items[e] = self._context.parameters_from_columns(self._columns, e)
        return p


class ParameterTrack:
    """Model parameters along [t_start, t_end + one frame), one set per refresh interval.

    Parameters
    ----------
    context
        The model's data sources (:class:`vega_model.parameters.ModelContext`).
    t_start_ms, t_end_ms
        Simulated span [ms], multiples of ``frame_ms``. The track runs one frame past the
        end so that the truth at ``t_end`` has its wind and parameters.
    frame_ms, refresh_ms, dt_ms
        Frame, parameter refresh interval (a divisor of the frame; default: the frame) and
        physics step (a divisor of the refresh interval) [ms].
    deviations
        Uncertainty deviations by name (:meth:`ModelParameters.perturbed`; names of other
        models are ignored there). Empty: the nominal model.

    Notes
    -----
    Entry ``e`` holds :func:`parameters_at` (t_e) with t_e = t_start + e·refresh: the
    parameters are held constant over each refresh interval (a zero-order hold of slowly
    varying data; the sensitivity to the interval is measured in tests/sim/test_closed_loop.py).
    Objects are read-only once built and may be shared.
    """

    def __init__(self, context: ModelContext, t_start_ms: int, t_end_ms: int, *,
                 frame_ms: int = 10, refresh_ms: int = 10, dt_ms: int = 1,
                 deviations: Mapping[str, float] | None = None):
        if frame_ms % refresh_ms or refresh_ms % dt_ms:
            raise BadInput(f"parameter refresh {refresh_ms} ms must divide the frame "
                           f"({frame_ms} ms) and be a multiple of the step ({dt_ms} ms)")
        if t_start_ms % frame_ms or t_end_ms % frame_ms or t_end_ms <= t_start_ms:
            raise BadInput(f"span [{t_start_ms}, {t_end_ms}] ms must be whole frames of "
                           f"{frame_ms} ms with t_end > t_start")
        first_ms, last_ms = table_span_ms(context.time_range_s, frame_ms)
        if t_start_ms < first_ms or t_end_ms > last_ms:
            raise BadInput(f"span [{t_start_ms / 1000}, {t_end_ms / 1000}] s is outside the "
                           f"flight-condition table [{first_ms / 1000}, {last_ms / 1000}] s")
        self.context = context
        self.t_start_ms, self.t_end_ms = int(t_start_ms), int(t_end_ms)
        self.frame_ms, self.refresh_ms, self.dt_ms = int(frame_ms), int(refresh_ms), int(dt_ms)
        self.deviations = dict(deviations or {})
        n = (t_end_ms - t_start_ms + frame_ms) // refresh_ms
        # parameters_at(context, t_start + refresh·e, deviations) for every e, on arrays
        # (ModelContext.parameters_at_times: the same numbers); the objects are built on first
        # access, the per-frame readers take the views
        times = (t_start_ms + refresh_ms * np.arange(n, dtype=np.int64)) / 1000.0
        columns = context.parameter_columns_at_times(times, self.deviations)
        self._views: tuple[ParameterView, ...] | None = None
        self._view_array: np.ndarray | None = None
        if columns is None:                          # a custom aerodynamic model
            self._columns: dict[str, np.ndarray] = {}
            self.params: Sequence[ModelParameters] = tuple(
                context.parameters_at_times(times, self.deviations))
            self._views = tuple(
                ParameterView(p.v_mps, p.q_pa, p.mach, p.h_m, p.rho_kgpm3, p.l_cp_m,
                              p.psi_t_ins, p.psi_r_ins, p.l_ins_m) for p in self.params)
        else:
            self._columns = columns
            self.params = _LazyParameters(context, columns, n)
        self._linear: LinearFrames | None = None
        self._nonlinear: list[NonlinearModel | None] = [None] * n
        self._kernel: tuple | None = None

    @property
    def views(self) -> tuple[ParameterView, ...]:
        """The :class:`ParameterView` of every entry (built on first access from
        :meth:`view_array`, then shared)."""
        if self._views is None:
            self._views = tuple(
                ParameterView(v, q, m, h, r, lcp, (t0, t1), (r0, r1), li)
                for v, q, m, h, r, lcp, t0, t1, r0, r1, li in self.view_array().tolist())
        return self._views

    def view_array(self) -> np.ndarray:
        """The fields of every entry's :class:`ParameterView` as rows of a read-only float
        array (entries, 11), the mode-shape pairs flattened: v_mps, q_pa, mach, h_m,
        rho_kgpm3, l_cp_m, psi_t_ins (2), psi_r_ins (2), l_ins_m. The views are these numbers
        (the batched engine, :mod:`vega_sim.batch`, reads the array)."""
        if self._view_array is None:
            if self._columns:
                c = self._columns
                rows = np.column_stack((
                    c["v_mps"], c["q_pa"], c["mach"], c["h_m"], c["rho_kgpm3"],
                    c["x_cp_m"] - c["x_cg_m"], c["psi_t_ins_0"], c["psi_t_ins_1"],
                    c["psi_r_ins_0"], c["psi_r_ins_1"], self.params[0].x_ins_m - c["x_cg_m"]))
                rows = rows.astype(float, copy=False)
            else:
                rows = np.array([(p.v_mps, p.q_pa, p.mach, p.h_m, p.rho_kgpm3, p.l_cp_m,
                                  *p.psi_t_ins, *p.psi_r_ins, p.l_ins_m) for p in self._views],
                                dtype=float)
            rows.setflags(write=False)
            self._view_array = rows
        return self._view_array

    @property
    def n_frames(self) -> int:
        """Frames in [t_start, t_end)."""
        return (self.t_end_ms - self.t_start_ms) // self.frame_ms

    def entry(self, t_ms: int) -> int:
        """Index of the parameter entry in force at ``t_ms``."""
        return (t_ms - self.t_start_ms) // self.refresh_ms

    def at_ms(self, t_ms: int) -> ModelParameters:
        """Parameters in force at ``t_ms``."""
        return self.params[(t_ms - self.t_start_ms) // self.refresh_ms]

    def view_ms(self, t_ms: int) -> ParameterView:
        """The :class:`ParameterView` of the parameters in force at ``t_ms``."""
        return self.views[(t_ms - self.t_start_ms) // self.refresh_ms]

    def kernel_inputs(self) -> tuple:
        """(constants of every entry, Mach tables) for the compiled nonlinear plant
        (:func:`vega_model.nonlinear_kernel.rk4_frame`; built once, then shared)."""
        if self._kernel is None:
            from vega_model.kernel_inputs import entry_constants, mach_tables

            if self._columns:
                consts = _entry_constants_of_columns(self._columns, self.params[0])
            else:
                consts = np.array([entry_constants(p) for p in self.params], dtype=float)
            consts.setflags(write=False)
            self._kernel = (consts, mach_tables(self.params[0]))
        return self._kernel

    def nonlinear_model(self, e: int) -> NonlinearModel:
        """The nonlinear model of parameter entry ``e`` (built on first use, then shared)."""
        model = self._nonlinear[e]
        if model is None:
            model = self._nonlinear[e] = NonlinearModel(self.params[e])
        return model

    def linear_frames(self) -> LinearFrames:
        """The linear plant's frame maps (computed once, then shared).

        Each physics step is the exact ZOH discretisation of linear_model(p) for the entry in
        force, [[Φ, Γ], [0, I]] = exp([[A, B], [0, 0]]·dt) (the input columns are scaled to
        unit norm before the exponential and back after, which leaves Γ exact and keeps the
        norm small), and the steps of a frame are composed into F = Φ_{K−1}…Φ_0 and
        G = [Φ_{K−1}…Φ_1 Γ_0, …, Γ_{K−1}].
        """
        if self._linear is None:
            self._linear = self._build_linear()
        return self._linear

    def _build_linear(self) -> LinearFrames:
        n_e = len(self.params)
        models = [linear_model(p) for p in self.params]
        dt = self.dt_ms / 1000.0
        aug = np.zeros((n_e, _N + 3, _N + 3))
        aug[:, :_N, :_N] = np.array([m[0] for m in models]) * dt
        aug[:, :_N, _N:] = np.array([m[1] for m in models]) * dt
        q_alpha_x = np.array([m[2][0] for m in models])
        q_alpha_wind = np.array([m[3][0, 2] for m in models])
        col = np.maximum(np.abs(aug[:, :_N, _N:]).sum(axis=1), 1.0)    # (n_e, 3)
        aug[:, :_N, _N:] /= col[:, None, :]
        phi = np.empty((n_e, _N, _N))
        gam = np.empty((n_e, _N, 3))
        for s in range(0, n_e, _EXPM_CHUNK):
            block = _expm_batched(aug[s:s + _EXPM_CHUNK])
            phi[s:s + _EXPM_CHUNK] = block[:, :_N, :_N]
            gam[s:s + _EXPM_CHUNK] = block[:, :_N, _N:] * col[s:s + _EXPM_CHUNK, None, :]
        steps = self.frame_ms // self.dt_ms
        frame_entries = np.arange(self.n_frames) * (self.frame_ms // self.refresh_ms)
        H = np.empty((self.n_frames, _N, _N + 3 * steps))
        prod = np.broadcast_to(np.eye(_N), (self.n_frames, _N, _N)).copy()
        for k in range(steps - 1, -1, -1):
            e = frame_entries + (k * self.dt_ms) // self.refresh_ms
            H[:, :, _N + 3 * k:_N + 3 * k + 3] = prod @ gam[e]
            prod = prod @ phi[e]
        H[:, :, :_N] = prod
        for arr in (H, q_alpha_x, q_alpha_wind):
            arr.setflags(write=False)
        return LinearFrames(H, q_alpha_x, q_alpha_wind)


def _entry_constants_of_columns(columns: Mapping[str, np.ndarray],
                                first: ModelParameters) -> np.ndarray:
    """:func:`vega_model.nonlinear_kernel.entry_constants` of every entry, as rows, from the
    track's columns (:meth:`ModelContext.parameters_at_times`; ``first``: an entry, for the
    fields that do not vary): the same operations on arrays, element by element, so the same
    numbers (tests/sim/test_closed_loop.py compares them with ``entry_constants``)."""
    c = columns
    T, m, J = c["thrust_n"], c["mass_kg"], c["jyy_kgm2"]
    lc, d = c["x_cg_m"] - first.x_pvp_m, c["x_cp_m"] - c["x_cg_m"]
    mn, ln, jn = first.nozzle_mass_kg, first.nozzle_lever_m, first.nozzle_inertia_kgm2
    rp0, rp1 = c["psi_r_pvp_0"], c["psi_r_pvp_1"]
    w1, w2 = 2.0 * math.pi * c["f1_hz"], 2.0 * math.pi * c["f2_hz"]
    zeta = first.zeta
    n = T.size
    return np.column_stack((
        c["v_mps"], c["sound_speed_mps"], np.full(n, first.s_ref_m2), 0.5 * c["rho_kgpm3"],
        d, T, m, J, lc, c["psi_t_pvp_0"], c["psi_t_pvp_1"], rp0, rp1, np.full(n, -mn * ln),
        -T, lc * T, np.full(n, jn), jn * rp0, jn * rp1, -w1 * w1, 2.0 * zeta * w1, -w2 * w2,
        2.0 * zeta * w2, np.full(n, first.aero.crossflow_coefficient)))


@lru_cache(maxsize=4)
def _cached_track(context, t_start_ms, t_end_ms, frame_ms, refresh_ms, dt_ms, deviations):
    return ParameterTrack(context, t_start_ms, t_end_ms, frame_ms=frame_ms,
                          refresh_ms=refresh_ms, dt_ms=dt_ms, deviations=dict(deviations))


def parameter_track(context: ModelContext, t_start_ms: int, t_end_ms: int, *,
                    frame_ms: int = 10, refresh_ms: int = 10, dt_ms: int = 1,
                    deviations: Mapping[str, float] | None = None) -> ParameterTrack:
    """A :class:`ParameterTrack`, memoised per (context, span, intervals, deviations).

    The track is a deterministic function of its arguments and read-only, so repeated runs of
    one span (seeds, scenarios, Monte Carlo with the same deviations) share one precomputation.
    """
    key = tuple(sorted((str(k), float(v)) for k, v in (deviations or {}).items()))
    return _cached_track(context, int(t_start_ms), int(t_end_ms), int(frame_ms),
                         int(refresh_ms), int(dt_ms), key)


def thesis_dryden_coefficients(h_m, airspeed_mps, data: VehicleData, intensity: str,
                               dt_s: float):
    """One exact ZOH step of the Dryden filter (Eq. 2.53) driven by a constant unit input.

    Parameters
    ----------
    h_m, airspeed_mps
        Altitude [m] and airspeed V ≥ 0 [m/s] (arrays or scalars).
    data, intensity
        Vehicle data and Table 2.4 intensity (:func:`vega_model.wind.turbulence_params`).
    dt_s
        Step [s].

    Returns
    -------
    a, g : numpy.ndarray
        x_{k+1} = a x_k + g for the filter state x (output v = x) with input n_w = 1.

    Notes
    -----
    The filter is :func:`vega_model.wind.dryden_ss`: ẋ = −(V/L_w) x + σ_w √(2V/(π L_w)) n_w
    (airspeed form, docs/ENVIRONMENT_MODELS.md §3.2), so a = exp(−V dt/L_w) and
    g = σ_w √(2V/(π L_w)) (1 − a)/(V/L_w), which tends to 0 as V → 0. The steady state is the
    filter's DC gain σ_w √(2 L_w/(π V)).
    """
    sigma, ell = turbulence_params(np.asarray(h_m, dtype=float), data, intensity)
    v = np.abs(np.asarray(airspeed_mps, dtype=float))
    rate = v / ell
    a = np.exp(-rate * dt_s)
    moving = rate > 0.0
    frac = np.where(moving, -np.expm1(-rate * dt_s) / np.where(moving, rate, 1.0), dt_s)
    gain = sigma * np.sqrt(2.0 * v / (math.pi * ell))
    return a, gain * frac


class PlantWind:
    """Wind v_w along +z, stepped at the physics rate (thesis §2.12.5).

    Parameters
    ----------
    data
        Vehicle data.
    track
        Parameters in force at each step: altitude ``h_m`` and airspeed ``v_mps`` of the
        reference trajectory (the wind is then independent of the plant state, so the linear
        and nonlinear plants see the same wind sequence).
    profile, turbulence, gust, seed
        As :class:`vega_model.wind.WindModel` (``profile`` True for Eq. 2.54, False for none,
        or a :class:`vega_model.wind.WindTable`; ``gust`` a :class:`GustProfile` or None).
    thesis_constant_dryden
        If true, the turbulence is not the seeded random Dryden process but the thesis'
        deterministic input (thesis §5.2, Fig. 5.2): W_w = 3 times the response of the
        Dryden filter of intensity ``turbulence`` to a constant unit input, from a zero state
        at the first step; discretised exactly per step with the parameters in force
        (:func:`thesis_dryden_coefficients`).
    dt_ms
        Physics step [ms].
    change
        Change of the steady profile (:class:`vega_model.wind.ProfileChange`; default none).
    """

    def __init__(self, data: VehicleData, track: ParameterTrack, *, profile: bool | WindTable,
                 turbulence: str, gust: GustProfile | None, seed: int,
                 thesis_constant_dryden: bool = False, dt_ms: int = 1,
                 change: ProfileChange | None = None):
        self._model = WindModel(data, profile=profile,
                                turbulence="none" if thesis_constant_dryden else turbulence,
                                gust=gust, seed=seed, dt_s=dt_ms / 1000.0,
                                change=change if change is not None else ProfileChange())
        self._track = track
        self._dt_ms = int(dt_ms)
        # a WindModel with every part off returns exactly 0.0: skip it
        self._active = self._model.profile or gust is not None or (
            turbulence != "none" and not thesis_constant_dryden)
        self._thesis = bool(thesis_constant_dryden)
        if self._thesis:
            h, v = track.view_array()[:, 3].tolist(), track.view_array()[:, 0].tolist()
            a, g = thesis_dryden_coefficients(h, v, data, turbulence, dt_ms / 1000.0)
            self._a, self._g = a.tolist(), g.tolist()
        self._state = 0.0
        self._sequence: list[float] | None = None
        self._array: np.ndarray | None = None

    def _whole_track(self) -> list[float]:
        """v_w at every physics step of the track, from its start: one
        :meth:`WindModel.steps` per parameter entry in order (its altitude and airspeed), as
        :meth:`WindModel.entry_steps` computes them at once."""
        if self._sequence is None:
            track = self._track
            views = track.view_array()                  # the views' h_m and v_mps
            self._sequence = self._model.entry_steps(
                track.t_start_ms, self._dt_ms, track.refresh_ms // self._dt_ms,
                views[:, 3].tolist(), views[:, 0].tolist())
            self._array = np.array(self._sequence)
        return self._sequence

    def frame_and_array(self, t_ms: int, n_steps: int) -> tuple[list[float], np.ndarray]:
        """:meth:`frame` and the same numbers as a float array (not to be written)."""
        if self._active and not self._thesis:
            j = (t_ms - self._track.t_start_ms) // self._dt_ms
            out = self._whole_track()[j:j + n_steps]
            return out, self._array[j:j + n_steps]
        out = self.frame(t_ms, n_steps)
        return out, np.array(out, dtype=float)

    def frame(self, t_ms: int, n_steps: int) -> list[float]:
        """Advance ``n_steps`` physics steps from ``t_ms``; return v_w held over each [m/s].

        Frames follow each other from the track's start (:class:`PlantStep`); the sequence
        of the whole track is drawn at the first call (the wind does not depend on the plant
        state), the same numbers as drawing it frame by frame."""
        track = self._track
        t0, refresh, dt = track.t_start_ms, track.refresh_ms, self._dt_ms
        if self._active:
            j = (t_ms - t0) // dt
            out = self._whole_track()[j:j + n_steps]
        else:
            out = [0.0] * n_steps
        if not self._thesis:
            return out
        for k in range(n_steps):
            e = (t_ms + k * dt - t0) // refresh
            x = self._state
            out[k] += THESIS_DRYDEN_WEIGHT * x
            self._state = self._a[e] * x + self._g[e]
        return out


class PlantStep:
    """The vehicle (truth plant) integrated frame by frame at the physics rate.

    Parameters
    ----------
    track
        Parameters along the flight (its span is the run's span).
    wind
        The wind source (stepped here, once per physics step).
    model
        ``"linear"`` (exact ZOH of the frozen-time linear model per step) or ``"nonlinear"``
        (:class:`vega_model.dynamics.NonlinearModel`, classical RK4 per step, integrated by
        its compiled twin :func:`vega_model.nonlinear_kernel.rk4_frame`: the same numbers bit
        for bit, tests/model/test_nonlinear_kernel.py).
    x0
        Initial state in :data:`vega_model.dynamics.STATES` order.
    beta0_rad
        Nozzle angle at rest at the start (the actuator's initial state).

    Notes
    -----
    Lockstep protocol: :meth:`output` is the truth at the current frame time t_f;
    :meth:`advance` takes the actuator's samples for (t_f, t_f + frame] and returns the truth
    at t_f + frame. The wind of a frame is drawn when the frame becomes current (so that the
    truth at t_f reports the wind of the step starting at t_f).
    """

    def __init__(self, track: ParameterTrack, wind: PlantWind, model: str = "nonlinear",
                 x0: Sequence[float] | None = None, beta0_rad: float = 0.0):
        if model not in PLANT_MODELS:
            raise BadInput(f"plant model must be one of {PLANT_MODELS}, got {model!r}")
        self.track = track
        self.model = model
        self._wind = wind
        self._dt_s = track.dt_ms / 1000.0
        self._steps = track.frame_ms // track.dt_ms
        x = np.zeros(_N) if x0 is None else np.array(x0, dtype=float)
        if x.shape != (_N,) or not np.all(np.isfinite(x)):
            raise BadInput(f"x0 must be {_N} finite values ({', '.join(STATES)})")
        self._x = x
        self._beta, self._rate = float(beta0_rad), 0.0
        self._t_ms = track.t_start_ms
        self._seq = 0
        self._linear = track.linear_frames() if model == "linear" else None
        if self._linear is None:
            # compiled RK4 frame, bit-identical to NonlinearModel.rk4_step (ahead-of-time
            # compiled when built, vega_model.kernels; imported here: nothing for the other
            # nodes' start-up)
            from vega_model.kernels import compiled

            consts, tables = track.kernel_inputs()
            self._rk4_frame, self._kernel_args = compiled().rk4_frame, (consts, *tables)
        self._winds, self._wind_array = self._draw_winds()
        self._out: TruthOut | None = None      # the truth at t_start, formed on first use

    @property
    def t_ms(self) -> int:
        """Current frame time [ms]."""
        return self._t_ms

    @property
    def state(self) -> np.ndarray:
        """Copy of the plant state at the current frame time (:data:`STATES` order)."""
        return self._x.copy()

    @property
    def wind(self) -> PlantWind:
        """The plant's wind source."""
        return self._wind

    def output(self) -> TruthOut:
        """Truth at the current frame time."""
        if self._out is None:
            self._out = self._truth()
        return self._out

    def _draw_winds(self) -> tuple[list[float], np.ndarray]:
        return self._wind.frame_and_array(self._t_ms, self._steps)

    def advance(self, deflection_samples_rad: Sequence[float],
                rate_samples_radps: Sequence[float]) -> TruthOut:
        """Integrate one frame with the actuator's samples at the ends of its physics steps.

        Parameters
        ----------
        deflection_samples_rad, rate_samples_radps
            β and β̇ at t_f + dt, …, t_f + frame (``ActuatorState`` batches; β̈ follows from
            the rates, see the module docstring).

        Returns
        -------
        TruthOut
            The truth at t_f + frame.

        Raises
        ------
        ValueError
            On a wrong number of samples, or past the end of the track's span.
        """
        steps = self._steps
        if len(deflection_samples_rad) != steps or len(rate_samples_radps) != steps:
            raise ValueError(f"need {steps} actuator samples per frame")
        if self._t_ms >= self.track.t_end_ms:
            raise ValueError(f"the plant is at the end of its span ({self._t_ms} ms)")
        b0, r0 = self._beta, self._rate
        inv_dt = 1.0 / self._dt_s
        winds = self._winds
        if self._linear is not None:
            xu = self._x.tolist()
            for k in range(steps):
                b1, r1 = deflection_samples_rad[k], rate_samples_radps[k]
                xu += (0.5 * (b0 + b1), (r1 - r0) * inv_dt, winds[k])
                b0, r0 = b1, r1
            f = (self._t_ms - self.track.t_start_ms) // self.track.frame_ms
            self._x = self._linear.H[f] @ np.array(xu)
        else:
            track = self.track
            b0 = float(deflection_samples_rad[-1])
            r0 = float(rate_samples_radps[-1])
            samples = np.array((deflection_samples_rad, rate_samples_radps), dtype=float)
            # the state is integrated in place (PlantStep's own array, never handed out)
            self._rk4_frame(self._x, *self._kernel_args, samples[0], samples[1],
                            self._wind_array, self._beta, self._rate, inv_dt, self._dt_s,
                            self._t_ms, track.t_start_ms, track.refresh_ms, track.dt_ms)
        self._beta, self._rate = b0, r0
        self._t_ms += self.track.frame_ms
        self._seq += 1
        self._winds, self._wind_array = self._draw_winds()
        self._out = self._truth()
        return self._out

    def _truth(self) -> TruthOut:
        t = self._t_ms
        e = self.track.entry(t)
        p = self.track.views[e]
        w = self._winds[0]
        s = self._x.tolist()
        if self._linear is not None:
            alpha = angle_of_attack(p, s, w)
            q_alpha = float(self._linear.q_alpha_x[e] @ self._x) + float(
                self._linear.q_alpha_wind[e]) * w
        else:
            alpha, q_alpha = alpha_and_q_alpha(p, s, w)
        return TruthOut(t, self._seq, s[0], s[1], s[2], s[3], alpha, q_alpha, p.q_pa, p.mach,
                        p.v_mps, p.h_m, w, (s[4], s[5]), (s[6], s[7]))
