"""The in-process simulation: scenarios, the loop's step classes, the closed loop and the
requirements (plain Python).
"""
