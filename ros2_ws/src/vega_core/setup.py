"""Build script of the ament_python package vega_core (layout of ``ros2 pkg create``).

Executables go to ``lib/vega_core`` (setup.cfg), where ``ros2 run vega_core EXE`` and
``vega node vega_core EXE`` find them.
"""
from glob import glob

from setuptools import find_packages, setup

package_name = 'vega_core'

data_files = [
    ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
    ('share/' + package_name, ['package.xml']),
]
config_files = sorted(path for path in glob('config/*') if not path.endswith('~'))
if config_files:
    data_files.append(('share/' + package_name + '/config', config_files))

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    package_data={package_name: []},
    data_files=data_files,
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='VEGA TVC maintainers',
    maintainer_email='maintainers@vega-tvc.invalid',
    description='Foundation of every VEGA TVC package: the bad-input error core, document loading and units (plain Python, no ROS).',
    license='Apache-2.0',
    entry_points={'console_scripts': []},
)
