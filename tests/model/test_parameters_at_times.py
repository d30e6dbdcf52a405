"""The array path of the model parameters (``ModelContext.parameters_at_times``, its flight
conditions interpolation, the custom-aerodynamics fallback), ``ModelParameters.scalars`` and
``model_parameters``: each against the scalar path ``ModelContext.parameters`` /
``ModelParameters.perturbed`` (separate code, tests/model/test_uncertainty_perturbation.py
holds it to hand-derived values) or against values read by hand from the objects. Kept fast:
it is in vega_model.parameters' covering set of tools/mutation/targets.toml."""

import dataclasses
import math

import numpy as np
import pytest

from vega_model.aero import Aerodynamics
from vega_model.parameters import (PARAMETER_UNITS, ModelContext, default_context,
                                   model_parameters)

ALL_DEVIATIONS = {"thrust": 0.05, "velocity": 0.02, "density": -0.1, "x_cp": 0.1, "x_cg": 0.01,
                  "mass": -0.03, "jyy": 0.1, "bending_frequency_1": -0.2,
                  "bending_frequency_2": 0.2, "psi_mode_1": 0.3, "psi_mode_2": -0.5,
                  "delay_s": 0.01, "actuator": 0.1}


def _same(p, q):
    assert dataclasses.astuple(dataclasses.replace(p, aero=None)) == \
        dataclasses.astuple(dataclasses.replace(q, aero=None))
    assert repr(p) == repr(q)            # the signs of zeros too


@pytest.mark.slow
@pytest.mark.parametrize("deviations", [{}, ALL_DEVIATIONS])
def test_parameters_at_times_equals_parameters_one_by_one(deviations):
    """Times before, at and after the track's ends and every 10 ms inside."""
    ctx = default_context()
    lo, hi = ctx.time_range_s
    times = np.concatenate([[lo - 1.0, lo, hi, hi + 2.0], np.arange(0, 10999) * 0.01])
    many = ctx.parameters_at_times(times, deviations)
    assert len(many) == times.size
    for t, p in zip(times.tolist(), many):
        q = ctx.parameters(t)
        if any(deviations.values()):
            q = q.perturbed(deviations)
        _same(p, q)


def test_parameters_at_times_takes_any_array_shape_and_refuses_nan():
    ctx = default_context()
    grid = np.array([[12.5, 40.0], [71.25, 99.0]])
    many = ctx.parameters_at_times(grid)
    assert [p.t_s for p in many] == [12.5, 40.0, 71.25, 99.0]
    with pytest.raises(ValueError, match="time is NaN"):
        ctx.parameters_at_times([10.0, math.nan])


class _DelegatingAero:
    """A custom aerodynamic model (not an :class:`Aerodynamics`): the shipped one's numbers
    through delegation, so the fallback path must give the scalar path's objects."""

    def __init__(self, inner):
        self._inner = inner

    def __getattr__(self, name):
        return getattr(self._inner, name)


@pytest.mark.parametrize("deviations", [None, {}, {"velocity": 0.0}, ALL_DEVIATIONS])
def test_a_custom_aerodynamic_model_falls_back_to_the_scalar_path(deviations):
    base = default_context()
    ctx = ModelContext(base.vehicle, base.conditions, aero=_DelegatingAero(base.aero))
    times = [0.0, 33.3, 61.0, 100.0]
    columns = {}
    many = ctx.parameters_at_times(np.array(times), deviations, columns=columns)
    assert columns == {}                          # left empty with a custom model
    assert ctx.parameter_columns_at_times(times, deviations) is None
    assert len(many) == len(times)
    for t, p in zip(times, many):
        assert p.aero is ctx.aero
        q = base.parameters(t)
        if deviations and any(deviations.values()):
            q = q.perturbed(deviations)
        assert p.t_s == t
        _same(p, q)
    if deviations and any(deviations.values()):   # the deviations did act
        assert many[1].thrust_n != base.parameters(33.3).thrust_n


def test_scalars_are_the_fields_named_in_parameter_units():
    p = default_context().parameters(47.0)
    s = p.scalars()
    assert list(s) == list(PARAMETER_UNITS)
    assert s["v_mps"] == p.v_mps and s["q_pa"] == p.q_pa and s["mass_kg"] == p.mass_kg
    assert all(type(v) is float for v in s.values())
    assert len(set(s.values())) > len(s) // 2     # not one value repeated


def test_model_parameters_uses_the_given_context_or_the_default_one():
    base = default_context()
    custom = ModelContext(base.vehicle, base.conditions, aero=_DelegatingAero(base.aero))
    assert isinstance(model_parameters(30.0).aero, Aerodynamics)
    _same(model_parameters(30.0), base.parameters(30.0))
    assert model_parameters(30.0).t_s == 30.0
    got = model_parameters(30.0, custom)
    assert got.aero is custom.aero and got.t_s == 30.0


