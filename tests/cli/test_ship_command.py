"""``vega ship`` (vega_cli.signoff.ship): a table becomes the flown default only from a
complete, passed sign-off record of its own bytes (docs/FLIGHT_DESIGN.md §6.5).

The table is a real structured table (the frozen 2026-11-27 copy in tests/data), the records
are hand-made in the format of ``vega verify``; every refusal is one line, exit 2, and leaves
the flown directory byte for byte as it was; ``--check`` accepts what ships and writes
nothing."""

import hashlib
import json
import shutil
from pathlib import Path

import pytest

from fixture_tables import STRUCTURED_2026_11_27
from vega_cli import cli
from vega_cli.signoff import record as R


def _ship(args) -> int:
    return cli.main(["ship", *args])


def _sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _record(table: Path, passes=746, **scope) -> dict:
    checks = [{"check": f"sil {s}", "gated": True, "passed": True} for s in R.GATED_SCENARIOS]
    checks += [{"check": "sil severe", "gated": False, "passed": False},
               {"check": "margins --dispersed", "gated": True, "passed": True},
               {"check": "robust --no-mu", "gated": True, "passed": True},
               {"check": "mc 852 flights", "gated": True, "passed": True,
                "figures": {"runs": 852, "passed": passes}}]
    return {"table": str(table), "table_sha256": _sha(table),
            "scope": {"checks": list(R.CHECKS),
                      "scenarios": list(R.GATED_SCENARIOS + R.REPORTED_SCENARIOS),
                      "at": "0:100:0.5", "runs": 852, "mc_reference": 746, **scope},
            "checks": checks, "signed_off": True}


@pytest.fixture
def setup(tmp_path):
    """A design run's table and tuning record, its sign-off directory, and a flown directory
    holding an older table."""
    run = tmp_path / "run"
    run.mkdir()
    table = run / "tvc_controller.npz"
    shutil.copyfile(STRUCTURED_2026_11_27, table)
    (run / "tvc_controller.json").write_text('{"tuning": "record"}\n')
    verify = tmp_path / "verify"
    verify.mkdir()
    config = tmp_path / "config"
    config.mkdir()
    (config / "tvc_controller.npz").write_bytes(b"old table")
    (config / "tvc_controller.json").write_text("old record")
    return table, verify, config


def _write(verify: Path, record) -> None:
    (verify / "verify.json").write_text(json.dumps(record))


def _snapshot(config: Path) -> dict:
    return {p.name: p.read_bytes() for p in sorted(config.iterdir())}


def test_a_complete_sign_off_ships_the_table_its_record_and_the_sign_off(setup, capsys):
    table, verify, config = setup
    _write(verify, _record(table))
    assert _ship([str(verify), "--config", str(config)]) == 0
    assert (config / "tvc_controller.npz").read_bytes() == table.read_bytes()
    assert (config / "tvc_controller.json").read_text() == '{"tuning": "record"}\n'
    shipped = json.loads((config / "tvc_controller.signoff.json").read_text())
    assert shipped["table_sha256"] == _sha(config / "tvc_controller.npz")
    assert shipped["shipped_from"] == str(table) and shipped["shipped_utc"].endswith("+00:00")
    assert R.signed_off_passes(shipped) == 746
    assert sorted(p.name for p in config.iterdir()) == [
        "tvc_controller.json", "tvc_controller.npz", "tvc_controller.signoff.json"]
    assert "746 of 852 flights" in capsys.readouterr().out


def test_check_accepts_a_complete_sign_off_and_writes_nothing(setup, capsys):
    table, verify, config = setup
    _write(verify, _record(table))
    before = _snapshot(config)
    assert _ship([str(verify), "--config", str(config), "--check"]) == 0
    assert _snapshot(config) == before
    out = capsys.readouterr().out
    assert "746 of 852 flights" in out and "nothing written (--check)" in out
    record = _record(table)
    record["signed_off"] = False
    _write(verify, record)
    assert _ship([str(verify), "--config", str(config), "--check"]) == 2
    assert "not signed off" in capsys.readouterr().err
    assert _snapshot(config) == before


