"""The batched flight engine (vega_sim.batch) equals the per-flight path bit for bit.

Every recorded array of each sample of a batch is compared with :func:`run_scenario`'s as raw
bytes (so NaNs and the signs of zeros too), and the requirement verdicts and campaign metrics
of both are equal. The samples are those a campaign flies (``sample_scenario`` with the shipped
dispersions): dispersed plants, wind-profile changes, turbulence seeds, gusts of either sense,
and the worst samples (largest Qα ratio) of a small campaign. The batched controller
(:class:`vega_gnc.controller_runtime.ControllerBatch`) is also compared with independent
runtimes on measurement streams that drive every safe path (hold, safe zero, stale, repeated,
implausible, non-finite, clamped and limited).
"""

import dataclasses
import math

import numpy as np
import pytest

from vega_campaign.campaign import flight_metrics, load_dispersions, sample_scenario
from vega_core.errors import BadInput
from vega_gnc.controller_runtime import (STATUS_HOLD_LAST, STATUS_LIMITED, STATUS_SAFE_ZERO,
                                         STATUS_VELOCITY_CLAMPED, ControllerBatch,
                                         ControllerRuntime, Measurement)
from vega_gnc.controller_table import (MEASUREMENT_NAMES, default_table_path,
                                       load_controller_table)
from vega_gnc.guidance_reference import default_reference_path, load_guidance_reference
from vega_loops.export import write_controller_table
from vega_model.actuator import ActuatorParams
from vega_model.vehicle_data import load_vehicle_data
from vega_sim.batch import fly_batch
from vega_sim.closed_loop import run_scenario, scenario_reference
from vega_sim.scenario import load_scenario


@pytest.fixture(scope="module")
def table():
    return load_controller_table(default_table_path())


def _differences(expected, got) -> list[str]:
    """Names of the recorded arrays of two results that differ in dtype, shape or any bit."""
    a, b = expected.arrays(), got.arrays()
    assert a.keys() == b.keys()
    return [k for k in a if a[k].dtype != b[k].dtype or a[k].shape != b[k].shape
            or a[k].tobytes() != b[k].tobytes()]


def _assert_equal_flights(scenarios, results, table):
    for scenario, got in zip(scenarios, results):
        expected = run_scenario(scenario, table)
        assert _differences(expected, got) == [], scenario.name
        assert got.seed == expected.seed and got.scenario == expected.scenario
        assert got.metrics() == expected.metrics()
        assert _same_row(flight_metrics(got), flight_metrics(expected)), scenario.name


def _same_row(a: dict, b: dict) -> bool:
    """Two campaign rows equal, numbers bit for bit (NaN equal to NaN)."""
    def same(x, y):
        if isinstance(x, (float, list)):
            return np.array(x, dtype=float).tobytes() == np.array(y, dtype=float).tobytes()
        return x == y
    return a.keys() == b.keys() and all(same(a[k], b[k]) for k in a)


def _window(scenario, t_start_s, t_end_s):
    return dataclasses.replace(scenario, t_start_s=t_start_s, t_end_s=t_end_s)


@pytest.mark.slow
def test_short_window_with_gusts_equals_per_flight(table):
    """Dispersed samples whose gusts blow inside a window starting off the controller period
    (the first frame has no controller step), one without INS noise."""
    base, disp = load_scenario("nominal"), load_dispersions()
    picked = []
    for i in range(200):
        scenario, values = sample_scenario(base, disp, 3, i)
        if 31.0 <= values["gust_start_s"] <= 33.0:
            picked.append(scenario)
        if len(picked) == 3:
            break
    assert len(picked) == 3
    assert {math.copysign(1.0, s.wind.gust.amplitude_mps) for s in picked} == {-1.0, 1.0}
    picked.append(dataclasses.replace(picked[0], sensor_noise=False, name="quiet_ins"))
    scenarios = [_window(s, 30.01, 36.01) for s in picked]
    _assert_equal_flights(scenarios, fly_batch(scenarios, table), table)


