"""The shipped default controller table (vega_gnc/config/tvc_controller.npz, `vega design`)
meets the flight-design requirements it was tuned for, checked with the independent margin
tool (vega_loops.margins: its own frequency grid, the flown interpolated controller):

* it is the structured design and covers the whole flight (pad noise to dispersed burn-out);
* every nominal frozen loop 0–100 s every 0.5 s is stable with the flown controller;
* heritage margins on the nominal plant at lift-off, max-Q and burn-out and between grid points;
* the bending-edge plants of thesis Table 2.3 and the Table 2.3 inertia stay stable at max-Q;
* its bytes are the ones its sign-off record (config/tvc_controller.signoff.json, installed by
  `vega ship`) signed off, and that record's gated checks all passed.

The table is the output of one from-scratch `vega design` run (design_runs/seed1-ratio/,
docs/FLIGHT_DESIGN.md §6.0).
"""

import math
from pathlib import Path

import numpy as np
import pytest

from vega_loops import margins as M
from vega_design.structured import V_BELOW_LIFTOFF_MPS, V_BEYOND_BURNOUT
from vega_gnc.controller_table import default_table_path, load_controller_table


@pytest.fixture(scope="module")
def context():
    from vega_model.parameters import default_context

    return default_context()


@pytest.fixture(scope="module")
def table():
    return load_controller_table(default_table_path())


def test_structured_and_whole_flight(table, context):
    assert table.design == "structured" and math.isnan(table.gamma)
    assert table.grid_v_mps[0] == V_BELOW_LIFTOFF_MPS
    assert table.grid_v_mps[-1] == pytest.approx(V_BEYOND_BURNOUT * context.parameters(100).v_mps)
    assert all(table.metadata["controller_stable"])


@pytest.mark.slow
def test_every_nominal_frozen_loop_is_stable(table, context):
    rows = M.frozen_stability(table, context, M.default_times())
    assert not any(r["clamped"] for r in rows)
    # 0 s: no thrust yet (no control authority): the loop is open, marginal at |z| = 1
    assert [r["t_s"] for r in rows if r["n_unstable"]] == []
    assert max(r["max_abs_eig"] for r in rows if r["t_s"] >= 0.5) < 1.0


@pytest.mark.parametrize("t_s", [0.5, 5.0, 11.0, 31.0, 47.5, 59.0, 75.0, 84.5, 85.5, 93.0, 99.0,
                                 100.0])
def test_nominal_heritage_margins(table, context, t_s):
    """Grid points and points between them (odd seconds: the interpolated controller; 84.5 and
    85.5 s: the transition into the tail-off controller; 100 s: burn-out, where the PM falls
    below 30° unless the tail-off is tuned jointly, docs/FLIGHT_DESIGN.md §4 step 5)."""
    from vega_model.uncertainty import UncertaintySet

    uset = UncertaintySet.from_vehicle(context.vehicle)
    row = M.analyse_time(table, context, t_s, [(0, uset.nominal())])[0]
    ok = M.criteria_ok(row)
    assert all(ok.values()), ({k: v for k, v in ok.items() if not v},
                              {k: row[k] for k in ("pm_deg", "gm_low_db", "gm_high_db",
                                                   "b1_peak_db", "b2_peak_db")})


@pytest.mark.slow
def test_bending_edges_and_table_2_3_inertia_stable_at_max_q(table, context):
    from vega_model.uncertainty import UncertaintySet

    uset = UncertaintySet.from_vehicle(context.vehicle)
    t_q = M.max_q_time(context)
    cases = [{"bending_frequency_1": f, "psi_mode_1": s, "delay_s": d}
             for f in (-0.20, -0.12, 0.15) for s in (-0.4, 0.3) for d in (-0.01, 0.01)]
    cases += [{"bending_frequency_2": f, "psi_mode_2": 0.5, "delay_s": 0.01}
              for f in (-0.25, 0.2)]
    cases.append({"jyy": M.JYY_TABLE_2_3})
    corners = [(k, {**uset.nominal(), **c}) for k, c in enumerate(cases)]
    rows = M.analyse_time(table, context, t_q, corners, nyquist=False)
    unstable = [cases[r["corner"]] for r in rows if r["n_unstable"]]
    assert unstable == []
    assert np.all(np.isfinite([r["max_abs_eig"] for r in rows]))


@pytest.mark.slow
@pytest.mark.parametrize("t_s", [0.5, 34.5, 43.0, 58.0, 60.0])
def test_exact_bending_criterion_at_the_dispersed_bending_corners(table, context, t_s):
    """At the times where the exact heritage bending criterion is hardest to meet at a dispersed
    bending corner, it is met at all 128 of them: 34.5 and 43 s (corners 536 and 568: f₁
    −20 %, mode-1 shapes +30 %, thrust and actuator bandwidth +10 %, delay +10 ms, where mode 1
    is phase-stabilised with an in-band GM near 6 dB), 0.5, 58 and 60 s (where step 7 of the
    run that made this table repaired misses: 0.5 s and 58 s log10_lp1_radps, 60 s
    notch1_zeta_num; its tuning record's solver.corner_repair)."""
    from vega_model.uncertainty import UncertaintySet

    uset = UncertaintySet.from_vehicle(context.vehicle)
    corners = [(k, dev) for k, dev in enumerate(M.dispersed_corners(uset))
               if M.corner_family(k) == "bending"]
    assert len(corners) == 128
    rows = M.analyse_time(table, context, t_s, corners, nyquist=False)
    assert [r["corner"] for r in rows if r["n_unstable"]] == []
    assert [r["corner"] for r in rows if not M.bending_ok(r, 1)] == []
    assert [r["corner"] for r in rows if not M.bending_ok(r, 2)] == []


def test_the_flown_bytes_are_the_signed_off_ones():
    """`vega ship` copies a table only with a complete sign-off record; this holds the
    installed files to it with ship's own rule (vega_cli.signoff.record.check_record: every
    gated check passed, the scope is the whole sign-off), and the table's SHA-256 is the
    record's, its campaign without an unstable flight and at least at its reference."""
    from vega_cli.signoff.record import check_record, read_record, sha256_of, signed_off_passes

    path = Path(default_table_path())
    where = path.with_name("tvc_controller.signoff.json")
    record = read_record(where)
    check_record(record, where, reference_floor=None)
    assert sha256_of(path) == record["table_sha256"]
    mc = next(c for c in record["checks"] if c["check"].startswith("mc ") and c["gated"])
    assert mc["figures"]["unstable"] == 0
    assert signed_off_passes(record) >= record["scope"]["mc_reference"]
