"""Build script of the ament_python package vega_core (metadata: setup.cfg)."""

from setuptools import setup

setup()