@pytest.mark.slow
def test_campaign_samples_and_the_worst_equal_per_flight(table):
    """A small campaign (16 samples of `nominal`, seed 0) flown as one batch: its three worst
    samples by Qα ratio, two with gusts and one without equal their per-flight flights."""
    base, disp = load_scenario("nominal"), load_dispersions()
    scenarios = [sample_scenario(base, disp, 0, i)[0] for i in range(16)]
    results = fly_batch(scenarios, table)
    rows = [flight_metrics(r) for r in results]
    worst = sorted(range(16), key=lambda i: rows[i]["q_alpha_margin"])[-3:]
    gusts = [i for i in range(16) if scenarios[i].wind.gust is not None][:2]
    calm = [i for i in range(16) if scenarios[i].wind.gust is None][:1]
    chosen = sorted(set(worst + gusts + calm))
    assert len(gusts) == 2 and calm
    assert any(rows[i]["verdict"] == "fail" for i in worst)     # failed verdicts compared too
    _assert_equal_flights([scenarios[i] for i in chosen], [results[i] for i in chosen], table)


@pytest.mark.slow
def test_shipped_dispersed_scenarios_in_one_batch(table):
    """Different base scenarios of one span and guidance fly in one batch (a gust scenario, the
    worst plant of `vega robust`, the bending edges), with their own seeds overridden."""
    names = ("gust", "dispersed_worst", "dispersed_mode2", "severe", "wind_change")
    seeds = (7, None, 11, None, 5)
    scenarios = [_window(load_scenario(n), 40.0, 52.0) for n in names]
    results = fly_batch(scenarios, table, seeds=list(seeds))
    for scenario, seed, got in zip(scenarios, seeds, results):
        expected = run_scenario(scenario, table, seed=seed)
        assert _differences(expected, got) == [], scenario.name
        assert got.seed == expected.seed
        assert got.metrics() == expected.metrics()


@pytest.mark.slow
def test_saturating_flights_without_guidance_equal_per_flight(table):
    """No guidance reference, and flights that start far off (a large attitude error; the
    nozzle near its stop, moving the wrong way) drive the command to its limit and the nozzle
    onto its rate limit and its stop."""
    base = _window(load_scenario("nominal_no_bias"), 40.0, 43.0)
    start = base.initial_state
    scenarios = [
        dataclasses.replace(base, initial_state=dataclasses.replace(start, theta_rad=0.15)),
        dataclasses.replace(base, seed=3, initial_state=dataclasses.replace(
            start, beta_rad=0.11, theta_dot_radps=-0.3)),
        base]
    results = fly_batch(scenarios, table)
    _assert_equal_flights(scenarios, results, table)
    limits = ActuatorParams.from_vehicle(load_vehicle_data())
    assert all((r.cmd_status == STATUS_LIMITED).any() for r in results[:2])
    beta = np.concatenate([r.beta_rad for r in results[:2]])
    rate = np.concatenate([r.beta_dot_radps for r in results[:2]])
    assert (np.abs(beta) == limits.position_limit_rad).any()
    assert (np.abs(rate) == limits.rate_limit_radps).any()


def _other_reference(directory, name: str, scale: float, every: int = 1):
    """The shipped reference with its rows scaled by ``scale`` (a reference other than the
    shipped one on its grid), on every ``every``-th time of its grid; written as a file."""
    arrays = dict(np.load(default_reference_path(), allow_pickle=False))
    keep = np.arange(0, arrays["t_s"].size, every)
    if keep[-1] != arrays["t_s"].size - 1:
        keep = np.append(keep, arrays["t_s"].size - 1)
    for key, value in arrays.items():
        if value.ndim and value.shape[0] == arrays["t_s"].size and key != "t_s":
            arrays[key] = value[keep] * (scale if key in ("reference", "beta_ff_rad") else 1.0)
    arrays["t_s"] = arrays["t_s"][keep]
    path = directory / f"{name}.npz"
    np.savez(path, **arrays)
    load_guidance_reference(path)                       # a valid reference file
    return str(path)


@pytest.mark.slow
def test_each_sample_flies_its_own_reference(table, tmp_path):
    """Samples with different guidance references (the shipped one, others on its grid as a
    flight-day campaign re-biases them, one on another grid) fly in one batch, each equal to
    its own per-flight run bit for bit."""
    base = _window(load_scenario("nominal"), 44.0, 47.0)
    guidance = [base.guidance, _other_reference(tmp_path, "a", 1.3),
                _other_reference(tmp_path, "b", 0.6), _other_reference(tmp_path, "a", 1.3),
                _other_reference(tmp_path, "c", 1.1, every=2)]
    same_grid = [dataclasses.replace(base, seed=i, guidance=g)
                 for i, g in enumerate(guidance[:4])]
    results = fly_batch(same_grid, table)
    _assert_equal_flights(same_grid, results, table)
    assert results[0].cmd_rad.tobytes() != results[1].cmd_rad.tobytes()   # they differ
    mixed = [dataclasses.replace(base, guidance=g) for g in (guidance[0], guidance[4])]
    _assert_equal_flights(mixed, fly_batch(mixed, table), table)