@pytest.mark.slow
@pytest.mark.parametrize("deviations", [{"velocity": 0.02}, {"x_cg": -0.01, "psi_mode_2": 0.4}])
def test_deviations_naming_a_few_parameters_leave_the_others_nominal(deviations):
    ctx = default_context()
    times = np.arange(0, 1001) * 0.1
    for t, p in zip(times.tolist(), ctx.parameters_at_times(times, deviations)):
        _same(p, ctx.parameters(t).perturbed(deviations))


@pytest.mark.slow
def test_at_the_tables_own_times_and_for_integer_times():
    """Every row time of the flight-conditions table (where the interpolation's interval is
    decided by equality) and times given as Python ints: the scalar path's objects."""
    ctx = default_context()
    rows = ctx.conditions.t_s
    for t, p in zip(rows.tolist(), ctx.parameters_at_times(rows)):
        _same(p, ctx.parameters(t))
    ints = [0, 1, 17, 40, 99, 100]
    for t, p in zip(ints, ctx.parameters_at_times(ints)):
        assert type(p.t_s) is float and type(p.v_mps) is float
        _same(p, ctx.parameters(float(t)))


def _conditions_with_rounding_rows(base):
    """The shipped table with every other row's values multiplied by −3.7: rows where
    a + 1·(b − a) is not b in floating point (in the shipped table it almost always is), so an
    interval chosen one row too early at a row time shows in the last bits."""
    from vega_model.flight_conditions import COLUMNS, FlightConditions

    data = np.column_stack([base.column(name) for name in COLUMNS])
    factors = np.where(np.arange(data.shape[0]) % 2 == 0, 1.0, -3.7)
    data = data.copy()
    data[:, 1:] *= factors[:, None]
    return FlightConditions(base.path, COLUMNS, data, base.provenance)


@pytest.mark.slow
def test_row_times_of_a_table_whose_interpolation_rounds():
    base = default_context()
    ctx = ModelContext(base.vehicle, _conditions_with_rounding_rows(base.conditions))
    v = ctx.conditions.column("v_mps")
    assert sum(a + 1.0 * (b - a) != b for a, b in zip(v[:-1], v[1:])) > 100
    rows = ctx.conditions.t_s
    for t, p in zip(rows.tolist(), ctx.parameters_at_times(rows)):
        _same(p, ctx.parameters(t))


def test_bending_data_interpolated_over_a_window_not_starting_at_lift_off():
    """Vehicle data whose bending window is 20–80 s (the shipped one starts at 0 s, where
    t − t_start and t + t_start agree): the array path still equals the scalar path."""
    import dataclasses as dc

    base = default_context()
    vehicle = dc.replace(base.vehicle, values={**base.vehicle.values,
                                               "bending.t_start_s": 20.0,
                                               "bending.t_end_s": 80.0})
    ctx = ModelContext(vehicle, base.conditions)
    times = np.array([0.0, 19.99, 20.0, 35.5, 50.0, 79.9, 80.0, 95.0])
    many = ctx.parameters_at_times(times)
    for t, p in zip(times.tolist(), many):
        _same(p, ctx.parameters(t))
    assert many[0].f1_hz == many[2].f1_hz != many[4].f1_hz != many[6].f1_hz == many[7].f1_hz


@pytest.mark.parametrize("deviations", [{}, ALL_DEVIATIONS])
def test_columns_are_the_fields_and_rebuild_the_objects(deviations):
    """``columns`` of parameters_at_times: each the field of every returned object (the
    mode-shape pairs as _0/_1); parameter_columns_at_times gives the same columns without the
    objects; parameters_from_columns rebuilds each object (equal, field by field)."""
    ctx = default_context()
    times = np.arange(0, 2001) * 0.05
    columns = {}
    params = ctx.parameters_at_times(times, deviations, columns=columns)
    assert len(columns) >= 20
    for name, column in columns.items():
        assert column.dtype == np.float64 and column.shape == times.shape
        field, _, index = name.rpartition("_") if name.startswith("psi_") else (name, "", "")
        values = [getattr(p, field)[int(index)] if index else getattr(p, field)
                  for p in params]
        assert column.tolist() == values, name
    varying = {f.name for f in dataclasses.fields(params[0])
               if len({getattr(p, f.name) for p in params}) > 1}
    assert varying <= {n.rpartition("_")[0] if n.startswith("psi_") else n for n in columns}
    only = ctx.parameter_columns_at_times(times, deviations)
    assert sorted(only) == sorted(columns)
    assert all(only[n].tolist() == columns[n].tolist() for n in columns)
    for k in (0, 700, 2000):
        _same(ctx.parameters_from_columns(only, k), params[k])
