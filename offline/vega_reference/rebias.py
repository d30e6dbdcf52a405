"""Day-of-launch re-biasing: the guidance reference re-solved on a measured wind profile, fast.

:func:`vega_reference.guidance.design_reference` builds the guidance problem with cvxpy and
solves it with Clarabel in seconds (the rigid models along the nominal, the problem's
canonicalisation, the solve). A campaign re-biases every sample to its own sounding
(docs/GUIDANCE.md §8), so here the same problem is assembled once as a sparse quadratic
programme in Clarabel's standard form

    minimise   ½ zᵀ P z + q(v_w)ᵀ z
    subject to A z + s = b(v_w),   s ∈ {0}^(4N) × ℝ₊^(4N)

with z = [x_0 … x_{N−1}, β_0 … β_{N−1}] (x_k = θ, θ̇, z, ż) — and only q and b, which are
linear in the design wind v_w, change from one sample to the next:

* P = 2Δt [ Σ_k (c_k/E_k)(c_k/E_k)ᵀ + w_θ/(1°)² e_θ e_θᵀ  on x_k ;
            w_β/(1°)² I + w_Δβ/(Δt·1°)² DᵀD  on β ]          (D: first differences)
* q_k = 2Δt (d_k v_w,k / E_k²) c_k on x_k, 0 on β;
  the objective plus Δt Σ_k (d_k v_w,k / E_k)² is the cost of the module docstring of
  :mod:`vega_reference.guidance` (Qα_k = c_k·x_k + d_k v_w,k, E_k the envelope);
* zero cone: x_0 = 0 and x_{k+1} − Φ_k x_k − Γβ_k β_k = Γw_k v_w,k;
* non-negative cone: ±z_k ≤ z_max, ±ż_k ≤ ż_max.

Each solve is a fresh Clarabel solver on these arrays (one thread, the default direct solver
QDLDL), so its result depends on its inputs only: the same measured profile gives the same
reference bit for bit, in any process and after any other solve (tests/reference). It is the
same problem as the cvxpy route and solved by the same solver, so the two agree to the
solver's tolerance (tests/reference/test_rebias.py), not bit for bit.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Mapping

import numpy as np
import scipy.sparse as sp

from vega_loops.blas import one_blas_thread
from vega_gnc.guidance_reference import GuidanceReference
from vega_model.parameters import ModelContext, default_context
from vega_reference.guidance import (DesignWind, GuidanceDesign, GuidanceWeights,
                                     design_from_solution, rigid_models,
                                     write_guidance_reference)

__all__ = ["GuidanceQP", "guidance_qp", "rebias_reference", "write_rebiased_reference"]

_N_X = 4        # rigid states θ, θ̇, z, ż


@dataclass(frozen=True)
class _Models:
    """The wind-independent data of the problem on its time grid."""

    t_s: np.ndarray
    h_m: np.ndarray                 # nominal altitude [m] at each time
    models: tuple                   # (Φ, Γβ, Γw, Qα row, Qα wind term, INS rows, Mach, E)


class GuidanceQP:
    """The guidance problem assembled once; :meth:`solve` re-solves it for a design wind.

    Parameters
    ----------
    weights
        Weights, drift bounds and time grid (:class:`GuidanceWeights`; default: those of the
        shipped reference).
    context
        Model data sources (default: the shipped vehicle data and flight conditions).
    requirements
        :class:`vega_sim.requirements.RequirementSpec` of the load envelope (default: the
        shipped requirements).

    Notes
    -----
    Building takes about as long as the cvxpy route's rigid models (≈ 1–2 s: N matrix
    exponentials); a solve is the sparse QP of the module docstring only.
    """

    @one_blas_thread
    def __init__(self, weights: GuidanceWeights | None = None, *,
                 context: ModelContext | None = None, requirements=None):
        from vega_sim.requirements import load_requirements

        weights = weights if weights is not None else GuidanceWeights()
        self.weights = weights
        self.context = context if context is not None else default_context()
        spec = requirements if requirements is not None else load_requirements()
        n_steps = int(round(weights.t_end_s / weights.dt_s))
        t = np.arange(n_steps + 1) * weights.dt_s
        phi, gb, gw, cq, dq, cins, params = rigid_models(t, self.context, weights.dt_s)
        mach = np.array([p.mach for p in params])
        env = np.interp(mach, spec.envelope_mach, spec.envelope_pa_rad)
        self._data = _Models(t_s=t, h_m=np.array([p.h_m for p in params]),
                             models=(phi, gb, gw, cq, dq, cins, mach, env))
        self._assemble()

    @property
    def t_s(self) -> np.ndarray:
        """The time grid [s]."""
        return self._data.t_s

    @property
    def altitude_m(self) -> np.ndarray:
        """The nominal altitude [m] at each time of the grid (where the design wind is read)."""
        return self._data.h_m

    def _assemble(self) -> None:
        phi, gb, gw, cq, dq, _, _, env = self._data.models
        w, dt = self.weights, self.weights.dt_s
        n = self._data.t_s.size
        nx = _N_X * n
        deg2 = math.radians(1.0) ** 2
        # P: x blocks 2Δt (c̃ c̃ᵀ + w_θ/deg² e_θ e_θᵀ); β block 2Δt (w_β/deg² I + w_Δβ/(Δt deg)² DᵀD)
        ct = cq / env[:, None]
        blocks = np.einsum("ki,kj->kij", ct, ct)
        blocks[:, 0, 0] += w.theta_weight / deg2
        p_x = sp.block_diag(list(2.0 * dt * blocks), format="csc")
        diff = sp.diags([-np.ones(n - 1), np.ones(n - 1)], [0, 1], shape=(n - 1, n))
        p_b = 2.0 * dt * (w.beta_weight / deg2 * sp.identity(n)
                          + w.beta_rate_weight / (dt * dt * deg2) * (diff.T @ diff))
        self._P = sp.triu(sp.block_diag([p_x, p_b]), format="csc")
        # q(v_w) = Q_w v_w: on x_k, 2Δt d_k/E_k² c_k
        rows = np.arange(nx)
        cols = np.repeat(np.arange(n), _N_X)
        self._Qw = sp.csc_matrix(((2.0 * dt * (dq / env ** 2)[:, None] * cq).ravel(),
                                  (rows, cols)), shape=(nx + n, n))
        # zero cone: x_0 = 0; x_{k+1} − Φ_k x_k − Γβ_k β_k = Γw_k v_w,k
        r, c, v = [np.arange(_N_X)], [np.arange(_N_X)], [np.ones(_N_X)]
        k = np.arange(n - 1)
        base = _N_X + _N_X * k                              # first row of step k
        for i in range(_N_X):
            r.append(base + i)
            c.append(_N_X * (k + 1) + i)
            v.append(np.ones(n - 1))
            for j in range(_N_X):
                r.append(base + i)
                c.append(_N_X * k + j)
                v.append(-phi[:-1, i, j])
            r.append(base + i)
            c.append(nx + k)
            v.append(-gb[:-1, i])
        n_eq = _N_X * n
        # non-negative cone: z_k ≤ z_max, −z_k ≤ z_max, ż_k ≤ ż_max, −ż_k ≤ ż_max
        kk = np.arange(n)
        for m, (state, sign) in enumerate(((2, 1.0), (2, -1.0), (3, 1.0), (3, -1.0))):
            r.append(n_eq + m * n + kk)
            c.append(_N_X * kk + state)
            v.append(np.full(n, sign))
        self._A = sp.csc_matrix((np.concatenate(v), (np.concatenate(r), np.concatenate(c))),
                                shape=(n_eq + 4 * n, nx + n))
        self._b0 = np.concatenate([np.zeros(n_eq), np.full(2 * n, w.z_max_m),
                                   np.full(2 * n, w.z_dot_max_mps)])
        # b(v_w) = b0 + B_w v_w: Γw_k v_w,k on the rows of step k
        self._Bw = sp.csc_matrix((gw[:-1].ravel(), ((base[:, None] + np.arange(_N_X)).ravel(),
                                                    np.repeat(k, _N_X))),
                                 shape=(n_eq + 4 * n, n))
        self._n_eq, self._n_ineq = n_eq, 4 * n
        # the constant of the cost: Δt Σ (d_k v_w,k / E_k)² = v_wᵀ diag(Δt d²/E²) v_w
        self._const = dt * (dq / env) ** 2

    @one_blas_thread
    def solve(self, wind: DesignWind) -> GuidanceDesign:
        """The reference for the design wind ``wind`` (:class:`GuidanceDesign`; its summary's
        ``solver`` entry records the route, status, iterations, time and cost).

        Raises
        ------
        RuntimeError
            If the solver does not return an optimal solution (an internal error: the
            problem is feasible for any wind, the zero-wind reference being 0).
        """
        import clarabel

        t0 = time.perf_counter()
        vw = wind.along(self._data.h_m, self.context.vehicle)
        q = self._Qw @ vw
        b = self._b0 + self._Bw @ vw
        settings = clarabel.DefaultSettings()
        settings.verbose = False
        settings.max_threads = 1          # one thread: the same operations in every run
        cones = [clarabel.ZeroConeT(self._n_eq), clarabel.NonnegativeConeT(self._n_ineq)]
        solution = clarabel.DefaultSolver(self._P, q, self._A, b, cones, settings).solve()
        status = str(solution.status)
        if status != "Solved":
            raise RuntimeError(f"guidance problem: solver status {status}")
        z = np.array(solution.x)
        n = self._data.t_s.size
        solve_s = time.perf_counter() - t0
        cost = float(solution.obj_val) + float(self._const @ (vw * vw))
        return design_from_solution(
            self._data.t_s, z[:_N_X * n].reshape(n, _N_X), z[_N_X * n:], vw, self.weights,
            self._data.models,
            {"name": "CLARABEL", "route": "vega_reference.rebias (QP assembled once)",
             "status": "optimal", "iterations": int(solution.iterations),
             "solve_s": solve_s, "cost": cost})


def guidance_qp(weights: GuidanceWeights | None = None) -> GuidanceQP:
    """The :class:`GuidanceQP` of ``weights`` (default: the shipped reference's) on the
    shipped model and requirements, built on first use in a process and then shared (it is
    read-only)."""
    return _cached_qp(weights if weights is not None else GuidanceWeights())


@lru_cache(maxsize=2)
def _cached_qp(weights: GuidanceWeights) -> GuidanceQP:
    return GuidanceQP(weights)


def rebias_reference(measured_altitude_m, measured_wind_mps,
                     weights: GuidanceWeights | None = None, *,
                     name: str = "measured profile (day-of-launch sounding)",
                     source: str = "", problem: GuidanceQP | None = None) -> GuidanceDesign:
    """The guidance reference re-biased to a measured wind profile (day-of-launch update).

    Parameters
    ----------
    measured_altitude_m, measured_wind_mps
        The sounding [m], [m/s] along +z (the scenario's sign): a
        :class:`vega_model.wind.WindTable` — altitudes strictly increasing, values finite —
        read as the plant reads a table (linear, end values held) at the nominal altitudes.
    weights
        The guidance problem's weights and bounds (default: those of the shipped reference,
        or the ``problem``'s).
    name, source
        Recorded with the design wind (a reference file's metadata).
    problem
        The assembled problem to solve (default: :func:`guidance_qp` of ``weights``).

    Returns
    -------
    GuidanceDesign
        As :func:`vega_reference.guidance.design_reference` returns it for the same design
        wind (to the solver's tolerance); the same arrays bit for bit for the same inputs.

    Raises
    ------
    vega_model.wind.WindTableError
        One line naming the column and row of a malformed profile (a ``BadInput``).
    """
    wind = DesignWind.from_table(measured_altitude_m, measured_wind_mps, name, source)
    qp = problem if problem is not None else guidance_qp(weights)
    if weights is not None and qp.weights != weights:
        raise ValueError("rebias_reference: the problem was assembled for other weights")
    return qp.solve(wind)


def write_rebiased_reference(path: str | Path, design: GuidanceDesign,
                             measured_altitude_m, measured_wind_mps,
                             weights: GuidanceWeights | None = None, *,
                             name: str = "measured profile (day-of-launch sounding)",
                             source: str = "",
                             sources: Mapping[str, str] | None = None) -> GuidanceReference:
    """Write a re-biased reference as a guidance reference file (the format and checks of
    :func:`vega_reference.guidance.write_guidance_reference`; its metadata holds the measured
    table as the design wind), for a scenario's ``guidance:`` to name — so that the in-process
    run, ``vega sil run`` and ``vega mc rerun`` fly the same reference, and the bag records
    its SHA-256. ``weights``: those the design was solved with (default: the shipped
    reference's). Returns the file as the flight software loads it."""
    wind = DesignWind.from_table(measured_altitude_m, measured_wind_mps, name, source)
    weights = weights if weights is not None else GuidanceWeights()
    return write_guidance_reference(path, design, wind, weights, sources=sources)
