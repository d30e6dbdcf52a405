"""Robustness analysis of a controller table beyond the classical margins.

robust (worst case over the uncertainty set, destabilising scale) and mu_analysis (structured
singular value bounds), time_margins (gain and delay margins of the nonlinear closed loop in
the time domain), and the plots of these and of the margins sweep (docs/ROBUST_ANALYSIS.md).
"""
