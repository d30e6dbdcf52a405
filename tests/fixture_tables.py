"""Controller tables for tests and benchmarks until the synthesised table exists (one place).

* :func:`write_pd_table` — a hand-designed scheduled PD (not the LPV synthesis): at each
  design time, from the linear model's rigid rows θ̈ ≈ a θ − b β and z̈ ≈ −g θ,
  β = K_p(θ − θ_ref) + K_d θ̇ with K_p = (ω² + a)/b, K_d = 2ζω/b (ω = 2.5 rad/s, ζ = 0.7) and
  a slow drift loop θ_ref = −(ω_z² z + 2ζ_z ω_z ż)/g (ω_z = 0.15 rad/s, ζ_z = 0.8), rolled off
  by a second-order low-pass at 10 rad/s (bending mode 1 is at 30–37 rad/s), exported
  through :func:`vega_loops.export.write_controller_table` like the real table.
* :func:`write_gain_table` — a static gain β_cmd = 0.5·θ_INS (a first-order state that never
  feeds the output), for latency tests.

Both write the ``.npz`` at the given path and return the table as the flight software loads it
(:class:`vega_gnc.controller_table.ControllerTable`); 50 Hz (dt = 0.02 s).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from vega_gnc.controller_table import ControllerTable

__all__ = ["DESIGN_TIMES", "STRUCTURED_2026_11_27", "write_pd_table", "write_gain_table"]

STRUCTURED_2026_11_27 = Path(__file__).resolve().parent / "data" / "tvc_controller_2026-11-27.npz"
"""A frozen copy of the structured table shipped from 2026-11-27 (sixth session; commit
019a54c): the real cases the design tools are tested on — its tuning record's hand edits (43 s),
its drift step, its 44/46 s points around max-Q, its tail-off — stay what the tests say when the
shipped table (vega_gnc/config/tvc_controller.npz) is replaced by a newer design."""

DESIGN_TIMES = (2, 5, 10, 20, 30, 40, 50, 60, 70, 80, 90, 92, 94, 96, 98, 100)
"""Flight times [s] whose velocities are the PD table's scheduling grid."""

_NAMES = ["theta_ins_rad", "theta_dot_ins_radps", "z_ins_m", "z_dot_ins_mps"]
_META = {"input_names": _NAMES, "measurement_sign": 1, "output_name": "beta_cmd_rad",
         "units": {"beta_cmd_rad": "rad"}, "weights": {}, "solver": {"name": "test fixture"}}


def _export(path, grid, A, B, C, D) -> "ControllerTable":
    from vega_loops.export import write_controller_table

    return write_controller_table(path, grid, np.array(A), np.array(B), np.array(C),
                                  np.array(D), dt_s=0.02, gamma=1.0, gamma_min=1.0,
                                  rate_bounds_mps2=[5.4, 36.4], metadata=_META)


def write_pd_table(path: str | Path) -> "ControllerTable":
    """Write the scheduled PD controller table (module docstring) to ``path``."""
    from vega_model.dynamics import linear_model
    from vega_model.parameters import default_context

    ctx = default_context()
    wn, zeta, wz, zz, wf, zf = 2.5, 0.7, 0.15, 0.8, 10.0, 0.7
    grid, A, B, C, D = [], [], [], [], []
    for t in DESIGN_TIMES:
        p = ctx.parameters(t)
        a, b, _, _ = linear_model(p)
        a_theta, b_theta, g_z = a[1, 0], -b[1, 0], -a[3, 0]
        kp = (wn ** 2 + a_theta) / b_theta
        kd = 2.0 * zeta * wn / b_theta
        gain = np.array([[kp, kd, -kp * wz ** 2 / g_z, -kp * 2.0 * zz * wz / g_z]])
        grid.append(p.v_mps)
        A.append([[0.0, 1.0], [-wf ** 2, -2.0 * zf * wf]])
        B.append(np.vstack([np.zeros((1, 4)), wf ** 2 * gain]))
        C.append([[1.0, 0.0]])
        D.append([[0.0, 0.0, 0.0, 0.0]])
    return _export(path, grid, A, B, C, D)


def write_gain_table(path: str | Path) -> "ControllerTable":
    """Write the static-gain table β_cmd = 0.5·θ_INS to ``path``."""
    A = [[[-1.0]], [[-1.0]]]
    B = [[[0.0, 0.0, 0.0, 0.0]]] * 2
    C = [[[0.0]]] * 2
    D = [[[0.5, 0.0, 0.0, 0.0]]] * 2
    return _export(path, [0.0, 3000.0], A, B, C, D)
