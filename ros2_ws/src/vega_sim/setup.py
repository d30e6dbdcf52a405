"""Build script of the ament_python package vega_sim (layout of ``ros2 pkg create``).

Executables go to ``lib/vega_sim`` (setup.cfg), where ``ros2 run vega_sim EXE`` and
``vega node vega_sim EXE`` find them.
"""
from glob import glob

from setuptools import find_packages, setup

package_name = 'vega_sim'

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
    package_data={package_name: ['config/*.yaml', 'scenarios/*.yaml']},
    data_files=data_files,
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='VEGA TVC maintainers',
    maintainer_email='maintainers@vega-tvc.invalid',
    description='The in-process VEGA TVC simulation (plain Python): scenarios, the plant, INS and actuator step classes, the closed loop, and the requirements with their configuration.',
    license='Apache-2.0',
    entry_points={'console_scripts': []},
)
