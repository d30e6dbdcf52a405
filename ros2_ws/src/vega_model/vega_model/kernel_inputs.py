"""The plant's inputs to the compiled kernel (:func:`vega_model.nonlinear_kernel.rk4_frame`):
the per-parameter-set constants and the Mach tables, built in plain Python.

Kept apart from the kernel's module so that a process that runs the ahead-of-time compiled
kernel (:mod:`vega_model.kernels`) does not import numba to build them.
"""

from __future__ import annotations

import numpy as np

from vega_model.parameters import ModelParameters

__all__ = ["CONSTANTS", "entry_constants", "MachTables", "mach_tables"]

CONSTANTS = ("v", "a", "s_ref", "half_rho", "d", "T", "m", "J", "lc", "tp0", "tp1", "rp0",
             "rp1", "neg_mn_ln", "neg_t", "lc_t", "jn", "jn_rp0", "jn_rp1", "mode1_q",
             "mode1_qd", "mode2_q", "mode2_qd", "k_cf")
"""Columns of :func:`entry_constants`: the per-parameter-set products of
:class:`vega_model.dynamics.NonlinearModel` (same names)."""


def entry_constants(p: ModelParameters) -> tuple[float, ...]:
    """The model constants of one parameter set, in :data:`CONSTANTS` order, formed with the
    operations :class:`vega_model.dynamics.NonlinearModel` uses."""
    T, m, J = p.thrust_n, p.mass_kg, p.jyy_kgm2
    lc, d = p.l_cg_pvp_m, p.l_cp_m
    mn, ln, jn = p.nozzle_mass_kg, p.nozzle_lever_m, p.nozzle_inertia_kgm2
    tp0, tp1 = p.psi_t_pvp
    rp0, rp1 = p.psi_r_pvp
    w1, w2 = p.omega_radps
    return (p.v_mps, p.sound_speed_mps, p.s_ref_m2, 0.5 * p.rho_kgpm3, d, T, m, J, lc,
            tp0, tp1, rp0, rp1, -mn * ln, -T, lc * T, jn, jn * rp0, jn * rp1,
            -w1 * w1, 2.0 * p.zeta * w1, -w2 * w2, 2.0 * p.zeta * w2,
            p.aero.crossflow_coefficient)


class MachTables(tuple):
    """(C_Nα breakpoints, values, slopes, C_A breakpoints, values, slopes) as float arrays."""


def mach_tables(p: ModelParameters) -> MachTables:
    """The aerodynamic Mach tables of ``p`` as the kernel reads them (the breakpoints, values
    and slopes of :meth:`vega_model.aero.Aerodynamics.scalar_tables`)."""
    out = []
    for table in p.aero.scalar_tables():
        # the table's own floats (ScalarTable's slots): the same breakpoints and slopes
        x, y, slopes = table._x, table._y, table._slopes
        out += [np.array(x, dtype=float), np.array(y, dtype=float),
                np.array(slopes if slopes else [0.0], dtype=float)]
    return MachTables(out)
