"""The mutation tool's two percentages (tools/mutation/run.py ``percentages``), against figures
worked out by hand from a module's counts: the table's killed % leaves "no tests" mutants out,
the strict % (issue 15's measure) counts them as not killed."""

import importlib.util
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def tool():
    spec = importlib.util.spec_from_file_location("mutation_run", ROOT / "tools/mutation/run.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _counts(**given):
    counts = {"killed": 0, "survived": 0, "equivalent": 0, "timeout": 0, "no tests": 0,
              "suspicious": 0, "not checked": 0}
    counts.update({k.replace("_", " "): v for k, v in given.items()})
    return counts


def test_no_tests_mutants_are_left_out_of_one_and_count_against_the_other(tool):
    # parameters at 3e3008e: 675 mutants, 610 killed, 35 survived, 30 no tests
    killed, strict = tool.percentages(675, _counts(killed=610, survived=35, no_tests=30))
    assert killed == round(100 * 610 / 645, 1) == 94.6
    assert strict == round(100 * 610 / 675, 1) == 90.4


def test_timeouts_count_as_killed_and_equivalents_and_unreached_are_left_out(tool):
    c = _counts(killed=80, timeout=5, survived=5, equivalent=7, no_tests=3, not_checked=10)
    assert tool.percentages(110, c) == (round(100 * 85 / 90, 1), round(100 * 85 / 93, 1))


def test_nothing_judged_gives_none(tool):
    assert tool.percentages(4, _counts(equivalent=2, no_tests=2)) == (None, 0.0)
    assert tool.percentages(2, _counts(equivalent=2)) == (None, None)