def test_refuses_what_it_does_not_fly(table):
    nominal = _window(load_scenario("nominal"), 10.0, 11.0)
    for other, why in ((dataclasses.replace(nominal, plant="linear"), "plant"),
                       (_window(nominal, 10.0, 12.0), "span"),
                       (dataclasses.replace(nominal, guidance="none"), "guidance")):
        with pytest.raises(BadInput, match=why):
            fly_batch([nominal, other], table)
    with pytest.raises(BadInput, match="seeds"):
        fly_batch([nominal], table, seeds=[1, 2])
    with pytest.raises(BadInput, match="no scenarios"):
        fly_batch([], table)


def _streams(n_samples: int, n_steps: int, rng, size: float = 1.0) -> list[list[tuple]]:
    """Per sample, (measurement, now_s) of each step: a 50 Hz stream with faults injected
    (``size``: a factor on the measured values)."""
    names = ("pitch", "rate", "drift", "drift_rate")
    scale = size * np.array([0.05, 0.05, 200.0, 20.0])
    streams = []
    for _ in range(n_samples):
        steps, t = [], 5.0
        for _ in range(n_steps):
            t += 0.02
            values = dict(zip(names, (scale * rng.standard_normal(4)).tolist()))
            v = float(rng.uniform(-50.0, 2000.0))
            stamp, now, valid = t, t + 0.012, True
            fault = rng.integers(0, 14)
            if fault == 0:
                valid = False
            elif fault == 1:
                values[names[rng.integers(0, 4)]] = math.nan
            elif fault == 2:
                stamp = t - 0.04                        # stale at use (or repeated/older)
            elif fault == 3:
                now = stamp - 0.001                     # from the future
            elif fault == 4:
                values["pitch"] = 4.0                   # implausible
            elif fault == 5:
                v = math.inf
            elif fault == 6:
                values["drift"] = 5e3                   # drives the command to its limit
            elif fault == 7:
                stamp = math.nan
            elif fault == 8 and rng.random() < 0.3:
                now = math.nan                          # the runtime's exception path
            elif fault == 9:
                t += 0.3                                # a gap beyond the hold limit
                stamp, now = t, t + 0.012
            m = Measurement(stamp, values["pitch"], values["rate"], values["drift"],
                            values["drift_rate"], v, valid)
            steps.append((m, now))
        streams.append(steps)
    return streams


@pytest.fixture(scope="module")
def overflow_table(tmp_path_factory):
    """A static gain of 1e308 on every input (rate-dependent): the state or the command
    overflows for inputs of order 1, the runtime's non-finite path."""
    meta = {"input_names": list(MEASUREMENT_NAMES), "measurement_sign": 1,
            "output_name": "beta_cmd_rad", "units": {}, "weights": {}, "solver": {}}
    return write_controller_table(
        tmp_path_factory.mktemp("ovf") / "o.npz", [100.0, 900.0], np.full((2, 1, 1), -1.0),
        np.zeros((2, 1, 4)), np.zeros((2, 1, 1)), np.full((2, 1, 4), 1e308), dt_s=0.02,
        gamma=1.0, gamma_min=1.0, rate_bounds_mps2=[5.4, 36.4], metadata=meta)


