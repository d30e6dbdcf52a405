"""Build script of the ament_python package vega_cli (layout of ``ros2 pkg create``).

Executables go to ``lib/vega_cli`` (setup.cfg), where ``ros2 run vega_cli EXE`` and
``vega node vega_cli EXE`` find them.
"""
from glob import glob

from setuptools import find_packages, setup

package_name = 'vega_cli'

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
    description='The vega command line of the VEGA TVC stack (the one package that imports every layer, offline_synthesis included).',
    license='Apache-2.0',
    entry_points={'console_scripts': []},
)
