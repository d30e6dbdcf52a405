"""Build script of the ament_python package vega_bus (metadata: setup.cfg)."""

from setuptools import setup

setup()
