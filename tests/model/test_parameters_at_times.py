"""The array path of the model parameters (``ModelContext.parameters_at_times``, its flight
conditions interpolation, the custom-aerodynamics fallback), ``ModelParameters.scalars`` and
``model_parameters``: each against the scalar path ``ModelContext.parameters`` /
``ModelParameters.perturbed`` (separate code, tests/model/test_uncertainty_perturbation.py
holds it to hand-derived values) or against values read by hand from the objects. Fast: this
is the covering set of vega_model.parameters' mutation run (tools/mutation/targets.toml)."""

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
