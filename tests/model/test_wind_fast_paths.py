"""The plant's wind over a whole track (vega_model.wind: ``coefficients_many``, ``entry_steps``,
``entry_steps_array`` and its compiled recursion vega_model.wind_kernel) gives exactly the numbers
of the per-step code it replaces, and the parameter columns are the parameter sets' numbers.

Exact equality (no tolerance): the SIL is proven byte-equal to the in-process run, and both go
through these functions.
"""

import dataclasses
import math

import numpy as np
import pytest

from vega_model.parameters import default_context
from vega_model.wind import (DrydenTurbulence, GustProfile, ProfileChange, WindModel,
                             WindTable)


def _bits(values):
    return np.asarray(values, dtype=float).view(np.uint64).tolist()


@pytest.fixture(scope="module")
def data():
    return default_context().vehicle


def _altitudes_and_speeds(data, n, seed):
    rng = np.random.default_rng(seed)
    alt = [float(a) for a in data["wind.dryden.altitude_m"]]
    h = np.concatenate([rng.uniform(-500.0, 30000.0, n), alt, [0.0, -1.0, 20000.0, 20000.5,
                                                             1e6, alt[0] - 1e-9]])
    v = np.concatenate([rng.uniform(-50.0, 2000.0, n), np.linspace(0.0, 900.0, len(alt)),
                        [0.0, -3.0, 400.0, 400.0, 2500.0, 1e-300]])
    return h.tolist(), v.tolist()


@pytest.mark.parametrize("intensity", ["light", "severe", "none"])
def test_coefficients_many_equal_coefficients(data, intensity):
    turb = DrydenTurbulence(data, intensity, seed=0, dt_s=0.001)
    h, v = _altitudes_and_speeds(data, 3000, 1)
    got = turb.coefficients_many(h, v)
    want = list(zip(*(turb.coefficients(a, b) for a, b in zip(h, v))))
    assert [_bits(g) for g in got] == [_bits(w) for w in want]


@pytest.mark.parametrize("bad", [(math.nan, 100.0), (1000.0, math.inf), (-math.inf, 1.0)])
def test_coefficients_many_refuse_non_finite(data, bad):
    turb = DrydenTurbulence(data, "light", seed=0, dt_s=0.001)
    with pytest.raises(ValueError, match="non-finite"):
        turb.coefficients_many([1000.0, bad[0]], [300.0, bad[1]])


@pytest.mark.parametrize("steps_per_entry, skip", [(10, 0), (10, 1500), (7, 3), (1, 1023),
                                                   (5, 1024)])
def test_entry_steps_equal_steps_per_entry(data, steps_per_entry, skip):
    """Python and compiled paths against :meth:`steps` once per entry, from a generator already
    ``skip`` draws in (mid-block, block ends), across several noise blocks; afterwards the three
    generators go on with the same draws."""
    ref, py, nb = (DrydenTurbulence(data, "severe", seed=9, dt_s=0.001) for _ in range(3))
    for t in (ref, py, nb):
        t.steps(skip, (1.0, 0.5, 0.5))
    h, v = _altitudes_and_speeds(data, 600, 2)
    coeffs = ref.coefficients_many(h, v)
    want = []
    for c in zip(*coeffs):
        want += ref.steps(steps_per_entry, c)
    got_py = py.entry_steps(coeffs, steps_per_entry)
    got_nb = nb.entry_steps_array(coeffs, steps_per_entry)
    assert isinstance(got_nb, np.ndarray)
    assert _bits(got_py) == _bits(want)
    assert _bits(got_nb) == _bits(want)
    after = [t.steps(2100, (1.0, 0.9, 0.1)) for t in (ref, py, nb)]
    assert _bits(after[1]) == _bits(after[0]) and _bits(after[2]) == _bits(after[0])


@pytest.mark.parametrize("profile, turbulence, gust, change", [
    (True, "light", None, ProfileChange()),
    (True, "severe", GustProfile(12.3456, 2.0, -9.0), ProfileChange(1.3, -800.0)),
    (False, "moderate", GustProfile(0.0, 0.5, 4.0), ProfileChange()),
    (True, "none", GustProfile(19.995, 1.0, 9.0), ProfileChange(-0.5, 1000.0)),
    (False, "none", None, ProfileChange()),
    (WindTable([0.0, 3000.0, 11_000.0, 30_000.0], [2.0, 18.5, -6.25, 4.0]), "light",
     GustProfile(12.3456, 2.0, -9.0), ProfileChange(1.3, -800.0)),
])
def test_wind_entry_steps_equal_steps_per_entry(data, profile, turbulence, gust, change):
    """A 20 s track of 5 ms entries (altitudes and speeds of the shipped flight, perturbed):
    the same numbers as one :meth:`WindModel.steps` per entry (the gust's edges inside)."""
    ctx = default_context()
    t0_ms, dt_ms, spe = 5000, 1, 5
    params = ctx.parameters_at_times(np.arange(t0_ms, t0_ms + 20000, 5) / 1000.0,
                                     {"velocity": 0.05})
    h, v = [p.h_m for p in params], [p.v_mps for p in params]
    kw = dict(profile=profile, turbulence=turbulence, gust=gust, seed=3, dt_s=0.001,
              change=change)
    one, many = WindModel(data, **kw), WindModel(data, **kw)
    want = []
    for e, (a, b) in enumerate(zip(h, v)):
        first = t0_ms + e * spe * dt_ms
        want += one.steps([(first + k * dt_ms) / 1000.0 for k in range(spe)], a, b)
    got = many.entry_steps(t0_ms, dt_ms, spe, h, v)
    assert isinstance(got, list) and all(type(w) is float for w in got[:50])
    assert _bits(got) == _bits(want)


@pytest.mark.parametrize("deviations", [{}, {"velocity": 0.02, "density": -0.1, "x_cg": 0.01,
                                             "psi_mode_1": 0.3, "bending_frequency_2": 0.2}])
def test_parameter_columns_are_the_fields(deviations):
    ctx = default_context()
    times = np.arange(0, 3001) * 0.04
    columns = {}
    params = ctx.parameters_at_times(times, deviations, columns=columns)
    for name, column in columns.items():
        field, _, index = name.rpartition("_") if name.startswith("psi_") else (name, "", "")
        values = [getattr(p, field)[int(index)] if index else getattr(p, field) for p in params]
        assert _bits(column) == _bits(values), name
    varying = {f.name for f in dataclasses.fields(params[0])
               if len({getattr(p, f.name) for p in params}) > 1}
    assert varying <= {n.rpartition("_")[0] if n.startswith("psi_") else n for n in columns}
