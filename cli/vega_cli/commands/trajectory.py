"""``vega trajectory``: simulate the reference ascent and write the flight-condition table.

``vega trajectory --out FILE.csv`` runs the 3-DOF ascent of ``vega_reference.trajectory``
(0-110 s, 0.1 s rows, docs/TRAJECTORY.md) and writes the versioned table with its provenance
header. The product reads the committed copy, ``vega_model/data/flight_conditions.csv``;
regenerate it with ``--out ros2_ws/src/vega_model/vega_model/data/flight_conditions.csv``.
"""

from __future__ import annotations

import argparse

__all__ = ["register", "summary"]


def summary(path: str, columns) -> str:
    """One line: rows written, max-Q value, time and Mach, final velocity.

    Parameters
    ----------
    path : str
        The file written.
    columns : mapping of str to numpy.ndarray
        The table's columns (``t_s``, ``q_pa``, ``mach``, ``v_mps`` are used).
    """
    t, q = columns["t_s"], columns["q_pa"]
    i = int(q.argmax())
    return (f"wrote {t.size} rows ({t[0]:g}-{t[-1]:g} s) to {path}: "
            f"max-Q {q[i] / 1e3:.2f} kPa at t = {t[i]:.1f} s (M {columns['mach'][i]:.2f}), "
            f"v({t[-1]:g} s) = {columns['v_mps'][-1]:.1f} m/s")


def _run(args: argparse.Namespace) -> int:
    from vega_reference.trajectory import write_flight_conditions

    columns = write_flight_conditions(args.out, vehicle_path=args.vehicle)
    print(summary(args.out, columns))
    return 0


def register(subparsers) -> None:
    """Add the ``trajectory`` sub-command."""
    p = subparsers.add_parser(
        "trajectory", help="simulate the reference ascent, write the flight-condition table",
        description="Pitch-plane 3-DOF ascent of the VEGA first stage (0-110 s): vertical "
                    "rise, pitch-over kick, zero-lift gravity turn; writes the flight "
                    "conditions every 0.1 s as a versioned CSV with a provenance header.")
    p.add_argument("--out", required=True, metavar="FILE.csv", help="output CSV file")
    p.add_argument("--vehicle", metavar="VEHICLE.yaml", default=None,
                   help="vehicle data file (default: the one shipped with vega_plant)")
    p.set_defaults(func=_run)
