"""Build script of the ament_python package vega_model (metadata: setup.cfg)."""

from setuptools import setup

setup()
