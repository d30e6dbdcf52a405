"""The plant's compiled kernels, loaded ahead-of-time compiled when ``make setup`` built them.

:func:`vega_model.nonlinear_kernel.rk4_frame` (the nonlinear RK4 frame) and
:func:`vega_model.wind_kernel.dryden_entries` (the turbulence recursion) are numba functions.
Compiled just in time they cost a process ≈ 0.3 s of CPU to ``import numba`` and ≈ 0.2 s to
load numba's on-disk cache — in the SIL, the plant node's start-up is the longest of the five
and sets the start barrier (docs/SIL_SPEED.md). ``make setup`` therefore also compiles the
same Python functions ahead of time (numba's ``pycc``, :func:`build`) into one extension
module, which loads in ≈ 1 ms without numba.

One source: the extension is compiled from the functions of those two modules (their
``py_func``), with the signatures below; no ``fastmath``, no CPU-specific target, so the numbers
are the JIT's and the plain-Python model's bit for bit (tests/model/test_kernels.py). The
module's file name carries a digest of the two source files, of numba's and numpy's versions
and of the signatures (:func:`source_digest`): after an edit of a kernel the old file is never
loaded, and :func:`compiled` falls back to the JIT functions until ``make setup`` builds it
again.

Examples
--------
>>> from vega_model.kernels import compiled
>>> compiled().kind in ("aot", "jit")
True

Command line (``make setup`` runs it): ``python -m vega_model.kernels`` builds the extension
into ``vega_model/__pycache__`` unless a current one is there, and prints its path.
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.machinery
import importlib.util
import sys
import sysconfig
from functools import lru_cache
from pathlib import Path
from types import SimpleNamespace

__all__ = ["SIGNATURES", "aot_path", "build", "compiled", "source_digest"]

_A = "f8[::1]"
SIGNATURES = {
    "rk4_frame": ("nonlinear_kernel",
                  f"void({_A}, f8[:,::1], {_A}, {_A}, {_A}, {_A}, {_A}, {_A}, {_A}, {_A}, {_A}, "
                  "f8, f8, f8, f8, i8, i8, i8, i8)"),
    "dryden_entries": ("wind_kernel", f"Tuple(({_A}, f8))({_A}, f8, {_A}, {_A}, {_A}, i8)"),
}
"""Exported function → (module of :mod:`vega_model` it comes from, numba signature). The
argument types are those its callers pass (``vega_sim.plant_step``, ``vega_model.wind``):
C-contiguous float64 arrays, floats, and ints for the millisecond times and counts."""

_HERE = Path(__file__).resolve().parent
_PREFIX = "vega_kernels_aot_"


def _versions() -> str:
    """numba's and numpy's installed distributions (``<name>-<version>.dist-info`` beside each
    package: the extension is compiled by one and linked against the other's C API), read
    without importing them or importlib.metadata (≈ 20 ms)."""
    found = []
    for name in ("numba", "numpy"):
        spec = importlib.util.find_spec(name)
        if spec is None or spec.origin is None:
            found.append(f"{name}: none")
            continue
        found += sorted(p.name for p in Path(spec.origin).parent.parent.glob(
            f"{name}-*.dist-info")) or [f"{name}: unknown"]
    return ",".join(found)


def source_digest() -> str:
    """16 hex digits of SHA-256 over the kernel modules' source files, numba's and numpy's
    versions and :data:`SIGNATURES`: the name of the extension that is current for this
    source."""
    h = hashlib.sha256()
    for module in sorted({m for m, _ in SIGNATURES.values()}):
        h.update((_HERE / f"{module}.py").read_bytes())
    h.update(_versions().encode())
    h.update(repr(sorted(SIGNATURES.items())).encode())
    return h.hexdigest()[:16]


def aot_path(digest: str | None = None) -> Path:
    """Where the extension for ``digest`` (default: the current source's) lives."""
    name = _PREFIX + (digest or source_digest())
    return _HERE / "__pycache__" / (name + sysconfig.get_config_var("EXT_SUFFIX"))


def _load_extension(path: Path):
    name = path.name.split(".", 1)[0]
    loader = importlib.machinery.ExtensionFileLoader(name, str(path))
    spec = importlib.util.spec_from_file_location(name, path, loader=loader)
    module = importlib.util.module_from_spec(spec)
    loader.exec_module(module)
    return module


@lru_cache(maxsize=1)
def compiled() -> SimpleNamespace:
    """The kernels to call: ``rk4_frame``, ``dryden_entries`` and ``kind`` ("aot": the
    extension built for the current source; "jit": numba's just-in-time functions, when no
    current extension exists). Resolved once per process."""
    path = aot_path()
    if path.is_file():
        module = _load_extension(path)
        return SimpleNamespace(kind="aot", path=path,
                               **{name: getattr(module, name) for name in SIGNATURES})
    return SimpleNamespace(kind="jit", path=None, **{
        name: getattr(importlib.import_module(f"vega_model.{module}"), name)
        for name, (module, _) in SIGNATURES.items()})


def build(out: Path | None = None) -> Path:
    """Compile the kernels ahead of time (numba ``pycc``) into the extension :func:`compiled`
    loads (or into the directory ``out``); returns the file. Takes ≈ 3 s."""
    import tempfile

    from numba.pycc import CC

    path = aot_path()
    target = Path(out) / path.name if out is not None else path
    target.parent.mkdir(parents=True, exist_ok=True)
    cc = CC(path.name.split(".", 1)[0])
    with tempfile.TemporaryDirectory(dir=target.parent) as tmp:
        cc.output_dir = tmp
        cc.verbose = False
        for name, (module, signature) in SIGNATURES.items():
            function = getattr(importlib.import_module(f"vega_model.{module}"), name)
            cc.export(name, signature)(function.py_func)
        cc.compile()
        built = Path(tmp) / path.name
        built.replace(target)             # atomic: a reader sees no half-written file
    return target


def main() -> int:
    """Build the current extension unless it is there; print its path."""
    path = aot_path()
    if not path.is_file():
        for stale in path.parent.glob(_PREFIX + "*"):
            stale.unlink()
        path = build()
    print(f"vega_model.kernels: {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
