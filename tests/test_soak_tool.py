"""tools/soak.py (the flake check: rounds of concurrent whole-suite copies): pytest's summary
line parsed, the round verdict, and one real round on a passing and on a failing test file."""

import importlib.util
import subprocess
import sys
from pathlib import Path
import pytest

ROOT = Path(__file__).resolve().parents[1]
_spec = importlib.util.spec_from_file_location("soak", ROOT / "tools" / "soak.py")
soak = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(soak)


def test_summary_line_counts():
    text = ("....F\nFAILED tests/x.py::test_a - assert 1 == 2\n"
            "1 failed, 12 passed, 2 skipped, 1 error in 3.21s\n")
    assert soak.summary(text) == {"passed": 12, "failed": 1, "skipped": 2, "errors": 1}
    assert soak.summary("no summary here") == {"passed": 0, "failed": 0, "skipped": 0,
                                               "errors": 0}


def test_round_verdict_needs_every_copy_clean():
    ok = {"passed": 5, "failed": 0, "skipped": 0, "errors": 0}
    assert soak.round_passed([0, 0], [ok, ok])
    assert not soak.round_passed([0, 1], [ok, ok])
    assert not soak.round_passed([0, 0], [ok, dict(ok, skipped=1)])
    assert not soak.round_passed([0, 0], [ok, dict(ok, passed=0)])


@pytest.mark.slow
def test_one_round_on_real_copies(tmp_path):
    """Two copies of a passing file: exit 0 and a PASS line; of a file with a failing test:
    exit 1, and the log names the failing test of both copies."""
    good = tmp_path / "test_good.py"
    good.write_text("def test_ok():\n    assert 1 + 1 == 2\n")
    bad = tmp_path / "test_bad.py"
    bad.write_text("def test_no():\n    assert 1 + 1 == 3\n")
    log = tmp_path / "soak.jsonl"
    run = [sys.executable, str(ROOT / "tools" / "soak.py"), "--rounds", "1", "--copies", "2",
           "--log", str(log), "--"]
    passed = subprocess.run(run + [str(good)], capture_output=True, text=True, timeout=300)
    assert passed.returncode == 0, passed.stdout + passed.stderr
    assert "round 1/1: PASS" in passed.stdout
    failed = subprocess.run(run + [str(bad)], capture_output=True, text=True, timeout=300)
    assert failed.returncode == 1
    last = log.read_text().splitlines()[-1]
    assert '"passed": false' in last and last.count("test_bad.py::test_no") == 2
    kept = sorted(tmp_path.glob("soak-round1-copy*.log"))
    assert [p.name for p in kept] == ["soak-round1-copy0.log", "soak-round1-copy1.log"]
    assert all("assert 1 + 1 == 3" in p.read_text() for p in kept)
