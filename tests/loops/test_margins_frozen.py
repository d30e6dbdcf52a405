"""``vega_loops.margins``: the quick stability check before a run
(:func:`frozen_stability`, :func:`check_table_stabilises`) and the sweep driver
(:func:`sweep` in process, :func:`_init_worker`, :func:`_time_task`).

Reference for the stability verdicts: the one-period map of the sampled loop built HERE, by a
1 ms step simulation written out in the test — the plant assembled by hand from
:func:`vega_model.dynamics.linear_model` and the actuator's two equations, the command
computed at kT applied from kT + 39 ms (the vehicle's three delays, read from its data) and
held for T, integrated exactly over each millisecond (the input is constant on each), the
controller recursion of the flown matrices. The map is applied to every unit state, and its
eigenvalues are the closed loop's. No part of margins.py's sampled-data model (modified
z-transform, delay line, closed-loop matrix) is used.
"""

import dataclasses
import math
import re
from pathlib import Path

import numpy as np
import pytest
from scipy.linalg import expm

from vega_loops import margins as M

ROOT = Path(__file__).resolve().parents[2]
SHIPPED = ROOT / "ros2_ws" / "src" / "vega_gnc" / "config" / "lpv_controller.npz"


def _scaled(table, k, index=None):
    """The table with its controller outputs (Cd, Dd) × k: at every grid point, or at
    ``index`` only."""
    Cd, Dd = np.array(table.Cd), np.array(table.Dd)
    if index is None:
        Cd, Dd = Cd * k, Dd * k
    else:
        Cd[index] *= k
        Dd[index] *= k
    return dataclasses.replace(table, Cd=Cd, Dd=Dd)


def _reference(table, context, t):
    """(clamped, eigenvalues of the one-period map) of the nominal loop at ``t``, by the 1 ms
    simulation described in the module docstring."""
    from vega_model.dynamics import OUTPUTS, linear_model

    veh = context.vehicle
    p = context.parameters(t)
    g = table.grid_v_mps
    v = min(max(p.v_mps, g[0]), g[-1])
    clamped = not (g[0] <= p.v_mps <= g[-1])
    # flown controller: the runtime's interpolation written out (upper ρ̇ slice)
    i = int(np.clip(np.searchsorted(g, v, side="right") - 1, 0, len(g) - 2))
    w = (v - g[i]) / (g[i + 1] - g[i])
    mats = []
    for name in ("Ad", "Bd", "Cd", "Dd"):
        m = np.asarray(getattr(table, name))
        mats.append((1 - w) * m[i][-1] + w * m[i + 1][-1])
    Ad, Bd, Cd, Dd = mats
    sign = table.measurement_sign
    # plant + actuator (β, β̇): β̈ = ω²(u − β) − 2ζω β̇ drives the plant's β̈ input
    Ap, Bp, Cp, Dp = linear_model(p)
    wn, zeta = veh["actuator.natural_frequency_radps"], veh["actuator.damping_ratio"]
    A = np.zeros((10, 10))
    A[:8, :8] = Ap
    A[:8, 8] += Bp[:, 0] - wn ** 2 * Bp[:, 1]
    A[:8, 9] += -2 * zeta * wn * Bp[:, 1]
    A[8, 9] = 1.0
    A[9, 8], A[9, 9] = -wn ** 2, -2 * zeta * wn
    B = np.zeros(10)
    B[:8] = wn ** 2 * Bp[:, 1]
    B[9] = wn ** 2
    rows = [OUTPUTS.index(n) for n in table.input_names]
    assert not np.any(Dp[rows][:, 1])                 # no β̈ (hence β_cmd) feed-through
    Cy = np.hstack([Cp[rows], Dp[rows][:, :1], np.zeros((len(rows), 1))])
    # 1 ms exact steps with the input constant over each
    aug = np.zeros((11, 11))
    aug[:10, :10], aug[:10, 10] = A, B
    E = expm(aug * 1e-3)
    tau_ms = round(1000 * (veh["delays.sensor_s"] + veh["delays.computing_s"]
                           + veh["delays.actuator_s"]))
    T_ms = round(1000 * table.dt_s)
    n_hist = tau_ms // T_ms + 1                       # commands still to reach the nozzle
    nc = Ad.shape[0]
    N = 10 + n_hist + nc

    def one_period(s):
        x, hist, xc = s[:10], list(s[10:10 + n_hist]), s[10 + n_hist:]
        y = Cy @ x
        u = (Cd @ xc + Dd @ (sign * y)).item()       # u_k; hist = [u_{k-1}, u_{k-2}, …]
        cmds = [u] + hist                            # cmds[j] = u_{k-j}
        for r in range(T_ms):
            j = math.floor((r - tau_ms) / T_ms)      # the command u_{k+j} in force
            x = E[:10, :10] @ x + E[:10, 10] * cmds[-j]
        xc = Ad @ xc + Bd @ (sign * y)
        return np.concatenate([x, cmds[:n_hist], xc])

    Phi = np.column_stack([one_period(e) for e in np.eye(N)])
    return clamped, np.linalg.eigvals(Phi)


