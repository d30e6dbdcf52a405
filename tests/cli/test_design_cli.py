"""`vega design`: refusals of bad arguments (one line, exit 2, nothing written); the tuning
itself is tested in tests/synthesis/test_structured_design.py (a full run takes ≈ 40 min)."""

from pathlib import Path

import pytest

from vega_cli import cli

LPV = Path(__file__).resolve().parents[2] / "ros2_ws/src/vega_gnc/config/lpv_controller.npz"


@pytest.mark.parametrize("args, message", [
    (["--out", "{d}/t.txt"], "must end in .npz"),
    (["--out", "{d}/t.npz", "--maxiter", "0"], "--maxiter 0: must be within 1..1000"),
    (["--out", "{d}/t.npz", "--workers", "-1"], "--workers -1: must be within 0..64"),
    (["--out", "{d}/t.npz", "--anchors-from", str(LPV)], "not a structured design table"),
    (["--out", "{d}/t.npz", "--anchors-from", "{d}/missing.npz"], "no such file"),
    (["--out", "{d}/t.npz", "--maxiter", "x"], "invalid int value"),
])
def test_bad_arguments(tmp_path, capsys, args, message):
    argv = ["design", *(a.replace("{d}", str(tmp_path)) for a in args)]
    try:
        code = cli.main(argv)
    except SystemExit as exc:
        code = exc.code
    assert code == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1, err
    assert not any(tmp_path.iterdir())
