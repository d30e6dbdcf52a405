"""Flight-condition table: regeneration reproduces the committed file, loader, interpolation.

The trajectory is simulated once through the ``vega trajectory`` command module (module
fixture) and once more at half the integration step; every other test reads the committed table.
"""

import argparse
import contextlib
import io
import math
from dataclasses import fields

import numpy as np
import pytest

from vega_reference.trajectory import (AscentModel, TrajectoryError, simulate,
                                          write_flight_conditions)
from vega_model.flight_conditions import (COLUMNS, FlightCondition, FlightConditions,
                                          FlightConditionsError, default_flight_conditions_path)
from vega_model.vehicle_data import load_vehicle_data
from vega_cli.commands import trajectory as trajectory_command

REQUIRED = ("t_s", "v_mps", "vdot_mps2", "h_m", "mach", "rho_kgpm3", "sound_speed_mps", "q_pa",
            "thrust_n", "axial_force_n", "mass_kg", "x_cg_m", "jyy_kgm2", "x_cp_m",
            "cn_alpha_per_rad", "c_a", "flight_path_angle_rad", "gravity_mps2")


@pytest.fixture(scope="module")
def regenerated(tmp_path_factory):
    """Run ``vega trajectory --out FILE`` once; return (path, printed summary line)."""
    out = tmp_path_factory.mktemp("trajectory") / "flight_conditions.csv"
    parser = argparse.ArgumentParser(prog="vega")
    trajectory_command.register(parser.add_subparsers(dest="command"))
    args = parser.parse_args(["trajectory", "--out", str(out)])
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        assert args.func(args) == 0
    return out, printed.getvalue()


@pytest.fixture(scope="module")
def fc():
    return FlightConditions.load()


@pytest.mark.slow
def test_regenerating_reproduces_the_committed_table(regenerated):
    out, _ = regenerated
    committed = default_flight_conditions_path().read_bytes()
    new = out.read_bytes()
    if new != committed:
        diff = [i + 1 for i, (a, b) in enumerate(zip(new.splitlines(), committed.splitlines()))
                if a != b]
        pytest.fail(f"regenerated table differs from the committed one (first differing lines "
                    f"{diff[:5]}); run: vega trajectory --out "
                    f"ros2_ws/src/vega_model/vega_model/data/flight_conditions.csv")


@pytest.mark.slow
def test_summary_line(regenerated):
    out, line = regenerated
    assert line.count("\n") == 1
    assert line.startswith(f"wrote 1101 rows (0-110 s) to {out}: ")
    assert "max-Q 60.1" in line and "at t = 47." in line and "v(110 s) = 19" in line


def test_unwritable_output_is_a_one_line_error(tmp_path):
    out = tmp_path / "missing" / "fc.csv"
    with pytest.raises(TrajectoryError) as info:
        write_flight_conditions(out)
    assert isinstance(info.value, ValueError)
    assert str(info.value) == f"{out}: cannot write flight conditions (no directory {out.parent})"


def test_provenance_header_without_timestamp(fc):
    text = default_flight_conditions_path().read_text(encoding="utf-8")
    assert text.splitlines()[0] == "# vega_flight_conditions 1"
    assert fc.provenance["generator"].startswith("vega_reference.trajectory")
    assert len(fc.provenance["vehicle_yaml_sha256"]) == 64
    assert "regenerate" in fc.provenance
    assert not any(w in text.lower() for w in ("date", "time:", "utc", "generated at"))


def test_columns_and_grid(fc):
    assert set(REQUIRED) <= set(COLUMNS)
    assert tuple(f.name for f in fields(FlightCondition)) == COLUMNS == fc.columns
    np.testing.assert_allclose(fc.t_s, np.arange(1101) * 0.1, rtol=0, atol=1e-9)
    for name in COLUMNS:
        assert np.all(np.isfinite(fc.column(name))), name
    with pytest.raises(KeyError, match="no column 'pitch_deg'"):
        fc.column("pitch_deg")


def test_table_is_internally_consistent(fc):
    """Derived columns follow from the primary ones (thesis Eqs. 2.12, 2.15)."""
    v, rho, a = fc.column("v_mps"), fc.column("rho_kgpm3"), fc.column("sound_speed_mps")
    np.testing.assert_allclose(fc.column("q_pa"), 0.5 * rho * v * v, rtol=1e-8, atol=1e-6)
    np.testing.assert_allclose(fc.column("mach"), v / a, rtol=1e-8, atol=1e-12)
    np.testing.assert_allclose(fc.column("axial_force_n"),
                               fc.column("q_pa") * 7.14 * fc.column("c_a"), rtol=1e-7, atol=1e-6)
    # the v̇ column integrates to v (trapezoidal rule on the 0.1 s grid, from the first row
    # after lift-off at 0.82 s, where v̇ jumps)
    vdot, i0 = fc.column("vdot_mps2"), 9
    steps = 0.5 * (vdot[i0 + 1:] + vdot[i0:-1]) * np.diff(fc.t_s[i0:])
    assert np.max(np.abs(v[i0] + np.cumsum(steps) - v[i0 + 1:])) < 0.02
    # zero angle of attack after the pitch-over kick: the operating point of thesis §2.10.1
    alpha = fc.column("alpha_rad")
    assert np.all(alpha <= 0.0) and np.all(alpha[fc.t_s >= 20.0] == 0.0)
    assert np.all(alpha[fc.t_s <= 4.0] == 0.0)
    assert math.degrees(alpha.min()) > -6.0