@pytest.mark.parametrize("t", [5.0, 30.0, 60.0, 95.0])
def test_frozen_stability_against_the_one_period_map(table, context, t):
    (got,) = M.frozen_stability(table, context, [t])
    clamped, eig = _reference(table, context, t)
    assert got == {"t_s": t, "clamped": clamped, "n_unstable": 0,
                   "max_abs_eig": pytest.approx(np.max(np.abs(eig)), rel=1e-9)}
    assert type(got["t_s"]) is float and type(got["clamped"]) is bool
    assert clamped is (t in (5.0, 95.0))
    assert int(np.sum(np.abs(eig) > 1 + 1e-6)) == 0


def test_frozen_stability_unstable_table(table, context):
    bad = _scaled(table, 30.0)
    got = M.frozen_stability(bad, context, [20, 60.0])
    for row, t in zip(got, (20.0, 60.0)):
        _, eig = _reference(bad, context, t)
        n = int(np.sum(np.abs(eig) > 1 + 1e-6))
        assert n > 0
        assert row == {"t_s": t, "clamped": False, "n_unstable": n,
                       "max_abs_eig": pytest.approx(np.max(np.abs(eig)), rel=1e-9)}


def test_check_table_stabilises_stable_table_returns_nothing(table, context):
    assert M.check_table_stabilises(table, context, 20.0, 23.0) == []


def test_check_table_stabilises_reports_the_clamped_unstable_times(table, context):
    """Only the end-point controller (used below 95.6 m/s, t < 10 s) is wrong: the unstable
    loops are all clamped, reported, not refused. The times are the multiples of the step
    from the first one ≥ t_start up to t_end inclusive."""
    bad = _scaled(table, 30.0, index=0)
    rows = M.check_table_stabilises(bad, context, 2.3, 5.0, step_s=0.5)
    expected = []
    for t in (2.5, 3.0, 3.5, 4.0, 4.5, 5.0):
        clamped, eig = _reference(bad, context, t)
        assert clamped
        n = int(np.sum(np.abs(eig) > 1 + 1e-6))
        if n:
            expected.append((t, n))
    assert len(expected) == 6
    assert [(r["t_s"], r["n_unstable"]) for r in rows] == expected
    assert all(r["clamped"] for r in rows)
    # step 1 s from 2.0: 2, 3, 4, 5 (t_start on a multiple is included)
    rows = M.check_table_stabilises(bad, context, 2.0, 5.0)
    assert [r["t_s"] for r in rows] == [2.0, 3.0, 4.0, 5.0]


@pytest.mark.parametrize("t_end, shown", [(24.0, "20, 21, 22, 23, 24 s"),
                                          (25.0, "20, 21, 22, 23, 24 … s")])
def test_check_table_stabilises_refuses_inside_the_grid(table, context, t_end, shown):
    from vega_core.errors import BadFile

    bad = _scaled(table, 30.0)
    big = max(np.max(np.abs(_reference(bad, context, t)[1]))
              for t in np.arange(20.0, t_end + 0.5, 1.0))
    with pytest.raises(BadFile) as err:
        M.check_table_stabilises(bad, context, 19.5, t_end)
    msg = str(err.value)
    assert f"unstable inside its scheduling range at t = {shown} (largest " in msg
    assert f"|eigenvalue| {big:.6g})" in msg
    assert str(bad.path) in msg


