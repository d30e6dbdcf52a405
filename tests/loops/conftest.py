"""Fixtures shared by the margin-tool tests (tests/loops/test_margins_*.py): the default
model context and the LPV controller table they analyse. A test file defining a fixture of the
same name uses its own."""

from pathlib import Path

import pytest

LPV_TABLE = (Path(__file__).resolve().parents[2]
             / "ros2_ws/src/vega_gnc/config/lpv_controller.npz")


@pytest.fixture(scope="module")
def context():
    from vega_model.parameters import default_context

    return default_context()


@pytest.fixture(scope="module")
def table():
    from vega_gnc.controller_table import load_controller_table

    return load_controller_table(LPV_TABLE)
