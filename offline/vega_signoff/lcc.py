"""Launch commit criterion (LCC): go/no-go of a flight day from its measured wind profile.

Before a flight-day sample flies, the launch team sees only the sounding (the *measured*
profile, docs/WINDS.md §6) and the guidance re-biased to it (docs/GUIDANCE.md §8). The
criterion judges that, and nothing the vehicle will meet later:

(a) **predicted flight**: the closed loop with the nominal plant, no turbulence, gust or INS
    noise, the re-biased reference and the measured profile → |Qα_pred|(t), z_pred(t);
(b) **allowance for the wind change since the sounding**: a change δw at the altitude h(t)
    changes the angle of attack by δw/V(t) (α ≈ θ − γ + w/V, so ∂α/∂w = 1/V, the vehicle's
    attitude not yet turned by the controller), hence Qα by Q(t)·δw/V(t). With δw at k
    standard deviations of the site's wind-change model σ_Δw(h, lag)
    (:func:`vega_campaign.wind_environment.change_rms_mps`, per component — the in-plane
    residual has one component's variance in either flight-plane mode)::

        allowance(t) = k · σ_Δw(h(t), lag) · Q(t) / V(t)        [Pa·rad]

    GO on load needs max_t (|Qα_pred(t)| + allowance(t)) ≤ A (the constant allowable,
    docs/REQUIREMENTS.md §6); on drift, max_t (|z_pred(t)| + Δz_k(t)) < the drift limit,
    Δz_k(t) = k·sqrt(g(t)ᵀ C g(t)) the k-sigma drift response to the change field: g_j(t)
    the drift's sensitivity to the wind at node h_j (finite differences of the nominal
    predicted flight, :func:`drift_sensitivity`), C_ij = σ_i σ_j exp(−|h_i − h_j|/L_Δ) the
    change's covariance between nodes (:func:`drift_allowance_m`; derivation in
    docs/MONTE_CARLO.md §9.2);
(c) **low-speed α**: below Mach M₀ (the envelope's threshold, 0.31) the predicted flight
    meets §2's envelope, with no change allowance (docs/REQUIREMENTS.md §6.4: α at low speed
    is an LCC input, not part of the success criterion the allowance protects;
    docs/MONTE_CARLO.md §9.2 (b));
(d) **ground wind**: the measured speed below ``top_m`` at most the limit.

Every number is in ``data/lcc.yaml`` with its source; the allowable, the drift limit and the
envelope come from the requirement file, so the criterion and the verdicts share one
definition.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from vega_core.documents import field_error as _fail
from vega_core.documents import finite_number as _number
from vega_core.documents import mapping_keys as _keys
from vega_core.documents import parse_yaml, read_text
from vega_core.errors import BadFile

__all__ = ["LccSettings", "LccVerdict", "default_lcc_path", "load_lcc", "parse_lcc",
           "change_allowance_pa_rad", "ground_wind_mps", "evaluate_lcc",
           "predicted_scenario", "drift_sensitivity", "change_covariance", "drift_allowance_m",
           "REASONS"]

REASONS = ("load", "drift", "low_speed_alpha", "ground_wind")
"""The no-go reasons, in the order :func:`evaluate_lcc` reports them."""


@dataclass(frozen=True)
class LccSettings:
    """A validated LCC file (``data/lcc.yaml``)."""

    path: str
    text: str
    k_sigma: float                  # 1: multiple of the wind-change rms in the allowance
    ground_wind_limit_mps: float    # m/s: largest measured speed below top_m
    ground_wind_top_m: float        # m: the layer the ground-wind limit applies to
    drift_node_spacing_m: float     # m: spacing of the drift sensitivity's wind nodes
    drift_top_m: float              # m: highest node (its value held above, as a table is)
    drift_perturbation_mps: float   # m/s: the finite difference of each node's wind


def default_lcc_path() -> Path:
    """The shipped LCC file."""
    return Path(__file__).resolve().parent / "data" / "lcc.yaml"


def _valued(path: str, key: str, node: Any, unit: str, lo: float, hi: float) -> float:
    _keys(path, key, node, ("value", "unit", "source"))
    if node["unit"] != unit:
        raise _fail(path, f"{key}.unit", f"must be {unit!r}, got {node['unit']!r}")
    if not isinstance(node["source"], str) or not node["source"].strip():
        raise _fail(path, f"{key}.source", "must be a non-empty text")
    return _number(path, f"{key}.value", node["value"], lo, hi)


def parse_lcc(text: str, path: str = "<lcc>") -> LccSettings:
    """Parse and validate an LCC file's text; one line naming the file and the field on any
    problem (:class:`vega_core.errors.BadFile`)."""
    tree = parse_yaml(text, path)
    _keys(path, "", tree, ("schema_version", "wind_change_k_sigma", "ground_wind",
                           "drift_allowance"))
    if tree["schema_version"] != 1:
        raise _fail(path, "schema_version", f"must be 1, got {tree['schema_version']!r}")
    k = _valued(path, "wind_change_k_sigma", tree["wind_change_k_sigma"], "1", 0.0, 10.0)
    ground = _keys(path, "ground_wind", tree["ground_wind"], ("limit_mps", "top_m"))
    limit = _valued(path, "ground_wind.limit_mps", ground["limit_mps"], "m/s", 0.0, 120.0)
    top = _valued(path, "ground_wind.top_m", ground["top_m"], "m", 0.0, 30_000.0)
    drift = _keys(path, "drift_allowance", tree["drift_allowance"],
                  ("method", "node_spacing_m", "top_m", "perturbation_mps", "source"))
    if drift["method"] != "linear_gaussian":
        raise _fail(path, "drift_allowance.method",
                    f"must be 'linear_gaussian', got {drift['method']!r}")
    if not isinstance(drift["source"], str) or not drift["source"].strip():
        raise _fail(path, "drift_allowance.source", "must be a non-empty text")
    spacing = _valued(path, "drift_allowance.node_spacing_m", drift["node_spacing_m"], "m",
                      10.0, 10_000.0)
    drift_top = _valued(path, "drift_allowance.top_m", drift["top_m"], "m", 0.0, 100_000.0)
    if drift_top / spacing > 1000.0:
        raise _fail(path, "drift_allowance.top_m",
                    f"gives {drift_top / spacing:.0f} nodes at the spacing; at most 1000")
    eps = _valued(path, "drift_allowance.perturbation_mps", drift["perturbation_mps"], "m/s",
                  1e-3, 10.0)
    return LccSettings(path=path, text=text, k_sigma=k, ground_wind_limit_mps=limit,
                       ground_wind_top_m=top, drift_node_spacing_m=spacing,
                       drift_top_m=drift_top, drift_perturbation_mps=eps)


def load_lcc(path: str | Path | None = None) -> LccSettings:
    """Load and validate an LCC file (default: the shipped one)."""
    p = Path(path) if path is not None else default_lcc_path()
    return parse_lcc(read_text(p, "LCC file"), str(p))


def change_allowance_pa_rad(k_sigma: float, sigma_altitude_m, sigma_mps, h_m, q_pa,
                            v_mps) -> np.ndarray:
    """The load allowance for the wind change, k·σ_Δw(h)·Q/V [Pa·rad], at each time.

    Parameters
    ----------
    k_sigma
        Multiple of the rms change (1).
    sigma_altitude_m, sigma_mps
        The rms change per component [m/s] on an altitude grid [m] (interpolated linearly,
        end values held, as the plant reads a wind table).
    h_m, q_pa, v_mps
        Altitude [m], dynamic pressure [Pa] and airspeed [m/s] of the predicted flight.

    Notes
    -----
    A wind change δw (along +z) changes the wind's angle of attack by atan(δw/V) ≈ δw/V, so
    Qα by Q·δw/V before the controller turns the vehicle (module docstring, (b)).
    """
    sigma = np.interp(np.asarray(h_m, dtype=float), np.asarray(sigma_altitude_m, dtype=float),
                      np.asarray(sigma_mps, dtype=float))
    v = np.maximum(np.asarray(v_mps, dtype=float), 1e-9)
    return float(k_sigma) * sigma * np.asarray(q_pa, dtype=float) / v


def ground_wind_mps(altitude_m, wind_mps, top_m: float) -> float:
    """Largest |measured wind| [m/s] at or below ``top_m`` [m] (the profile read as the
    plant reads it: linear, end value held, so the value at ``top_m`` counts)."""
    alt = np.asarray(altitude_m, dtype=float)
    w = np.asarray(wind_mps, dtype=float)
    inside = np.abs(w[alt <= top_m])
    at_top = abs(float(np.interp(top_m, alt, w)))
    return float(max(inside.max(initial=0.0), at_top))


@dataclass(frozen=True)
class LccVerdict:
    """Go/no-go of one measured profile and the numbers behind it (SI; Qα in Pa·deg)."""

    go: bool
    reasons: tuple[str, ...]
    predicted_max_q_alpha_pa_deg: float
    q_alpha_with_allowance_pa_deg: float     # max over t of |Qα_pred| + allowance
    allowance_pa_deg: float                  # the allowance at that time
    load_time_s: float
    allowable_pa_deg: float
    predicted_drift_m: float
    drift_with_allowance_m: float
    drift_limit_m: float
    low_speed_ratio: float                   # max over M < M₀ of |Qα_pred|/envelope
    ground_wind_mps: float
    ground_wind_limit_mps: float

    def row(self) -> dict[str, Any]:
        """The ``lcc_*`` columns of a campaign row."""
        return {"lcc_go": bool(self.go), "lcc_reasons": ",".join(self.reasons),
                "lcc_predicted_max_q_alpha_pa_deg": self.predicted_max_q_alpha_pa_deg,
                "lcc_q_alpha_with_allowance_pa_deg": self.q_alpha_with_allowance_pa_deg,
                "lcc_allowance_pa_deg": self.allowance_pa_deg,
                "lcc_predicted_drift_m": self.predicted_drift_m,
                "lcc_drift_with_allowance_m": self.drift_with_allowance_m,
                "lcc_low_speed_ratio": self.low_speed_ratio,
                "lcc_ground_wind_mps": self.ground_wind_mps}


def evaluate_lcc(predicted, measured, sigma_altitude_m, sigma_mps, drift_allowance,
                 settings: LccSettings, spec=None) -> LccVerdict:
    """The criterion (module docstring) on a predicted flight.

    Parameters
    ----------
    predicted
        The predicted flight (:class:`vega_sim.closed_loop.SimulationResult` of
        :func:`predicted_scenario`): ``t_ms``, ``q_alpha_pa_rad``, ``q_pa``, ``v_mps``,
        ``h_m``, ``mach``, ``z_m``.
    measured
        The measured profile (:class:`vega_model.wind.WindTable`).
    sigma_altitude_m, sigma_mps
        The rms wind change per component [m/s] on its altitude grid [m].
    drift_allowance
        Δz_k at the predicted flight's times [m] (:func:`drift_allowance_m`), or a scalar.
    settings
        The LCC file (:func:`load_lcc`).
    spec
        The requirements (default: the shipped ones): the allowable A, the drift limit, the
        envelope and its threshold Mach M₀.
    """
    from vega_sim.requirements import load_requirements

    spec = spec if spec is not None else load_requirements()
    if spec.allowable_pa_rad is None:
        raise BadFile("the requirement file has no q_alpha_allowable (docs/REQUIREMENTS.md §6)")
    qa = np.abs(np.asarray(predicted.q_alpha_pa_rad, dtype=float))
    allow = change_allowance_pa_rad(settings.k_sigma, sigma_altitude_m, sigma_mps,
                                    predicted.h_m, predicted.q_pa, predicted.v_mps)
    load = qa + allow
    i = int(np.argmax(load))
    z = np.abs(np.asarray(predicted.z_m, dtype=float))
    dz = np.broadcast_to(np.asarray(drift_allowance, dtype=float), z.shape)
    drift = z + dz
    mach = np.asarray(predicted.mach, dtype=float)
    m0 = spec.envelope_definition.mach_min if spec.envelope_definition else 0.31
    low = mach < m0
    env = np.interp(mach, spec.envelope_mach, spec.envelope_pa_rad)
    low_ratio = float((qa[low] / env[low]).max()) if low.any() else 0.0
    ground = ground_wind_mps(measured.altitude_m, measured.wind_mps, settings.ground_wind_top_m)
    reasons = []
    if not load[i] <= spec.allowable_pa_rad:
        reasons.append("load")
    if not drift.max() < spec.drift_m:
        reasons.append("drift")
    if not low_ratio <= 1.0:
        reasons.append("low_speed_alpha")
    if not ground <= settings.ground_wind_limit_mps:
        reasons.append("ground_wind")
    return LccVerdict(
        go=not reasons, reasons=tuple(reasons),
        predicted_max_q_alpha_pa_deg=math.degrees(float(qa.max())),
        q_alpha_with_allowance_pa_deg=math.degrees(float(load[i])),
        allowance_pa_deg=math.degrees(float(allow[i])),
        load_time_s=float(predicted.t_ms[i]) / 1000.0,
        allowable_pa_deg=math.degrees(spec.allowable_pa_rad),
        predicted_drift_m=float(z.max()), drift_with_allowance_m=float(drift.max()),
        drift_limit_m=float(spec.drift_m), low_speed_ratio=low_ratio,
        ground_wind_mps=ground, ground_wind_limit_mps=settings.ground_wind_limit_mps)


def predicted_scenario(base, profile, guidance: str):
    """The scenario of a predicted (or sensitivity) flight: ``base`` with the nominal plant
    (no deviations, the base's initial state), no turbulence, gust or INS noise, the steady
    wind ``profile`` (a :class:`vega_model.wind.WindTable`) and the reference ``guidance``."""
    wind = dataclasses.replace(base.wind, profile=profile, turbulence="none", gust=None,
                               thesis_constant_dryden=False, profile_scale=1.0,
                               profile_shift_m=0.0)
    return dataclasses.replace(base, name=f"{base.name}_predicted", wind=wind,
                               sensor_noise=False, uncertainty=(), guidance=guidance)


@lru_cache(maxsize=4)
def _controller_table(path: str):
    from vega_gnc.controller_table import load_controller_table

    return load_controller_table(path)


def _wind_nodes(settings: LccSettings) -> np.ndarray:
    """The drift sensitivity's wind nodes [m]: 0, spacing, … up to ``drift_top_m``."""
    n = int(math.floor(settings.drift_top_m / settings.drift_node_spacing_m + 1e-9))
    return settings.drift_node_spacing_m * np.arange(n + 1, dtype=float)


_SENSITIVITY_BATCH = 16      # flights per fly_batch call: ≈ 9 MB each while a batch flies


@lru_cache(maxsize=4)
def _drift_sensitivity(scenario_yaml: str, table_path: str, spacing_m: float, top_m: float,
                       eps_mps: float) -> tuple[np.ndarray, np.ndarray]:
    from vega_model.wind import WindTable
    from vega_sim.batch import fly_batch
    from vega_sim.scenario import parse_scenario

    base = parse_scenario(scenario_yaml, "<campaign scenario>")
    n = int(math.floor(top_m / spacing_m + 1e-9))
    nodes = spacing_m * np.arange(n + 1, dtype=float)
    winds = [np.zeros_like(nodes)]
    for j in range(nodes.size):
        w = np.zeros_like(nodes)
        w[j] = eps_mps
        winds.append(w)
    scenarios = [predicted_scenario(base, WindTable(nodes, w, f"drift sensitivity {i}"),
                                    base.guidance) for i, w in enumerate(winds)]
    table = _controller_table(table_path)
    z = []
    for start in range(0, len(scenarios), _SENSITIVITY_BATCH):
        for r in fly_batch(scenarios[start:start + _SENSITIVITY_BATCH], table):
            z.append(np.array(r.z_m, dtype=float))
            del r
    g = (np.stack(z[1:]) - z[0][None, :]) / eps_mps
    nodes.setflags(write=False)
    g.setflags(write=False)
    return nodes, g


def drift_sensitivity(scenario_yaml: str, table_path: str,
                      settings: LccSettings) -> tuple[np.ndarray, np.ndarray]:
    """The wind nodes h_j [m] and the drift sensitivity g_j(t) = ∂z(t)/∂w_j [m per m/s],
    (nodes, frames), of the nominal predicted flight (the base scenario's reference, no
    turbulence, gust or INS noise).

    Finite differences: a calm flight and one flight per node with that node's wind at
    +``drift_perturbation_mps`` (the plant reads the table linearly between nodes and holds
    the top node's value above it, so node j's flight is the hat function at h_j), flown by
    the batched engine. Computed once per process for a scenario, table and node set
    (``len(nodes) + 1`` flights)."""
    return _drift_sensitivity(scenario_yaml, str(table_path), settings.drift_node_spacing_m,
                              settings.drift_top_m, settings.drift_perturbation_mps)


def change_covariance(nodes_m, sigma_altitude_m, sigma_mps, correlation_m: float) -> np.ndarray:
    """C_ij = σ(h_i) σ(h_j) exp(−|h_i − h_j|/L) [m²/s²]: the covariance of the wind change
    between nodes (σ interpolated linearly on its grid, end values held)."""
    h = np.asarray(nodes_m, dtype=float)
    s = np.interp(h, np.asarray(sigma_altitude_m, dtype=float),
                  np.asarray(sigma_mps, dtype=float))
    if not correlation_m > 0.0:
        raise ValueError(f"correlation_m must be > 0, got {correlation_m!r}")
    return np.outer(s, s) * np.exp(-np.abs(h[:, None] - h[None, :]) / float(correlation_m))


def drift_allowance_m(scenario_yaml: str, table_path: str, sigma_altitude_m, sigma_mps,
                      correlation_m: float, settings: LccSettings) -> np.ndarray:
    """Δz_k(t) = k·sqrt(g(t)ᵀ C g(t)) [m] at the predicted flight's frame times: k standard
    deviations of the drift's response to the wind change since the sounding (module
    docstring (b); docs/MONTE_CARLO.md §9.2), g from :func:`drift_sensitivity`, C from
    :func:`change_covariance` with the change's rms ``sigma_mps`` on ``sigma_altitude_m`` and
    its vertical correlation scale ``correlation_m`` [m]."""
    nodes, g = drift_sensitivity(scenario_yaml, table_path, settings)
    c = change_covariance(nodes, sigma_altitude_m, sigma_mps, correlation_m)
    var = np.sum(g * (c @ g), axis=0)
    return settings.k_sigma * np.sqrt(np.maximum(var, 0.0))
