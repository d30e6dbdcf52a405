"""``vega node PKG EXE [ARGS...]``: start a ROS 2 executable, like ``ros2 run PKG EXE``.

``ros2 run`` looks the package's install prefix up in the ament index and executes
``<prefix>/lib/PKG/EXE``; this does the same with the same index (``AMENT_PREFIX_PATH``), so the
packages keep the layout a full ROS 2 install expects, where the ``ros2`` command line (absent
from the PyPI wheels) works on them unchanged. The executable replaces this process (``exec``)
with the project's ROS environment (:mod:`vega_bringup.rosenv`); everything after EXE, such as
``--ros-args --params-file FILE``, is passed to it as is.
"""

import argparse
import os
import sys

from vega_bringup import rosenv
from vega_bringup.executables import find_executable

__all__ = ["register"]


def _run(args):
    """Replace this process by the executable, in the project's ROS environment."""
    path = find_executable(args.package, args.executable)
    if args.ros_domain_id_picked:
        env = rosenv.ros_environment(domain_id=rosenv.HAND_START_DOMAIN_ID)
        print(f"vega node: ROS_DOMAIN_ID={env['ROS_DOMAIN_ID']} (the default for nodes started "
              f"by hand; export ROS_DOMAIN_ID=N, 1..101, in every terminal to choose another)",
              file=sys.stderr)
    else:
        env = rosenv.ros_environment()
    sys.stdout.flush()
    sys.stderr.flush()
    os.execve(path, [path, *args.arguments], env)


def register(subparsers):
    """Add the ``node`` sub-command."""
    parser = subparsers.add_parser(
        "node", help="start a ROS 2 executable (the equivalent of 'ros2 run')",
        description="Start executable EXE of ROS 2 package PKG, found through the ament index "
                    "like 'ros2 run PKG EXE', with the project's ROS environment (LOCALHOST "
                    "discovery; ROS_DOMAIN_ID from the caller, else 101, the same for every "
                    "node started by hand, so that nodes in separate terminals meet).")
    parser.add_argument("package", metavar="PKG", help="ROS 2 package name")
    parser.add_argument("executable", metavar="EXE", help="executable of the package")
    parser.add_argument("arguments", nargs=argparse.REMAINDER, metavar="ARGS",
                        help="passed to the executable, e.g. --ros-args --params-file FILE")
    parser.set_defaults(func=_run)
