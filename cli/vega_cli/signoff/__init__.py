"""The sign-off of a controller table: what a new design must pass before it replaces the flown
one (docs/FLIGHT_DESIGN.md §6.5, "How a design is signed off").

* :mod:`.record` — the sign-off record (``verify.json``): its checks and scenarios, the SHA-256
  that ties it to the table's bytes, and the rule a record must meet to ship a table;
* :mod:`.verify` — runs the checks (``vega verify``) and writes the record;
* :mod:`.ship` — installs a table with a complete, passed record of its own bytes
  (``vega ship``).
"""
