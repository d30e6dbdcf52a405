"""The flight-day sign-off: a campaign flown in a launch site's statistical winds with the
guidance re-biased per sample to its sounding (:mod:`vega_signoff.flight_day`) and a launch
commit criterion judged on the sounding before each sample flies (:mod:`vega_signoff.lcc`).

It sits above :mod:`vega_campaign` (the Monte Carlo runner, the dispersions, the wind
environment) and :mod:`vega_reference` (the re-biasing), which never import each other.
"""
