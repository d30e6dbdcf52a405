"""The plant's kernels compiled ahead of time (vega_model.kernels): built by ``make setup``,
loaded without numba, the same numbers as the plain-Python model bit for bit, and never loaded
for a source they were not built from."""

import subprocess
import sys

import numpy as np
import pytest

from vega_model import kernels, nonlinear_kernel as nk
from vega_model.dynamics import NonlinearModel
from vega_model.parameters import default_context


def _bits(values):
    return np.asarray(values, dtype=float).view(np.uint64).tolist()


def test_setup_built_the_extension_of_the_current_source_and_it_loads_without_numba():
    found = kernels.compiled()
    assert found.kind == "aot", "no current ahead-of-time kernels: run `make setup`"
    assert found.path == kernels.aot_path()
    out = subprocess.run(
        [sys.executable, "-c",
         "import sys\nfrom vega_model.kernels import compiled\nk = compiled()\n"
         "print(k.kind, 'numba' in sys.modules, 'llvmlite' in sys.modules)"],
        capture_output=True, text=True, check=True, timeout=120)
    assert out.stdout.split() == ["aot", "False", "False"]


def test_an_edited_source_falls_back_to_the_jit_functions(monkeypatch):
    kernels.compiled.cache_clear()
    try:
        monkeypatch.setattr(kernels, "source_digest", lambda: "0" * 16)
        found = kernels.compiled()
        assert found.kind == "jit"
        assert found.rk4_frame is nk.rk4_frame
        assert "0" * 16 in kernels.aot_path().name
    finally:
        kernels.compiled.cache_clear()


def test_the_digest_covers_the_kernel_sources(tmp_path, monkeypatch):
    before = kernels.source_digest()
    for name in ("nonlinear_kernel.py", "wind_kernel.py"):
        copy = tmp_path / name
        copy.write_bytes((kernels._HERE / name).read_bytes())
    monkeypatch.setattr(kernels, "_HERE", tmp_path)
    assert kernels.source_digest() == before
    (tmp_path / "wind_kernel.py").write_bytes(
        (tmp_path / "wind_kernel.py").read_bytes() + b"\n# an edit\n")
    assert kernels.source_digest() != before


@pytest.mark.parametrize("t_s", [0.5, 40.0, 99.0])
def test_aot_rk4_frame_equals_the_python_model_across_parameter_entries(t_s):
    """Ten 1 ms steps over two parameter entries (a 5 ms refresh), against
    NonlinearModel.rk4_step step by step (which the kernel does not call)."""
    aot = kernels.compiled().rk4_frame
    ctx = default_context()
    params = [ctx.parameters(t_s), ctx.parameters(t_s + 0.005)]
    consts = np.array([nk.entry_constants(p) for p in params])
    consts.setflags(write=False)                    # as the plant passes them
    tables = nk.mach_tables(params[0])
    rng = np.random.default_rng(int(t_s * 7))
    for _ in range(50):
        beta = rng.normal(size=10) * 0.05
        rate = rng.normal(size=10) * 0.2
        wind = rng.normal(size=10) * 10.0
        x0 = (rng.normal(size=8) * [0.2, 0.2, 50, 20, 0.02, 0.02, 0.2, 0.2]).tolist()
        x = np.array(x0)
        t_ms = int(round(t_s * 1000))
        aot(x, consts, *tables, beta, rate, wind, 0.01, -0.1, 1000.0, 0.001, t_ms, t_ms, 5, 1)
        want, b0, r0 = tuple(x0), 0.01, -0.1
        for k in range(10):
            b1, r1 = float(beta[k]), float(rate[k])
            want = NonlinearModel(params[k // 5]).rk4_step(
                want, (0.5 * (b0 + b1), (r1 - r0) * 1000.0, float(wind[k]), 0.5 * (r0 + r1)),
                0.001)
            b0, r0 = b1, r1
        assert _bits(x) == _bits(want)


def test_aot_dryden_entries_is_the_recursion_written_out():
    aot = kernels.compiled().dryden_entries
    rng = np.random.default_rng(5)
    sigma = np.abs(rng.normal(size=4))
    a = rng.uniform(0.9, 1.0, size=4)
    b = np.sqrt(1.0 - a * a)
    noise = rng.normal(size=4 * 25)
    out, eta = aot(noise, 0.3, sigma, a, b, 25)
    want, e, k = [], 0.3, 0
    for s, ae, be in zip(sigma.tolist(), a.tolist(), b.tolist()):
        for _ in range(25):
            e = ae * e + be * float(noise[k])
            want.append(s * e)
            k += 1
    assert _bits(out) == _bits(want)
    assert _bits([eta]) == _bits([e])
