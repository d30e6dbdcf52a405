"""Build script of the ament_python package vega_sim (metadata: setup.cfg)."""

from setuptools import setup

setup()
