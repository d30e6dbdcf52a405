"""Build script of the ament_python package vega_plant (metadata: setup.cfg)."""

from setuptools import setup

setup()