@pytest.mark.filterwarnings("ignore:overflow encountered:RuntimeWarning")
@pytest.mark.parametrize("which", ["shipped", "overflow", "per_sample", "per_sample_grids"])
def test_controller_batch_equals_runtimes_on_faulty_streams(table, overflow_table, which,
                                                            tmp_path):
    """Each sample of a ControllerBatch returns its own runtime's commands and keeps its state,
    bit for bit, through every safe path (the shipped table with its guidance reference, or
    with a reference of its own per sample on one grid or on two; a table whose gains
    overflow, without one)."""
    rng = np.random.default_rng(20)
    n, n_steps = 6, 400
    expected = {STATUS_HOLD_LAST, STATUS_SAFE_ZERO, STATUS_LIMITED, STATUS_VELOCITY_CLAMPED}
    used, size = table, 1.0
    if which == "shipped":
        reference = scenario_reference(load_scenario("nominal"))
        references = [reference] * n
    elif which.startswith("per_sample"):
        every = 3 if which == "per_sample_grids" else 1
        references = [load_guidance_reference(_other_reference(tmp_path, f"r{i}", 0.5 + 0.2 * i,
                                                               every if i % 2 else 1))
                      for i in range(n)]
        reference = references
    else:                                   # |Σy| ≈ 1: overflows at some steps, not at all
        used, reference, size = overflow_table, None, 0.005
        references = [None] * n
        expected = {STATUS_HOLD_LAST, STATUS_SAFE_ZERO, STATUS_LIMITED}
    streams = _streams(n, n_steps, rng, size)
    runtimes = [ControllerRuntime(used, reference=references[i]) for i in range(n)]
    batch = ControllerBatch(n, used, reference=reference)
    assert (batch._many is not None) == which.startswith("per_sample")
    if which == "per_sample":
        assert batch._stacks is not None        # one grid: read together
    if which == "per_sample_grids":
        assert batch._stacks is None
    statuses = set()
    for k in range(n_steps):
        ms = [streams[i][k][0] for i in range(n)]
        nows = np.array([streams[i][k][1] for i in range(n)])
        u, v, status = batch.step(
            np.array([m.stamp_s for m in ms]),
            np.array([(m.pitch_rad, m.pitch_rate_radps, m.drift_m, m.drift_rate_mps)
                      for m in ms]),
            np.array([m.velocity_mps for m in ms]), np.array([m.valid for m in ms]), nows)
        for i in range(n):
            cmd = runtimes[i].step(ms[i], now_s=float(nows[i]))
            got = (u[i], v[i], int(status[i]))
            assert np.array([cmd[0], cmd[1]]).tobytes() == np.array(got[:2]).tobytes(), (k, i)
            assert cmd.status == got[2], (k, i)
            state = batch._xy[i, :runtimes[i]._n]
            assert runtimes[i].state.tobytes() == state.tobytes(), (k, i)
            statuses.add(cmd.status)
    assert expected <= statuses


@pytest.mark.slow
def test_campaign_batch_task_rows_equal_fly_sample():
    """``fly_batch_samples`` (one Dask task per batch) returns fly_sample's rows."""
    from vega_campaign.campaign import default_dispersions_path, fly_batch_samples, fly_sample
    from vega_sim.scenario import dump_scenario

    text = dump_scenario(_window(load_scenario("nominal"), 20.0, 26.0))
    disp = default_dispersions_path().read_text()
    table_path = str(default_table_path())
    rows = fly_batch_samples(text, table_path, disp, 5, [3, 8])
    for row in rows:
        expected = fly_sample(text, table_path, disp, 5, row["sample"])
        assert row.pop("wall_s") > 0.0 and expected.pop("wall_s") > 0.0
        assert _same_row(row, expected), row["sample"]


def test_tracks_of_one_span_share_the_flight_condition_interpolation():
    """The batch's samples build their parameter tracks on one context: the flight-condition
    interpolation of a span is done once and reused (read-only), and every track's columns
    equal, bit for bit, those a fresh context computes — after another span in between and
    with other deviations."""
    from vega_model.parameters import ModelContext, default_context

    shared, dev = default_context(), {"velocity": 0.02, "x_cp": -0.1, "mass": 0.03}
    span = (40_000 + 10 * np.arange(1201)) / 1000.0
    other = (10_000 + 10 * np.arange(301)) / 1000.0
    first = shared.parameter_columns_at_times(span)
    again = shared.parameter_columns_at_times(span.copy())
    assert again["h_m"] is first["h_m"] and not first["h_m"].flags.writeable
    for times, deviations in ((span, dev), (other, {}), (span, {}), (span, dev)):
        got = shared.parameter_columns_at_times(times, deviations)
        want = ModelContext().parameter_columns_at_times(times, deviations)
        assert got.keys() == want.keys()
        assert [k for k in got if got[k].tobytes() != want[k].tobytes()] == []
    assert shared.parameter_columns_at_times(other)["h_m"] is not first["h_m"]
