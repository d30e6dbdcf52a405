"""Build script of the ament_python package vega_cli (metadata: setup.cfg)."""

from setuptools import setup

setup()
