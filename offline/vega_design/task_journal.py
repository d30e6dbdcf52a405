"""A journal of finished design tasks, so that an interrupted ``vega design`` resumes.

A from-scratch ``vega design`` runs for hours on two cores (docs/FLIGHT_DESIGN.md §4); without
a record of the finished work a kill or a reboot loses all of it. Every tuning task of the
design (an anchor, a grid walk between two anchors, a rescue, a point added between grid
points, the tail-off tuning: steps 1–5) is a deterministic function of its arguments — the
searches are seeded — so its result can be written down when it finishes and reused when the
same task comes again: a resumed run computes exactly what the uninterrupted run would have.
What is not journalled (the checks between the tasks, step 6's drift-rate scaling, step 7's
corner repair) is deterministic given the tasks' results and is recomputed: step 6 takes a few
minutes, step 7 ≈ 6–25 min on two cores, against hours for the tasks. This is the design's only
way back into a run: a table is always made from its inputs, never from an earlier table.

The journal is a text file of JSON lines: a header naming the code that wrote it, then one
line per finished task — the task's key (SHA-256 of the function's name and a canonical
encoding of its arguments: floats by their exact hexadecimal form, arrays by dtype, shape and
bytes) and its result (pickled, base64). The header's code digest covers every file of the
packages whose code computes a task (``vega_design``, ``vega_analysis``, ``vega_loops``,
``vega_model``, ``vega_core``, ``vega_gnc``) and the numpy and scipy versions: a journal
written by other code is refused (one line, exit 2 through :class:`~vega_core.errors.BadFile`),
never silently reused. A line cut short by a kill is dropped when the journal is opened; any
other damage is refused.

Pickle is used for the results because they are the design's own objects (parameter vectors,
detail dictionaries with numpy values) and must come back bit for bit; a journal is a local
file written by this module, not an exchange format — do not open one from elsewhere.
"""

from __future__ import annotations

import base64
import hashlib
import json
import os
import pickle
import struct
from pathlib import Path

import numpy as np
from vega_core.errors import BadFile

__all__ = ["TaskJournal", "code_digest", "task_key"]

FORMAT = "vega design task journal"
VERSION = 1
CODE_PACKAGES = ("vega_design", "vega_analysis", "vega_loops", "vega_model", "vega_core",
                 "vega_gnc")


def _encode(obj, out: list) -> None:
    """Append a canonical, type-tagged encoding of ``obj`` to ``out`` (bytes pieces)."""
    if obj is None:
        out.append(b"N")
    elif isinstance(obj, (bool, np.bool_)):
        out.append(b"B1" if obj else b"B0")
    elif isinstance(obj, (int, np.integer)):
        out.append(b"I" + str(int(obj)).encode() + b";")
    elif isinstance(obj, (float, np.floating)):
        out.append(b"F" + float(obj).hex().encode() + b";")
    elif isinstance(obj, str):
        data = obj.encode()
        out.append(b"S" + struct.pack("<Q", len(data)) + data)
    elif isinstance(obj, np.ndarray):
        data = np.ascontiguousarray(obj).tobytes()
        out.append(b"A" + obj.dtype.str.encode() + b":" + repr(obj.shape).encode() + b":"
                   + struct.pack("<Q", len(data)) + data)
    elif isinstance(obj, (tuple, list)):
        out.append(b"T" + struct.pack("<Q", len(obj)))
        for item in obj:
            _encode(item, out)
    elif isinstance(obj, dict):
        out.append(b"D" + struct.pack("<Q", len(obj)))
        for key in sorted(obj, key=repr):
            _encode(key, out)
            _encode(obj[key], out)
    else:
        raise TypeError(f"task_key: cannot encode {type(obj).__name__}")


