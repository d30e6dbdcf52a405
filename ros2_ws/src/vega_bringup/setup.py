"""Build script of the ament_python package vega_bringup (metadata: setup.cfg)."""

from setuptools import setup

setup()
