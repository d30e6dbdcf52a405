"""``vega synth``'s solver-path option mirrors the pipeline (one source of truth, held by this
test: the CLI spells the choices out to stay fast to start)."""

import subprocess
import sys

from vega_lpv.pipeline import DEFAULT_SOLVER_PATH, SOLVER_PATHS
from vega_cli.cli import build_parser


def _synth_action(option: str):
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a.choices, dict) and "synth" in a.choices)
    synth = sub.choices["synth"]
    return next(a for a in synth._actions if option in a.option_strings)


def test_solver_path_choices_and_default_are_the_pipelines():
    action = _synth_action("--solver-path")
    assert tuple(action.choices) == tuple(SOLVER_PATHS)
    assert action.default == DEFAULT_SOLVER_PATH == "ipm"


def test_an_unknown_solver_path_is_refused_before_anything_runs():
    result = subprocess.run([sys.executable, "-m", "vega_cli.cli", "synth", "--solver-path",
                             "fast"], capture_output=True, text=True, timeout=120, check=False)
    assert result.returncode == 2
    assert "--solver-path" in result.stderr and "'fast'" in result.stderr
    assert result.stdout == ""