def test_consistent_with_thesis_table_2_1(fc):
    """P80 figures (thesis Table 2.1): 88 t of propellant, 114 s, 2200 kN average, Isp 280 s."""
    data = load_vehicle_data()
    assert (data["propulsion.propellant_mass_kg"], data["propulsion.burn_time_s"],
            data["propulsion.average_thrust_n"], data["propulsion.isp_vacuum_s"]) == (
        88000.0, 114.0, 2200e3, 280.0)
    burnt = fc.column("mass_kg")[0] - fc.column("mass_kg")[-1]
    assert 0.97 * 88000.0 < burnt < 88000.0          # nearly all burnt by 110 s (tail-off)
    impulse = np.trapezoid(fc.column("thrust_n"), fc.t_s)
    assert impulse / 114.0 == pytest.approx(2200e3, rel=0.10)   # rounded catalogue values
    isp_effective = impulse / (burnt * 9.80665)
    assert 0.93 * 280.0 < isp_effective < 280.0      # sea-level losses: below vacuum Isp


@pytest.mark.slow
def test_integration_step_converged(fc):
    """Halving the Runge-Kutta step (0.01 s -> 0.005 s) changes v by < 1e-4 m/s."""
    fine = simulate(AscentModel.from_vehicle(load_vehicle_data()), substeps=20)
    assert np.max(np.abs(fine["v_mps"] - fc.column("v_mps"))) < 1e-4
    assert np.max(np.abs(fine["h_m"] - fc.column("h_m"))) < 0.01


def test_at_interpolates_linearly_and_clamps(fc):
    t = 47.23
    i = int(np.searchsorted(fc.t_s, t)) - 1
    w = (t - fc.t_s[i]) / (fc.t_s[i + 1] - fc.t_s[i])
    got = fc.at(t)
    assert got.t_s == t
    for name in COLUMNS[1:]:
        col = fc.column(name)
        assert getattr(got, name) == pytest.approx(col[i] + w * (col[i + 1] - col[i]),
                                                   rel=1e-12, abs=1e-12), name
    row = fc.at(fc.t_s[300])
    assert row.q_pa == fc.column("q_pa")[300]
    assert fc.at(-5.0) == fc.at(0.0)
    assert fc.at(500.0).v_mps == fc.column("v_mps")[-1]
    with pytest.raises(ValueError, match="NaN"):
        fc.at(math.nan)
    with pytest.raises(AttributeError):
        got.v_mps = 0.0     # frozen


# --- malformed files -------------------------------------------------------------------

def _committed_lines():
    return default_flight_conditions_path().read_text(encoding="utf-8").splitlines()


def _header_index(lines):
    return next(i for i, line in enumerate(lines) if not line.startswith("#"))


def _write(tmp_path, lines):
    path = tmp_path / "bad.csv"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def _edit_cell(lines, row, column, value):
    h = _header_index(lines)
    names = lines[h].split(",")
    cells = lines[h + 1 + row].split(",")
    cells[names.index(column)] = value
    lines[h + 1 + row] = ",".join(cells)
    return lines


def _drop_column(lines, column):
    h = _header_index(lines)
    k = lines[h].split(",").index(column)
    return lines[:h] + [",".join(c for j, c in enumerate(line.split(",")) if j != k)
                        for line in lines[h:]]


@pytest.mark.parametrize("mutate, message", [
    (lambda ls: _drop_column(ls, "q_pa"), "missing column 'q_pa'"),
    (lambda ls: _edit_cell(ls, 10, "t_s", "0.85"), "t_s not strictly increasing"),
    (lambda ls: _edit_cell(ls, 10, "mach", "nan"), "non-finite value nan in column 'mach'"),
    (lambda ls: _edit_cell(ls, 10, "mach", "fast"), "not a number"),
    (lambda ls: ["# vega_flight_conditions 2"] + ls[1:], "unknown format version '2'"),
    (lambda ls: ls[1:], "format line missing"),
    (lambda ls: ls[:_header_index(ls) + 2], "need at least 2 data rows"),
])
def test_malformed_file_is_rejected_in_one_line(tmp_path, mutate, message):
    path = _write(tmp_path, mutate(_committed_lines()))
    with pytest.raises(FlightConditionsError) as info:
        FlightConditions.load(path)
    text = str(info.value)
    assert "\n" not in text
    assert text.startswith(f"{path}: ")
    assert message in text
    assert isinstance(info.value, ValueError)


def test_unreadable_file(tmp_path):
    missing = tmp_path / "none.csv"
    with pytest.raises(FlightConditionsError, match=f"{missing}: cannot read"):
        FlightConditions.load(missing)


def test_load_accepts_any_column_order(tmp_path, fc):
    lines = _committed_lines()
    h = _header_index(lines)
    rows = [line.split(",") for line in lines[h:]]
    perm = list(range(len(rows[0])))[::-1]
    swapped = lines[:h] + [",".join(r[j] for j in perm) for r in rows]
    path = _write(tmp_path, swapped)
    other = FlightConditions.load(path)
    assert other.path == str(path)
    assert other.at(33.33) == fc.at(33.33)
    np.testing.assert_array_equal(other.column("q_pa"), fc.column("q_pa"))
