"""The VEGA vehicle model library: vehicle data, atmosphere, aerodynamics, rigid-body and bending
dynamics, TVC actuator, delays, wind, INS, uncertainty set (plain Python).
"""
