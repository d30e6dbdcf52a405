"""Build script of the ament_python package vega_bus (layout of ``ros2 pkg create``).

A library package (no executables): the topic contract every VEGA TVC node shares.
"""
from setuptools import find_packages, setup

package_name = 'vega_bus'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='VEGA TVC maintainers',
    maintainer_email='maintainers@vega-tvc.invalid',
    description=(
        'The VEGA TVC node graph contract: topic names, message types, QoS profiles, stamp '
        'conversion and the lockstep start barrier.'
    ),
    license='Apache-2.0',
    entry_points={'console_scripts': []},
)
