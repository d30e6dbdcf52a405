"""A short in-process run and its bag, flown once per set of inputs and cached (tests only).

The mutation runs of vega_bags modules (`make mutation MODULE=bagcheck|replay`) start one test
process per mutant — over a thousand — and each would fly the same fixture run again
(≈ 1.3 s flight + 0.4 s bag write of the ≈ 2.5 s a process takes). Nothing that flies the
run or writes the bag is mutated there, so the run is flown once: :func:`cached_short_run`
keys the cache on the SHA-256 of every source, configuration and data file of the packages
that produce it and of the fixture modules, wherever they are imported from; any change to
them is a new key, i.e. a new flight. The cache lives in the temporary directory (the bag
names its controller table there); one process writes an entry while holding a lock, and an
entry counts only once its last file is in place, so that concurrent test processes never
use half of one.
"""

from __future__ import annotations

import fcntl
import hashlib
import importlib
import os
import pickle
import shutil
import tempfile
import time
from pathlib import Path

from fixture_bags import ShortRun, short_run, write_bag

__all__ = ["cached_short_run"]

PACKAGES = ("vega_sim", "vega_model", "vega_gnc", "vega_bus", "vega_bags", "vega_core")
SUFFIXES = (".py", ".yaml", ".yml", ".npz", ".npy", ".csv", ".json", ".txt")
"""Files hashed (not mutmut's ``.meta`` records, which change after every mutant)."""


def _inputs_key(span_s) -> str:
    h = hashlib.sha256(repr(tuple(span_s)).encode())
    dirs = [Path(importlib.import_module(p).__file__).resolve().parent for p in PACKAGES]
    files = [f for d in dirs for f in sorted(d.rglob("*"))
             if f.suffix in SUFFIXES and f.is_file() and "__pycache__" not in f.parts]
    tests = Path(__file__).resolve().parents[1]
    files += [tests / "fixture_bags.py", tests / "fixture_tables.py"]
    for f in files:
        h.update(f.name.encode() + b"\0" + f.read_bytes() + b"\0")
    return h.hexdigest()[:32]


def cached_short_run(span_s) -> tuple[ShortRun, Path]:
    """(the run over ``span_s`` — its result and table file; ``table`` is None —, its bag
    written by :func:`fixture_bags.write_bag` without faults). Read-only: copy before
    changing anything."""
    cache = Path(tempfile.gettempdir()) / "vega-test-bags" / _inputs_key(span_s)
    done = cache / "result.pickle"
    if not done.is_file():
        cache.parent.mkdir(parents=True, exist_ok=True)
        with open(cache.parent / ".lock", "w") as lock:
            fcntl.flock(lock, fcntl.LOCK_EX)     # one process flies; the others wait for it
            if not done.is_file():
                for old in cache.parent.iterdir():   # entries of inputs a day old and more
                    if old.is_dir() and time.time() - old.stat().st_mtime > 86400:
                        shutil.rmtree(old, ignore_errors=True)
                shutil.rmtree(cache, ignore_errors=True)     # a writer that died midway
                (cache / "run").mkdir(parents=True)
                run = short_run(cache / "run", span_s=span_s)
                write_bag(cache / "bag", run)
                tmp = cache / "result.pickle.tmp"
                tmp.write_bytes(pickle.dumps(run.result))
                os.replace(tmp, done)                # complete only with the result in place
    result = pickle.loads(done.read_bytes())
    return ShortRun(result, cache / "run" / "pd.npz", None), cache / "bag"
