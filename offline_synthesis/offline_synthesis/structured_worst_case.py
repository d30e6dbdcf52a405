"""`vega robust`'s worst-case bending verdict for step 6 of the structured design.

:func:`offline_synthesis.structured.scale_drift` refuses a drift-rate scaling that makes the
worst case of `vega robust` miss the exact bending criterion between two grid points; it takes
the check as an argument because :mod:`offline_synthesis.robust` imports
:mod:`offline_synthesis.structured` (the package's modules import no cycle). Pass
:func:`worst_case_bending_ok`: ``scale_drift(..., worst_case=worst_case_bending_ok)``,
``rescale_drift(...)`` and ``design_flight(..., drift_worst_case=...)`` likewise.
"""

from __future__ import annotations

__all__ = ["worst_case_bending_ok"]


def worst_case_bending_ok(table, context, t_s: float) -> bool:
    """`vega robust`'s bending verdict at ``t_s`` (:func:`.robust.analyse_time`, seed 0, no μ):
    the plant of smallest disk margin found over the uncertainty set meets the exact bending
    criterion of both modes (≤ −6 dB, or 6 dB / 30° at every in-band crossover)."""
    from offline_synthesis.robust import analyse_time

    row = analyse_time(table, context, float(t_s), mu=False)
    return bool(row["worst_bending_1_ok"] and row["worst_bending_2_ok"])
