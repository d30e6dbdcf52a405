"""The vega command line: the one package that imports every layer."""
