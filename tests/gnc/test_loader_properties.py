"""Property tests of the flight side's file loaders (hypothesis): whatever one corruption does
to a valid controller table or guidance reference — a key dropped, a value made non-finite, an
array reshaped or retyped, a grid made non-monotonic — the loader refuses it with ONE line that
names the file (a BadFile), and never with another exception."""

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fixture_tables import write_pd_table
from vega_core.errors import BadFile
from vega_gnc.controller_table import validate_arrays
from vega_gnc.guidance_reference import default_reference_path, validate_reference_arrays


@pytest.fixture(scope="module")
def table_arrays(tmp_path_factory):
    path = tmp_path_factory.mktemp("pd") / "pd.npz"
    write_pd_table(path)
    with np.load(path) as npz:
        return {k: npz[k] for k in npz.files}


@pytest.fixture(scope="module")
def reference_arrays():
    with np.load(default_reference_path()) as npz:
        return {k: npz[k] for k in npz.files}


KINDS = ("drop", "nan", "inf", "reshape", "string", "reverse")


def _corrupt(arrays, kind, key, where):
    out = dict(arrays)
    arr = np.asarray(out[key])
    if kind == "drop":
        del out[key]
    elif kind in ("nan", "inf"):
        bad = np.array(arr, dtype=float)
        if bad.size == 0:
            return None
        bad.flat[where % bad.size] = np.nan if kind == "nan" else -np.inf
        out[key] = bad
    elif kind == "reshape":
        if arr.ndim == 0 or arr.size < 2:
            return None
        out[key] = arr.reshape(-1)[:-1]
    elif kind == "string":
        out[key] = np.array(["x"] * max(arr.size, 1))
    elif kind == "reverse":
        if arr.ndim != 1 or arr.size < 2:
            return None
        out[key] = arr[::-1].copy()
    return out


def _check(validate, arrays, kind, key, where):
    corrupted = _corrupt(arrays, kind, key, where)
    if corrupted is None:
        return
    try:
        validate("corrupt.npz", corrupted)
    except BadFile as exc:
        text = str(exc)
        assert text.startswith("corrupt.npz: ") and "\n" not in text, text
    else:
        raise AssertionError(f"{kind} of {key!r} accepted")


TABLE_KEYS = ("format_version", "grid_v_mps", "dt_s", "gamma", "gamma_min", "rate_bounds_mps2",
              "A", "B", "C", "D", "Ad", "Bd", "Cd", "Dd")


@settings(max_examples=150, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(kind=st.sampled_from(("drop", "nan", "inf", "reshape", "string")),
       key=st.sampled_from(TABLE_KEYS), where=st.integers(0, 10_000))
def test_a_corrupted_controller_table_is_refused_in_one_line(table_arrays, kind, key, where):
    if kind in ("nan", "inf") and key == "format_version":
        return                          # a non-finite version is not an integer: refused too
    _check(validate_arrays, table_arrays, kind, key, where)


@settings(max_examples=100, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(kind=st.sampled_from(KINDS), key=st.sampled_from(("t_s", "reference", "beta_ff_rad",
                                                          "format_version")),
       where=st.integers(0, 10_000))
def test_a_corrupted_guidance_reference_is_refused_in_one_line(reference_arrays, kind, key,
                                                               where):
    if kind == "reverse" and key != "t_s":
        return                          # reversing the values alone is a valid (other) file
    if kind in ("nan", "inf") and key == "format_version":
        return
    _check(validate_reference_arrays, reference_arrays, kind, key, where)


def test_the_unchanged_files_load(table_arrays, reference_arrays):
    validate_arrays("ok.npz", table_arrays)
    validate_reference_arrays("ok.npz", reference_arrays)
