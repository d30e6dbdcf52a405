"""Build script of the ament_python package vega_gnc (metadata: setup.cfg)."""

from setuptools import setup

setup()
