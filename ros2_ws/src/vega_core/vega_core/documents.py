"""Reading the project's data documents with one-line errors (the loaders' shared first steps).

Every loader of a text document — vehicle data, flight conditions, scenarios, requirements —
reads its file with :func:`read_text` and, for YAML, parses it with :func:`parse_yaml`
(:func:`load_yaml` does both), so that a missing, unreadable or malformed file is reported
the same way everywhere: one line naming the file, as :class:`vega_core.errors.BadFile` (or
the loader's own subclass of it, passed as ``error``), never a traceback chain.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from vega_core.errors import BadFile

__all__ = ["read_text", "parse_yaml", "load_yaml"]


def read_text(path: str | Path, what: str, error: type[Exception] = BadFile) -> str:
    """Contents of the UTF-8 file ``path``.

    Parameters
    ----------
    path
        The file.
    what
        What the file holds, for the message (``"scenario"``, ``"vehicle data"``, …).
    error
        Exception class raised (default :class:`~vega_core.errors.BadFile`).

    Raises
    ------
    error
        ``"<path>: cannot read <what> (<reason>)"`` if the file is missing, unreadable or not
        UTF-8 — one line, no traceback chain.
    """
    try:
        return Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        reason = getattr(exc, "strerror", None) or type(exc).__name__
        raise error(f"{path}: cannot read {what} ({reason})") from None


def parse_yaml(text: str, source: str, error: type[Exception] = BadFile) -> dict[str, Any]:
    """The YAML document ``text``, whose top level must be a mapping.

    Parameters
    ----------
    text
        YAML text.
    source
        Where the text comes from, for the message (the file path).
    error
        Exception class raised (default :class:`~vega_core.errors.BadFile`).

    Raises
    ------
    error
        ``"<source>: not valid YAML (line <n>)"`` (the line when the parser knows it) or
        ``"<source>: top level must be a mapping"``.
    """
    import yaml

    try:
        tree = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        line = f" (line {mark.line + 1})" if mark is not None else ""
        raise error(f"{source}: not valid YAML{line}") from None
    if not isinstance(tree, dict):
        raise error(f"{source}: top level must be a mapping")
    return tree


def load_yaml(path: str | Path, what: str, error: type[Exception] = BadFile) -> dict[str, Any]:
    """:func:`read_text` then :func:`parse_yaml` (``source`` = the path): the mapping of the
    YAML file ``path``, or ``error`` with one of their one-line messages."""
    return parse_yaml(read_text(path, what, error), str(path), error)
