"""The structured gain-scheduled design that flies (docs/FLIGHT_DESIGN.md).

structured tunes a fixed-structure controller per grid point against dispersed design sets and
exports the table; corner_repair applies the single-parameter repairs of the bending criterion
at the dispersed corners; task_journal records finished tuning tasks so that an interrupted
``vega design`` resumes.
"""
