"""vega_sil: bring-up and tools of the VEGA TVC software-in-the-loop (the ``vega`` command)."""
