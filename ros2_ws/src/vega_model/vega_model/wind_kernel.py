"""The Dryden turbulence recursion over a whole track, compiled (numba): the same floating-point
operations as :meth:`vega_model.wind.DrydenTurbulence.steps`, bit for bit.

η_{k+1} = a η_k + b n_k, v_k = σ η_{k+1} per physics step, with (σ, a, b) held over each
parameter entry. In plain Python a step costs ≈ 0.1–0.2 µs (≈ 15–25 ms for the 100 010 steps of a
100 s flight); compiled, ≈ 1 ns. The same numbers: one multiply and one add per operation in
Python's order, no ``fastmath`` (LLVM neither reassociates nor fuses them into an FMA), as in
:mod:`vega_model.nonlinear_kernel`. tests/model/test_wind.py compares it with the Python code.

Imported only through :mod:`vega_model.kernels` (the plant's wind, :meth:`vega_model.wind.
WindModel.entry_steps`), which loads the ahead-of-time compiled twin that ``make setup`` builds
and falls back to this function; so the nodes without a plant never import numba. Compiled on
first use and cached on disk next to this file (``cache=True``).
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["dryden_entries"]


@numba.njit(cache=True, nogil=True)
def dryden_entries(noise, eta, sigma, a, b, steps_per_entry):
    """The turbulence of ``steps_per_entry`` steps per entry, entries in turn.

    Parameters
    ----------
    noise
        The standard normal draws, one per step (len(sigma)·steps_per_entry).
    eta
        η before the first step.
    sigma, a, b
        Per entry: σ_w [m/s], a and √(1 − a²) (:meth:`DrydenTurbulence.coefficients`).
    steps_per_entry
        Steps per entry.

    Returns
    -------
    out, eta
        v_turb [m/s] at every step, and η after the last one.
    """
    out = np.empty(sigma.shape[0] * steps_per_entry)
    k = 0
    for e in range(sigma.shape[0]):
        s, ae, be = sigma[e], a[e], b[e]
        for _ in range(steps_per_entry):
            eta = ae * eta + be * noise[k]
            out[k] = s * eta
            k += 1
    return out, eta
