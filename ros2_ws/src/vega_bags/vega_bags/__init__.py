"""Run bags: bag I/O, the recorder node, bag check, report, replay, bags from the in-process run."""
