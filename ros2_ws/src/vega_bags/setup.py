"""Build script of the ament_python package vega_bags (metadata: setup.cfg)."""

from setuptools import setup

setup()
