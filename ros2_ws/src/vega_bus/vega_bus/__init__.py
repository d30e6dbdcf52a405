"""The contract of the VEGA TVC node graph, shared by vega_plant, vega_gnc and vega_sil."""
