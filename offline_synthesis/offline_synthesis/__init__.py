"""Offline half of the VEGA TVC stack: trajectory, linearised plant grid, LPV synthesis,
verification.
"""