def task_key(fn, args) -> str:
    """The journal key of the task ``fn(args)``: equal for equal arguments whatever their
    identity (the same array passed twice or two equal arrays), different for any differing
    bit of a float."""
    pieces: list[bytes] = []
    _encode((f"{fn.__module__}.{fn.__qualname__}", args), pieces)
    return hashlib.sha256(b"".join(pieces)).hexdigest()


def code_digest() -> str:
    """SHA-256 over the files of :data:`CODE_PACKAGES` (paths and contents, compiled caches
    and extension modules excluded) and the numpy and scipy versions."""
    import importlib

    import scipy

    h = hashlib.sha256(f"numpy {np.__version__} scipy {scipy.__version__}\n".encode())
    for name in CODE_PACKAGES:
        root = Path(importlib.import_module(name).__file__).parent
        for path in sorted(p for p in root.rglob("*") if p.is_file()
                           and "__pycache__" not in p.parts and p.suffix not in (".so", ".pyc")):
            h.update(f"{name}/{path.relative_to(root).as_posix()}\n".encode())
            h.update(hashlib.sha256(path.read_bytes()).digest())
    return h.hexdigest()


class TaskJournal:
    """The finished tasks of one design run, read from and appended to ``path``."""

    def __init__(self, path, digest: str | None = None):
        self.path = Path(path)
        self.digest = code_digest() if digest is None else digest
        self.results: dict[str, object] = {}
        self.reused = 0
        if self.path.exists() and self.path.stat().st_size:
            self._load()
        else:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._append({"format": FORMAT, "version": VERSION, "code": self.digest})

    def _load(self) -> None:
        raw = self.path.read_bytes()
        complete = raw[:raw.rfind(b"\n") + 1]         # a line cut short by a kill: dropped
        lines = complete.decode("utf-8", errors="replace").splitlines()
        where = f"design journal {self.path}"
        try:
            header = json.loads(lines[0]) if lines else None
        except json.JSONDecodeError:
            header = None
        if not isinstance(header, dict) or header.get("format") != FORMAT:
            raise BadFile(f"{where}: line 1 is not a '{FORMAT}' header")
        if header.get("version") != VERSION:
            raise BadFile(f"{where}: version {header.get('version')!r}, this code reads "
                          f"{VERSION}")
        if header.get("code") != self.digest:
            raise BadFile(f"{where}: written by other design code (digest "
                          f"{str(header.get('code'))[:12]}…, this code {self.digest[:12]}…); "
                          "its results would not be this code's: move it away to start over")
        for number, line in enumerate(lines[1:], start=2):
            try:
                entry = json.loads(line)
                self.results[entry["key"]] = pickle.loads(
                    base64.b64decode(entry["result"], validate=True))
            except (json.JSONDecodeError, KeyError, TypeError, ValueError,
                    pickle.UnpicklingError, EOFError) as exc:
                raise BadFile(f"{where}: line {number} is not a finished task "
                              f"({type(exc).__name__})") from None
        if len(complete) < len(raw):          # only a sound journal of this code is ever cut
            with open(self.path, "r+b") as f:
                f.truncate(len(complete))

    def _append(self, entry: dict) -> None:
        with open(self.path, "a", encoding="utf-8") as f:
            f.write(json.dumps(entry) + "\n")
            f.flush()
            os.fsync(f.fileno())

    def __contains__(self, key: str) -> bool:
        return key in self.results

    def __len__(self) -> int:
        return len(self.results)

    def get(self, key: str):
        """The recorded result of the task ``key`` (counted as reused)."""
        self.reused += 1
        return self.results[key]

    def record(self, key: str, result) -> None:
        """Write the result of a finished task (appended and synced before returning)."""
        self.results[key] = result
        self._append({"key": key, "result": base64.b64encode(
            pickle.dumps(result, protocol=4)).decode("ascii")})

    def call(self, fn, args):
        """``fn(args)``, or its recorded result when this task finished before."""
        key = task_key(fn, args)
        if key in self.results:
            return self.get(key)
        result = fn(args)
        self.record(key, result)
        return result
