"""Bring-up of SIL runs: run planning, the node supervisor (orchestrator), the ROS environment
rules, executable lookup.
"""
