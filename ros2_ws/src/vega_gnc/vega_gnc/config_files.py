"""The versioned ``.npz`` files the flight side trusts (controller table, guidance reference):
reading, the common header checks, and the installed copies.

Every problem is one line naming the file (the caller's :class:`vega_core.errors.BadFile`
subclass): unreadable, not an npz, a missing key, an unsupported ``format_version``, a
``metadata`` entry that is not a JSON object or lacks a required key, a non-numeric or
non-finite array.
"""

from __future__ import annotations

import json
import zipfile
from pathlib import Path
from typing import Any, Iterable, Mapping

import numpy as np

from vega_core.documents import refuse_pipe
from vega_core.errors import BadFile, BadInput

__all__ = ["read_npz", "check_header", "numeric_arrays", "installed_config"]


def read_npz(path: str, error: type[BadFile], what: str) -> dict[str, np.ndarray]:
    """Every array of the ``.npz`` file ``path`` (no pickles); ``what`` names the kind of file
    in the error (e.g. "controller table"). A FIFO or socket is refused before it is opened
    (:func:`vega_core.documents.refuse_pipe`: opening a FIFO would block)."""
    refuse_pipe(path, what, error)
    try:
        with np.load(path, allow_pickle=False) as npz:
            return {key: npz[key] for key in npz.files}
    except FileNotFoundError:
        raise error(f"{path}: no such file") from None
    except (OSError, ValueError, zipfile.BadZipFile, EOFError) as exc:
        raise error(f"{path}: not a readable {what} ({type(exc).__name__})") from None


def check_header(path: str, arrays: Mapping[str, np.ndarray], keys: Iterable[str],
                 version: int, metadata_keys: Iterable[str],
                 error: type[BadFile]) -> dict[str, Any]:
    """Check that ``keys`` are present, ``format_version`` is ``version`` and ``metadata`` is a
    JSON object with ``metadata_keys``; return the metadata."""
    for key in keys:
        if key not in arrays:
            raise error(f"{path}: missing key '{key}'")
    try:
        found = int(np.asarray(arrays["format_version"]).item())
    except (TypeError, ValueError):
        raise error(f"{path}: 'format_version' is not an integer") from None
    if found != version:
        raise error(f"{path}: format_version {found} is not supported (expected {version})")
    try:
        meta = json.loads(str(np.asarray(arrays["metadata"]).item()))
    except (TypeError, ValueError):
        raise error(f"{path}: 'metadata' is not a JSON string") from None
    if not isinstance(meta, dict):
        raise error(f"{path}: 'metadata' must be a JSON object")
    for key in metadata_keys:
        if key not in meta:
            raise error(f"{path}: metadata lacks '{key}'")
    return meta


def numeric_arrays(path: str, arrays: Mapping[str, np.ndarray], keys: Iterable[str],
                   error: type[BadFile]) -> dict[str, np.ndarray]:
    """``keys`` as read-only float arrays, each numeric and finite."""
    out = {}
    for key in keys:
        arr = np.asarray(arrays[key])
        if arr.dtype.kind not in "iuf":
            raise error(f"{path}: '{key}' is not numeric")
        arr = arr.astype(float)
        if not np.all(np.isfinite(arr)):
            raise error(f"{path}: '{key}' has non-finite values")
        arr.setflags(write=False)
        out[key] = arr
    return out


def installed_config(name: str) -> Path:
    """``share/vega_gnc/config/<name>`` of the installed package.

    Raises
    ------
    BadInput
        If the package ``vega_gnc`` is not in the ament index (workspace not built).
    """
    from ament_index_python.packages import PackageNotFoundError, get_package_share_directory

    try:
        return Path(get_package_share_directory("vega_gnc")) / "config" / name
    except PackageNotFoundError:
        raise BadInput("package 'vega_gnc' not found in the ament index; did 'make setup' "
                       "build it?") from None
