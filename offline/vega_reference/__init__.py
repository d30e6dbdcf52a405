"""The reference flight: the ascent trajectory and the guidance reference.

trajectory simulates the 3-DOF pitch-plane ascent that gives the flight-condition table the
plant and the controller schedule on (docs/TRAJECTORY.md); guidance computes the wind-biased
attitude reference the controller follows (docs/GUIDANCE.md).
"""
