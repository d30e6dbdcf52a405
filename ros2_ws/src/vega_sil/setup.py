"""Build script of the ament_python package vega_sil (layout of ``ros2 pkg create``).

Executables go to ``lib/vega_sil`` (see setup.cfg) so that ``ros2 run vega_sil EXE`` and
``vega node vega_sil EXE`` find them; files under ``vega_sil/data/`` and the requirement file
``vega_sil/config/*.yaml`` ship inside the Python package;
``package.xml`` and ``config/*`` (if present) are installed to ``share/vega_sil``.
"""
from glob import glob

from setuptools import find_packages, setup

package_name = 'vega_sil'

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
    package_data={package_name: ['data/*', 'config/*.yaml']},
    data_files=data_files,
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='VEGA TVC maintainers',
    maintainer_email='maintainers@vega-tvc.invalid',
    description=(
        'Bring-up and tools of the VEGA TVC software-in-the-loop: the vega command line, run '
        'orchestration, recording, bag checks, replay and reports.'
    ),
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'recorder = vega_sil.recorder:main',
        ],
    },
)
