"""Monte Carlo campaigns: dispersed scenarios, one flight per sample, verdicts and reports.

campaign draws a dispersed scenario from the dispersion file (data/dispersions.yaml, every
number with its source), flies it in process and reduces it to one row of metrics and
verdicts; campaign_run runs many of them on a Dask cluster, streams the rows to disk and
writes the summary (docs/MONTE_CARLO.md); compare pairs two campaigns of the same samples flight
by flight (flights lost and won, McNemar's exact p).
"""
