"""Flight side of the VEGA TVC loop: controller tables, scheduler, controller runtime, health
checks.
"""
