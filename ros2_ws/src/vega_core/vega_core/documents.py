"""Reading the project's data documents with one-line errors (the loaders' shared first steps).

Every loader of a text document — vehicle data, flight conditions, scenarios, requirements —
reads its file with :func:`read_text` and, for YAML, parses it with :func:`parse_yaml`
(:func:`load_yaml` does both), so that a missing, unreadable or malformed file is reported
the same way everywhere: one line naming the file, as :class:`vega_core.errors.BadFile` (or
the loader's own subclass of it, passed as ``error``), never a traceback chain.

Size limit: :func:`read_text` refuses a file larger than :data:`MAX_DOCUMENT_BYTES` (1 MiB;
a loader may pass its own ``max_bytes``) and reads at most that many bytes plus one, so a
wrong path (``--scenario /dev/zero``, a multi-gigabyte log) is refused at once instead of
hanging or filling the memory. 1 MiB is far above any legitimate document: a scenario or a
requirements file is under 2 kB, the vehicle data ~14 kB, and the largest, the generated
flight-condition table (0.1 s rows over 110 s), ~270 kB.
"""

from __future__ import annotations

import math
import os
import stat
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from vega_core.errors import BadFile

__all__ = ["MAX_DOCUMENT_BYTES", "read_text", "parse_yaml", "load_yaml", "refuse_pipe",
           "field_error", "mapping_keys", "finite_number"]

MAX_DOCUMENT_BYTES = 1 << 20
"""Largest document :func:`read_text` accepts by default [bytes] (1 MiB; module docstring)."""


def refuse_pipe(path: str | Path, what: str, error: type[Exception] = BadFile) -> None:
    """Refuse a FIFO or a socket as an input file, before it is opened: opening a FIFO blocks
    until some other process writes to it, so ``--scenario FIFO`` would hang with no word.
    (Missing files and other problems are left to the reader's own one-line errors.)

    Raises
    ------
    error
        ``"<path>: cannot read <what> (a FIFO or socket, not a regular file)"``.
    """
    try:
        mode = os.stat(path).st_mode
    except (OSError, ValueError):
        return
    if stat.S_ISFIFO(mode) or stat.S_ISSOCK(mode):
        raise error(f"{path}: cannot read {what} (a FIFO or socket, not a regular file)")


def read_text(path: str | Path, what: str, error: type[Exception] = BadFile,
              max_bytes: int = MAX_DOCUMENT_BYTES) -> str:
    """Contents of the UTF-8 file ``path`` (newlines normalised as in text mode).

    Parameters
    ----------
    path
        The file.
    what
        What the file holds, for the message (``"scenario"``, ``"vehicle data"``, …).
    error
        Exception class raised (default :class:`~vega_core.errors.BadFile`).
    max_bytes
        Size limit [bytes] (default :data:`MAX_DOCUMENT_BYTES`); at most ``max_bytes + 1``
        bytes are read, whatever the file (a device such as ``/dev/zero`` reports size 0).

    Raises
    ------
    error
        ``"<path>: cannot read <what> (<reason>)"`` if the file is missing, unreadable or not
        UTF-8, ``"<path>: <what> file is <n> bytes, over the <limit> limit"`` if it is too
        large — one line, no traceback chain.
    """
    limit = _size_text(max_bytes)
    refuse_pipe(path, what, error)
    try:
        with open(path, "rb") as stream:
            size = os.fstat(stream.fileno()).st_size
            if size > max_bytes:
                raise error(f"{path}: {what} file is {size} bytes, over the {limit} limit")
            data = stream.read(max_bytes + 1)
        if len(data) > max_bytes:
            raise error(f"{path}: {what} file is over the {limit} limit (more than "
                        f"{max_bytes} bytes read)")
        text = data.decode("utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        reason = getattr(exc, "strerror", None) or type(exc).__name__
        raise error(f"{path}: cannot read {what} ({reason})") from None
    return text.replace("\r\n", "\n").replace("\r", "\n")


def _size_text(n: int) -> str:
    """``n`` bytes as a limit in words: ``1 MiB (1048576 bytes)``."""
    for unit, size in (("GiB", 1 << 30), ("MiB", 1 << 20), ("KiB", 1 << 10)):
        if n >= size and n % size == 0:
            return f"{n // size} {unit} ({n} bytes)"
    return f"{n} bytes"


C_PARSER_MAX_CHARS = 16_384
"""Longest text [characters] parsed by libyaml (PyYAML's ``CSafeLoader``, ≈ 8× faster than its
pure-Python ``SafeLoader``: 20 → 2.5 ms for the 14 kB vehicle data, which every node reads at
start-up). libyaml's composer recurses in C once per nesting level and crashed the interpreter
(segmentation fault) at 50 000 levels of ``[`` (measured with PyYAML 6.0.3; 20 000 parsed),
where the pure-Python loader raises RecursionError (→ "nested too deeply"). A level takes at
least one character (``[``, or ``- `` in a compact sequence), so a text of at most this length
nests at most 16 384 levels: parsed in C (checked at that depth for ``[``, ``- `` and ``{a:``,
in the main thread and in a thread); longer texts go to the pure-Python loader. Both build the
document with the same SafeConstructor (tests/core/test_documents.py: equal trees for every
YAML file of the project)."""


def _loader(yaml, text: str):
    """PyYAML's safe loader for ``text``: libyaml's when it is there and the text is short."""
    c_loader = getattr(yaml, "CSafeLoader", None)
    if c_loader is not None and len(text) <= C_PARSER_MAX_CHARS:
        return c_loader
    return yaml.SafeLoader


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
        ``"<source>: not valid YAML (line <n>)"`` (the line when the parser knows it),
        ``"<source>: YAML nested too deeply"`` (the parser recurses once per level: a small
        file nested 100 000 levels deep exhausts the interpreter's stack) or
        ``"<source>: top level must be a mapping"``.
    """
    import yaml

    try:
        tree = yaml.load(text, Loader=_loader(yaml, text))
    except RecursionError:
        raise error(f"{source}: YAML nested too deeply") from None
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


def field_error(path: str, key: str, problem: str) -> BadFile:
    """The one-line error of a document's field: ``PATH: field 'KEY': PROBLEM``."""
    return BadFile(f"{path}: field '{key}': {problem}")


def mapping_keys(path: str, key: str, tree: Any, required, optional=()) -> Mapping:
    """``tree`` if it is a mapping with every ``required`` key and no key outside
    ``required`` and ``optional``; else :func:`field_error` naming the first key at fault
    (``key``: the mapping's own dotted name, "" at the top)."""
    if not isinstance(tree, Mapping):
        raise field_error(path, key, f"must be a mapping, got {type(tree).__name__}")
    prefix = f"{key}." if key else ""
    for k in tree:
        if k not in required and k not in optional:
            raise field_error(path, f"{prefix}{k}", "unknown key")
    for k in required:
        if k not in tree:
            raise field_error(path, f"{prefix}{k}", "missing")
    return tree


def finite_number(path: str, key: str, value: Any, lo: float = -math.inf,
                  hi: float = math.inf) -> float:
    """``value`` as a float if it is a finite number (not a bool) within [lo, hi]; else
    :func:`field_error`."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise field_error(path, key, f"must be a finite number, got {value!r}")
    if not lo <= value <= hi:
        raise field_error(path, key, f"must lie within [{lo:g}, {hi:g}], got {value!r}")
    return float(value)