def test_a_moved_table_is_shipped_with_table_when_its_bytes_are_the_signed_off_ones(setup):
    table, verify, config = setup
    _write(verify, _record(table))
    moved = table.parent / "moved.npz"
    table.rename(moved)
    (table.parent / "tvc_controller.json").rename(moved.with_suffix(".json"))
    assert _ship([str(verify), "--config", str(config)]) == 2      # not where it was verified
    assert _ship([str(verify), "--config", str(config), "--table", str(moved)]) == 0
    assert (config / "tvc_controller.npz").read_bytes() == moved.read_bytes()


def _edit(record, path, value):
    *keys, last = path.split(".")
    for k in keys:
        record = record[k]
    if value is KeyError:
        del record[last]
    else:
        record[last] = value


@pytest.mark.parametrize("edit, message", [
    (("signed_off", False), "not signed off"),
    (("checks", [{"check": "robust --no-mu", "gated": True, "passed": False}]),
     "not signed off (failed: robust --no-mu)"),
    (("scope.checks", ["sil", "margins", "mc"]), "short of the full sign-off: robust"),
    (("scope.scenarios", ["nominal", "thesis"]), "scenario gust; scenario wind_change"),
    (("scope.at", "43"), "frozen times '43' (not 0:100:0.5)"),
    (("scope.runs", 80), "80 flights (fewer than 852)"),
    (("scope.mc_reference", None), "no Monte Carlo reference"),
    (("table_sha256", KeyError), "no table_sha256 (written by an older vega verify?"),
    (("table_sha256", "0" * 64), "is not the signed-off 000000000000… of"),
])
def test_refusals_are_one_line_exit_2_and_leave_the_flown_files(setup, capsys, edit, message):
    table, verify, config = setup
    record = _record(table)
    _edit(record, *edit)
    _write(verify, record)
    before = _snapshot(config)
    assert _ship([str(verify), "--config", str(config)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("vega: error: ") and message in err, err
    assert _snapshot(config) == before


def test_a_table_changed_after_its_sign_off_is_refused(setup, capsys):
    table, verify, config = setup
    _write(verify, _record(table))
    with open(table, "ab") as f:
        f.write(b"\0")
    before = _snapshot(config)
    assert _ship([str(verify), "--config", str(config)]) == 2
    assert "changed since verified" in capsys.readouterr().err
    assert _snapshot(config) == before


def test_the_reference_may_not_fall_below_the_flown_tables_own_passes(setup, capsys):
    """Once the flown table has a sign-off, a new one must be compared against at least its
    passes: a design cannot ship on a lower bar than the one it replaces."""
    table, verify, config = setup
    (config / "tvc_controller.signoff.json").write_text(json.dumps(_record(table, passes=760)))
    _write(verify, _record(table, passes=750, mc_reference=746))
    before = _snapshot(config)
    assert _ship([str(verify), "--config", str(config)]) == 2
    assert "Monte Carlo reference 746 below the flown table's 760 passes" in \
        capsys.readouterr().err
    assert _snapshot(config) == before
    _write(verify, _record(table, passes=761, mc_reference=760))
    assert _ship([str(verify), "--config", str(config)]) == 0


@pytest.mark.parametrize("content, message", [
    (None, "verify.json: [Errno 2]"),
    ("{not json", "verify.json: not JSON"),
    ("[1, 2]", "verify.json: not a JSON object"),
])
def test_a_missing_or_broken_record_is_bad_input(setup, capsys, content, message):
    table, verify, config = setup
    if content is not None:
        (verify / "verify.json").write_text(content)
    before = _snapshot(config)
    assert _ship([str(verify), "--config", str(config)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err, err
    assert _snapshot(config) == before


def test_a_missing_tuning_record_or_a_broken_table_is_refused(setup, capsys):
    table, verify, config = setup
    (table.parent / "tvc_controller.json").unlink()
    _write(verify, _record(table))
    assert _ship([str(verify), "--config", str(config)]) == 2
    assert "tuning record" in capsys.readouterr().err
    (table.parent / "tvc_controller.json").write_text("{}")
    table.write_bytes(b"not an npz")
    _write(verify, _record(table))
    before = _snapshot(config)
    assert _ship([str(verify), "--config", str(config)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"table {table}:" in err, err
    assert _snapshot(config) == before