# ----------------------------------------------------------------------------- the sweep
@pytest.mark.slow
def test_sweep_in_process_progress_and_rows(context):
    """41 times, one plant each, in this process: 21 progress lines (every 41 // 20 = 2nd
    time, and the last), rows by time, the nominal corner."""
    times = [47.0 + 0.25 * k for k in range(41)]
    lines = []
    res = M.sweep(str(SHIPPED), times, workers=0, progress=lines.append)
    assert res["workers"] == 0 and res["run_time_s"] > 0
    assert len(res["corners"]) == 1 and not any(res["corners"][0].values())
    assert [r["t_s"] for r in res["rows"]] == times
    assert all(r["corner"] == 0 for r in res["rows"])
    for r in res["rows"]:
        p = context.parameters(r["t_s"])
        assert r["v_sched_mps"] == r["v_plant_mps"] == p.v_mps and r["clamped"] is False
        assert r["n_unstable"] == r["n_unstable_nyquist"] == 0     # Nyquist on corner 0
    assert len(lines) == 21
    done = [int(re.match(r"margins: (\d+)/41 times \(1 plant\(s\) each\), t = ", s).group(1))
            for s in lines]
    assert done == list(range(2, 41, 2)) + [41]
    assert lines[0].startswith("margins: 2/41 times (1 plant(s) each), t = 47.25 s, ")
    assert lines[-1].startswith("margins: 41/41 times (1 plant(s) each), t = 57 s, ")
    assert all(s.endswith(" s elapsed") for s in lines)
    # no callback: the same rows, silently
    quiet = M.sweep(str(SHIPPED), times[:2], workers=0)
    assert [r["t_s"] for r in quiet["rows"]] == times[:2]
    assert quiet["rows"][1]["pm_deg"] == res["rows"][1]["pm_deg"]


def test_init_worker_and_time_task(context):
    M._init_worker(str(SHIPPED))
    try:
        assert M._WORKER["table"].path == str(SHIPPED)
        assert M._WORKER["table"].grid_v_mps[0] == pytest.approx(95.6081449)
        assert M._WORKER["context"].parameters(60.0).v_mps == context.parameters(60.0).v_mps
        dev = {"thrust": 0.0, "delay_s": 0.01}
        rows = M._time_task((60.0, [(0, {"thrust": 0.0}), (3, dev)]))
    finally:
        M._WORKER.clear()
    assert [(r["t_s"], r["corner"]) for r in rows] == [(60.0, 0), (60.0, 3)]
    assert rows[1]["delay_s"] == pytest.approx(0.049)
    assert "n_unstable_nyquist" in rows[0] and "n_unstable_nyquist" not in rows[1]


def test_sweep_progress_every_time_for_few_times_and_the_elapsed_time():
    """Fewer than 40 times: a line after every time; the elapsed time in each line and the
    run time are this run's (measured around the call here)."""
    import time

    lines = []
    t0 = time.perf_counter()
    res = M.sweep(str(SHIPPED), [10.0, 20.0, 30.0], workers=0, progress=lines.append)
    wall = time.perf_counter() - t0
    assert [s.split(" times")[0] for s in lines] == ["margins: 1/3", "margins: 2/3",
                                                    "margins: 3/3"]
    assert [s.split("t = ")[1].split(" s,")[0] for s in lines] == ["10", "20", "30"]
    elapsed = [float(s.split(", ")[-1].removesuffix(" s elapsed")) for s in lines]
    assert 0.0 <= elapsed[0] <= elapsed[1] <= elapsed[2] <= wall + 0.05
    assert 0.0 < res["run_time_s"] <= wall


@pytest.mark.slow
def test_sweep_in_worker_processes_matches_the_in_process_sweep():
    """One spawned worker (the parent does not load the table itself): the same rows as the
    in-process sweep, by time, and a progress line per time counted from 1."""
    times = [47.0, 47.5, 48.0]
    M._WORKER.clear()
    lines = []
    res = M.sweep(str(SHIPPED), times, workers=1, progress=lines.append)
    assert M._WORKER == {}
    assert res["workers"] == 1
    assert [s.split(" times")[0] for s in lines] == ["margins: 1/3", "margins: 2/3",
                                                    "margins: 3/3"]
    assert lines[-1].startswith("margins: 3/3 times (1 plant(s) each), t = 48 s, ")
    here = M.sweep(str(SHIPPED), times, workers=0)
    M._WORKER.clear()
    # the default: two worker processes, nominal plant only
    two = M.sweep(str(SHIPPED), times[:1])
    assert M._WORKER == {} and two["workers"] == 2 and len(two["corners"]) == 1
    assert two["rows"][0]["pm_deg"] == here["rows"][0]["pm_deg"]
    assert [r["t_s"] for r in res["rows"]] == times
    for a, b in zip(res["rows"], here["rows"]):
        assert a.keys() == b.keys()
        for k in a:
            assert a[k] == b[k] or (a[k] != a[k] and b[k] != b[k]), k
