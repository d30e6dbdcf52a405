"""Finding a ROS 2 package's executable the way ``ros2 run`` does (the ament index).

``ros2 run PKG EXE`` looks the package's install prefix up in the ament index and executes
``<prefix>/lib/PKG/EXE``; :func:`find_executable` does the same lookup, so the packages keep
the layout a full ROS 2 install expects.
"""

import os

from vega_core.errors import BadArgument

__all__ = ["find_executable"]


def find_executable(package, executable):
    """Return the path of executable ``executable`` of ROS 2 package ``package``.

    Parameters
    ----------
    package : str
        Package name, looked up in the ament index.
    executable : str
        Name of a file in ``<prefix>/lib/<package>``.

    Returns
    -------
    str
        ``<prefix>/lib/<package>/<executable>``.

    Raises
    ------
    BadArgument
        One line: the package is not in the ament index, or has no such executable (the
        message lists the ones it has).
    """
    from ament_index_python.packages import PackageNotFoundError, get_package_prefix

    try:
        prefix = get_package_prefix(package)
    except PackageNotFoundError:
        raise BadArgument(
            f"package {package!r} not found in the ament index "
            f"(AMENT_PREFIX_PATH={os.environ.get('AMENT_PREFIX_PATH', '')}); "
            f"did 'make setup' build it?") from None
    directory = os.path.join(prefix, "lib", package)
    path = os.path.join(directory, executable)
    if os.sep in executable or not (os.path.isfile(path) and os.access(path, os.X_OK)):
        try:
            available = sorted(
                name for name in os.listdir(directory)
                if os.access(os.path.join(directory, name), os.X_OK)
                and os.path.isfile(os.path.join(directory, name)))
        except OSError:
            available = []
        raise BadArgument(
            f"no executable {executable!r} in package {package!r} "
            f"(available: {', '.join(available) or 'none'})")
    return path
