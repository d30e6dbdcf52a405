"""Mixed-μ upper bound of the flown frozen loops over the parametric uncertainty set
(docs/ROBUST_ANALYSIS.md §2.3).

Per frozen flight time, the loop of :mod:`vega_loops.margins` (flown discrete controller
on the *nominal* schedule, hold, delay, TVC actuator, launcher of ``vega linearize``; loop broken
at the actuator input) is written as M(jω) in feedback with a structured Δ holding the real
parameters of the uncertainty set (thesis Table 2.3 + TVC bandwidth, :mod:`vega_model.uncertainty`)
and the delay, and μ_Δ(M(jω)) is bounded from above on a frequency grid. If the centre loop is
stable and μ < 1 at every frequency, every plant of the set is stable (to the limits below);
1/μ_peak is the fraction of the box (around its centre) that the bound guarantees.

**LFT of the 12 real parameters** (:func:`mu_problem`). Each deviation is normalised around the
centre of its range, dev_i = c_i + h_i·δ_i, δ_i ∈ [−1, 1] (the ranges are asymmetric: the centre
is not the nominal plant). The state-space matrix S(δ) = [[A, B], [C, 0]] of actuator + launcher
(:func:`.margins.plant_loop_ss` at :func:`.margins.corner_plant`'s parameters, exactly as the
simulation applies a deviation dict) is sampled and fitted by a polynomial

    S(δ) ≈ S0 + Σ_i δ_i S_i + Σ_{i ∈ Q} δ_i² S_ii + Σ_{(i, j) ∈ X} δ_i δ_j S_ij,

S0 = S(0) exactly (the centre plant); S_i, S_ii by least squares along each axis (δ_i = ±½, ±1,
the others 0: exact where the entries are polynomials of degree ≤ 2 in δ_i); S_ij from the four
vertices of the pair (exact for the bilinear term). Q = :data:`QUADRATIC` (the parameters that
enter squared: v in Q = ½ρv², the bending and actuator frequencies in ω², the mode shapes, see
below); X = the :data:`MAX_CROSS` pairs whose bilinear term moves the loop most, if by at least
:data:`CROSS_MIN` (first order, below) — the aerodynamic products (v·x_CP, ρ·x_CP, v·ρ) at most
times.

*Coordinates.* The states of bending mode i are rescaled by its mode-shape factor,
q_i' = (1 + δψ_i)·q_i (:func:`plant_matrix`): a similarity (every transfer function unchanged)
that moves the whole mode-shape dependence onto the mode's input row, (1 + δψ_i)², rank one.
In the plant's own coordinates the shape scales the modal input, the INS outputs and the
bent-pivot thrust coupling separately; treated as independent scalars (below), those copies
can give the mode negative damping that no plant of the set has — measured at 50 s: μ at the
second mode 1.05 in the plant's coordinates, 0.38 in these.

*Factorisation.* Each term is factored into real scalar blocks by a truncated SVD in
loop-weighted coordinates: with the first-order loop change dL = −a(ω)·dS·b(ω) at the centre
(:func:`loop_sensitivities`), the row and column Gramians Wl = Σ a^H a/|1+L|, Wr = Σ b b^H/|1+L|
(∫ d log ω over the grid) weight S, and singular values below :data:`RANK_TOL` × the largest are
dropped (rank r_i). δ_i S_i + Σ δ_i δ_j S_ij is realised Horner-wise, δ_i·([S_i, U_ij]·[ξ; w_j]),
w_j = δ_j V_ijᵀ ξ: the inner terms give blocks of δ_j, the outer factor blocks of δ_i
(:func:`build_lft`). A parameter whose first-order loop influence max_ω |a S_i b|/|1 + L| (the
whole half-range, δ = 1) is below :data:`MIN_INFLUENCE` gets no block (rank 0): its effect goes
into the fit error and its cover.

*Repeated scalars.* ab13md accepts only 1×1 real blocks: the r_i copies of δ_i (δ_i I_{r_i})
are treated as r_i INDEPENDENT real scalars. That set contains the true one, so the bound stays a
valid upper bound — conservative by as much as the copies' independence allows.

**Delay** (one complex block). τ = τ₀ + Δ, τ₀ the centre (39 ms + the centre of ±10 ms), |Δ| ≤ h:
e^{−jωΔ} lies in the disc 1 + w(ω)·δ_c, |δ_c| ≤ 1, w(ω) = 2 sin(ωh/2) (ωh ≤ π, else 2)
(:func:`delay_weight`): a stable LTI operator bounded by w covers every constant delay of the
range.

**Fit error** (stated, and covered). Measured on a validation sample drawn apart from the fit
(:data:`N_VALIDATE` uniform points of the box and all 2^8 vertices of the 8 parameters of largest
loop influence, the other parameters at random vertices): ``loop_rel`` = max over samples and
grid of |L_true − L_fit|/|1 + L_true| (the ratio that could flip a stability verdict) and
``matrix_rel`` = max ‖S − S_fit‖/max ‖S − S0‖ (loop-weighted Frobenius norms). With ``cover``
(default) one more complex block adds ε(ω) δ_e to the return difference, ε(ω) = :data:`COVER_FACTOR`
× the largest |L_true − L_fit| met at ω: the bound then covers the true plants as far as the
sampled maximum (× the factor) bounds the fit error — a sampled, not a proven, bound.

**The loop** (:func:`interconnection`), continuous equivalent as in :func:`.margins.frozen_loop`:
u = (1 + w δ_c)·F(ω)·y (+ ε δ_e u), F = s·K(e^{jωT})·H(jω)·e^{−jωτ₀}, H the hold's fundamental
response; the plant ẋ = Ax + Bu, y = Cx with the LFT's blocks. Aliasing is neglected: the
exact sampled-data loop differs from it by its aliases (``aliasing_centre_rel`` gives the
largest |L_d − L|/|1 + L_d| of the centre plant on the grid); the Nyquist frequency π/T ends the
grid.

**Stability of the centre**: the μ test proves robust stability only around a stable centre.
It is checked on the exact sampled-data loop (:func:`.margins.sampled_data_stability`, centre
plant and centre delay) and reported (``centre_stable``).

**μ of each M(jω)** (:func:`mu_upper_bound`). Slycot ``ab13md`` (Fan, Tits & Doyle 1991: the
(D, G)-scaling bound) from its own Osborne start at every frequency. Not warm-started from the
previous frequency: with the full warm-start vector it hung (SLICOT AB13MD's line search has
no iteration limit) at 50 s; with the D part only it was no faster and up to 57 % looser
(measured). Two measured fixes of its speed: M is rank-deficient (10 states + 1 input against
~20 scalars), with which ab13md took 0.05–34 s per frequency; it is run on M + η‖M‖P (η =
:data:`REGULARISE`, P fixed pseudo-random) and on the blocks coupled at that frequency only
(:data:`REDUCE`). Its scalings (D, G) are then *certified on M itself*: β = √λ_max(D⁻¹(M^H D² M
+ j(GM − M^H G))D⁻¹) bounds μ(M) (:func:`mu_certificate`), and a local descent from there
(:func:`_polish`) improves the certificate; at the :data:`N_REPASS` highest values ab13md is run
again with the smaller η of :data:`REGULARISE_FINE`, together with ab13md on the whole,
unregularised M (certified and descended from in the same way, the smaller certificate kept;
each call limited to :data:`WHOLE_TIMEOUT_S`), repeated on the next highest values until the
peak is a value that has had it: the perturbed, reduced call can miss a far better certificate
(rank-one textbook matrices, tests/analysis/test_mu_exact.py). Every number reported is such a
certificate on the unperturbed M. Measured against plain ab13md (hours of it) on the 50 s loop: the
reported values within −2 … +14 % per frequency, +1.3 % at the peak.

**Grid** (:func:`mu_frequency_grid`): log-spaced from 0.01 rad/s to π/T, log-spaced over both
bending bands of the whole dispersed range (ω_i·[0.8·(1 + lower), 1.2·(1 + upper)] of the
set's frequency deviations), and 7 points at the centre plant's mode frequencies
(ω_c·(1 + ζ·{0, ±0.5, ±1.5, ±3}), where M has its lightly damped centre poles); then
:data:`N_REFINE` rounds halving the log-spacing around the :data:`N_PEAKS` highest local maxima.

Checks (tests/analysis/test_mu_analysis.py, test_mu_exact.py): textbook matrices with known
μ (a full complex block: σ̄; diagonal: max |m_ii|; rank one, real, complex and mixed scalars,
against an independent exact solver; two published examples; a certificate that holds); a
real-parametric loop whose destabilising parameter is
known analytically (k(1+δ)/(s+1)³ under unity feedback: μ_peak = k h/(8 − k)); the LFT against
the plants it represents (det(I − MΔ) = the ratio of return differences, exactly for the fit,
within the stated fit error for the true plants); the shipped table at 50 s.
"""

from __future__ import annotations

import math
import time as _time
from dataclasses import dataclass
from typing import Callable, Mapping, Sequence

import numpy as np

from vega_loops import margins as M

__all__ = [
    "DELAY_NAME", "QUADRATIC", "AXIS_POINTS", "RANK_TOL", "MIN_INFLUENCE", "CROSS_MIN",
    "MAX_CROSS", "COVER_FACTOR", "N_VALIDATE", "N_VERTEX_PARAMETERS", "REGULARISE",
    "REGULARISE_FINE", "REDUCE", "N_PEAKS", "N_REFINE", "N_REPASS", "WHOLE_TIMEOUT_S",
    "MODE_STATES",
    "mu_certificate", "mu_upper_bound", "delay_weight", "Box", "parameter_box",
    "plant_matrix", "axis_fit", "pair_fit", "ParametricLFT", "loop_sensitivities",
    "build_lft", "interconnection", "mu_frequency_grid", "MuProblem", "mu_problem",
    "Validation", "validate", "mu_at_time",
]

DELAY_NAME = "delay_s"
QUADRATIC = ("velocity", "bending_frequency_1", "bending_frequency_2", "psi_mode_1",
             "psi_mode_2", "actuator")
"""Parameters fitted with a δ² term: Q = ½ρv² (and the Mach-dependent aerodynamics), ω² of both
modes and of the actuator, and the mode shapes ((1 + δψ)² on the input row in the fit's
coordinates)."""
AXIS_POINTS = (-1.0, -0.5, 0.5, 1.0)
"""Normalised deviations of the single-parameter sweeps of the fit (with the centre, 0)."""
RANK_TOL = 2e-2
"""Relative truncation of the loop-weighted singular values (assumption, measured: 5e-2 left a
fit error of 0.32 of |1 + L| at 0.12 rad/s at 90 s, 2e-2 one of 0.06, for one scalar more)."""
MIN_INFLUENCE = 0.03
"""A parameter whose first-order loop change over its half-range stays below 3 % of |1 + L|
gets no block, its effect covered as fit error (assumption: at 50 s this removes mass, J_yy and
the actuator, 0.021, 0.026 and 0.013, four scalars, for ab13md's run time)."""
CROSS_MIN = 0.03
"""Smallest first-order loop influence (fraction of |1 + L|) of a bilinear term fitted."""
MAX_CROSS = 3
"""Most bilinear terms fitted (assumption, measured at 50 s: the loop fit error 0.41 without,
0.12 with the three aerodynamic products v·x_CP, ρ·x_CP, v·ρ, for about three scalars more)."""
COVER_FACTOR = 1.25
"""ε(ω) = 1.25 × the largest |L_true − L_fit| of the validation sample (assumption: the sampled
maximum under-estimates the box's; see the module docstring for the measured margin)."""
N_VALIDATE = 150
"""Uniform validation points (besides the 256 vertices)."""
N_VERTEX_PARAMETERS = 8
"""All 2^8 vertices of the 8 parameters of largest loop influence are validated."""
N_SWEEP = 25
"""Bending-frequency deviations per mode in the validation sweeps (× 3 mode-shape values, the
other parameters at random vertices)."""
COVER_SMOOTH_DEC = 0.1
"""The cover ε(ω) takes the largest sampled error within ±0.1 decade of ω (assumption: the
sampled maximum at one frequency under-estimates the box's where a resonance moves past it)."""
REGULARISE = 1e-2
"""η of ab13md's perturbed matrix M + η‖M‖P (measured at 50 s: 1e-3 left 22-s calls, 1e-2 none
above 0.5 s; the certificate and the local descent take the bound back to the unperturbed M)."""
REGULARISE_FINE = 3e-3
"""η of the second pass at the highest values."""
REDUCE = 1e-2
"""Blocks whose balanced row and column are both below 1 % of the largest are left out of the
ab13md call (measured at 50 s: ab13md 2.3× faster, the peak unchanged)."""
N_PEAKS = 3
N_REFINE = 2
N_REPASS = 6
WHOLE_TIMEOUT_S = 10.0
"""Wall-clock limit [s] of a whole-matrix ab13md call in :func:`mu_at_time` (assumption: on the
46 s loop it took 0.3–1.5 s below the rigid band, where the peak sits at max-Q, and 3 s to
over 120 s in the first bending band; where it finished within 120 s, 35 of the 41 matrices
measured, it lowered the bound by at most 2.8 %)."""


# ------------------------------------------------------------------------------ μ of a matrix
def mu_certificate(Z, d, g) -> float:
    """The (D, G) upper bound of μ(Z) certified by the scalings ``d`` > 0 and ``g``.

    β = √λ_max(D⁻¹(Zᴴ D² Z + j(G Z − Zᴴ G))D⁻¹), D = diag(d), G = diag(g): then
    Zᴴ D² Z + j(G Z − Zᴴ G) − β² D² ≤ 0, and μ(Z) ≤ β (Fan, Tits & Doyle 1991) for every
    block structure whose blocks commute with D (d constant over a full block) and with G
    zero on the complex blocks and real on the real scalars.
    """
    Z = np.asarray(Z, dtype=complex)
    d = np.asarray(d, dtype=float)
    g = np.asarray(g, dtype=float)
    H = Z.conj().T @ (d[:, None] ** 2 * Z) + 1j * (g[:, None] * Z - Z.conj().T * g[None, :])
    H = H / d[:, None] / d[None, :]
    lam = float(np.linalg.eigvalsh(0.5 * (H + H.conj().T))[-1])
    return math.sqrt(max(lam, 0.0))


def _polish(Z, real, s0, gt0, iters: int = 40, temps=(1e-2, 1e-3, 1e-4)):
    """Local descent of the certified bound, all blocks 1×1, over s = log d and g̃ = g/d² (real
    scalars only): λ_max of Mtᴴ Mt + j(G̃ Mt − Mtᴴ G̃), Mt = D Z D⁻¹ (the matrix of
    :func:`mu_certificate`), smoothed by a log-sum-exp whose temperature (relative to λ)
    decreases over ``temps``, ``iters`` L-BFGS iterations each. Returns (d, g) of the best point
    met (smallest λ_max, the start at worst)."""
    from scipy.optimize import minimize

    n = Z.shape[0]
    ridx = np.flatnonzero(real)
    best = {"lam": math.inf, "p": None}

    def f(p, t):
        s = p[:n]
        gt = np.zeros(n)
        gt[ridx] = p[n:]
        Mt = np.exp(s)[:, None] * Z * np.exp(-s)[None, :]
        H = Mt.conj().T @ Mt + 1j * (gt[:, None] * Mt - Mt.conj().T * gt[None, :])
        if not np.all(np.isfinite(H)):
            return 1e300, np.zeros_like(p)
        lam, V = np.linalg.eigh(0.5 * (H + H.conj().T))
        top = lam[-1]
        if top < best["lam"]:
            best.update(lam=top, p=p.copy())
        e = np.exp((lam - top) / t)
        W = (V * (e / e.sum())) @ V.conj().T          # gradient of the smoothed λ_max
        Q = W @ Mt.conj().T
        R = W * gt[None, :]
        ds = (2.0 * np.real(np.einsum("ij,ji->i", Mt, Q) - np.einsum("ij,ji->i", Q, Mt))
              - 2.0 * np.imag(np.einsum("ij,ji->i", Mt, R) - np.einsum("ij,ji->i", R, Mt)))
        dg = -2.0 * np.imag(np.einsum("ij,ji->i", Mt, W))[ridx]
        return top + t * math.log(e.sum()), np.r_[ds, dg]

    p = np.r_[s0, gt0[ridx]]
    bounds = [(x - 30.0, x + 30.0) for x in s0] + [(None, None)] * ridx.size
    try:
        f(p, 1.0)
        for rel in temps:
            t = max(rel * abs(best["lam"]), 1e-14)
            minimize(f, best["p"], args=(t,), jac=True, method="L-BFGS-B", bounds=bounds,
                     options={"maxiter": iters})
    except (np.linalg.LinAlgError, ValueError, FloatingPointError, OverflowError):
        pass
    if best["p"] is None:
        return np.exp(s0), gt0 * np.exp(2.0 * s0)
    p = best["p"]
    d = np.exp(p[:n] - p[:n].max())
    gt = np.zeros(n)
    gt[ridx] = p[n:]
    return d, gt * d * d


def _osborne(Z, sweeps: int = 60) -> np.ndarray:
    """Diagonal d balancing the row and column sums of |D Z D⁻¹| off the diagonal (the
    Osborne/Perron scaling ab13md starts from), geometric mean 1."""
    A = np.abs(np.asarray(Z))
    A = A - np.diag(np.diag(A))
    A = A + 1e-14 * max(float(A.max()), 1e-300)
    logd = np.zeros(A.shape[0])
    for _ in range(sweeps):
        d = np.exp(logd)
        B = A * d[:, None] / d[None, :]
        logd += 0.5 * (np.log(B.sum(0)) - np.log(B.sum(1)))
    return np.exp(logd - logd.mean())


def _admissible(d, g, nblock, itype):
    """(d, g) made a scaling the certificate of :func:`mu_certificate` holds for, or None.

    d must be finite and positive and constant over each full complex block (D commutes with
    Δ); g must be finite, and is set to zero on the complex blocks (only a real scalar's G may
    be non-zero). A scaling a solver returns is used only through this check."""
    d = np.asarray(d, dtype=float).copy()
    g = np.asarray(g, dtype=float).copy()
    if not (np.all(np.isfinite(d)) and np.all(d > 0.0) and np.all(np.isfinite(g))):
        return None
    start = 0
    for size, kind in zip(nblock, itype):
        blk = slice(start, start + int(size))
        if kind == 2:
            g[blk] = 0.0
            if np.ptp(np.log(d[blk])) > 1e-9:
                return None
        start += int(size)
    return d, g


def _ab13md_scalings(Z, nblock, itype):
    """Slycot ``ab13md`` on Z: (its bound, d, g), or None if it failed or its scalings are not
    admissible (:func:`_admissible`)."""
    from slycot import ab13md
    from slycot.exceptions import SlycotError

    try:
        bound, d, g, _ = ab13md(Z, nblock, itype)
    except SlycotError:          # SlycotArithmeticError (INFO 5/6)
        return None
    dg = _admissible(d, g, nblock, itype)
    return None if dg is None else (float(bound), *dg)


def _ab13md_child(conn, Z, nblock, itype):
    conn.send(_ab13md_scalings(Z, nblock, itype))
    conn.close()


def _ab13md_scalings_limited(Z, nblock, itype, timeout_s: float | None):
    """:func:`_ab13md_scalings` given at most ``timeout_s`` of wall-clock time (None: no
    limit, in this process): run in a forked child that is killed when the time is up (SLICOT's
    line search has no iteration limit, so the call cannot be stopped from inside). Returns
    (result, timed_out)."""
    if timeout_s is None:
        return _ab13md_scalings(Z, nblock, itype), False
    import multiprocessing

    ctx = multiprocessing.get_context("fork")
    recv, send = ctx.Pipe(duplex=False)
    child = ctx.Process(target=_ab13md_child, args=(send, Z, nblock, itype), daemon=True)
    child.start()
    send.close()
    out, timed_out = None, False
    try:
        if recv.poll(timeout_s):
            out = recv.recv()
        else:
            timed_out = True
    except EOFError:             # the child died without an answer: no scalings
        pass
    finally:
        if child.is_alive():
            child.kill()
        child.join()
        recv.close()
    return out, timed_out


def mu_upper_bound(Z, nblock: Sequence[int], itype: Sequence[int],
                   regularise: float = REGULARISE, reduce: float = REDUCE,
                   polish: bool = True, whole: bool = True,
                   whole_timeout_s: float | None = None) -> tuple[float, dict]:
    """Certified mixed-μ upper bound of Z for the block structure (``nblock``, ``itype``:
    1 a real scalar, 2 a complex full block).

    Two runs of Slycot ``ab13md`` (its own Osborne start), each certified on the whole,
    unperturbed Z (:func:`mu_certificate`) and, with all blocks 1×1 and ``polish``, improved by
    :func:`_polish`; the smallest certificate is returned:

    * *reduced*: on Z + η‖Z‖P (η = ``regularise``, P a fixed pseudo-random complex matrix,
      ‖P‖ = 1; 0: Z itself) restricted, when all blocks are 1×1, to the blocks whose row or
      column of the Osborne-balanced |Z| reaches ``reduce`` times the largest (the others keep
      their Osborne D, and G = 0). Fast on the rank-deficient loop matrices; if it fails, the
      Osborne D with G = 0 is certified instead (the fallback);
    * *whole* (with ``whole``): on Z itself, all blocks. Why both: the perturbation and the
      reduction move the optimum of the (D, G) problem, and a descent from the reduced call's
      scalings can stay far from the optimum of Z (measured on rank-one matrices with real
      scalars, where the (D, G) bound equals μ: up to 21× μ from the reduced call alone, within
      10 % from the whole one). It can be slow on rank-deficient matrices (measured on the
      46 s loop: 0.3–1.5 s below the rigid band, 3 s to over 120 s in the first bending band;
      SLICOT's line search has no iteration limit), so ``whole_timeout_s`` (None: none) limits
      its wall-clock time and :func:`mu_at_time` runs it only where the peak could be.

    A single block: its exact μ (σ̄ of a complex block; |z| of a real scalar z if z is real,
    else 0).

    Returns
    -------
    bound, info
        ``info``: ``ab13md`` (the reduced call's value on its perturbed, reduced matrix; NaN if
        it failed), ``certified`` (its scalings on Z, before the descent), ``n_ab13md`` (blocks
        in that call), ``fallback`` (neither call gave admissible scalings: the Osborne D with
        G = 0 is certified instead), ``whole_ab13md``, ``whole_certified`` (the whole call's
        value and its scalings certified on Z; NaN if not run or failed), ``whole_time_s``,
        ``whole_timed_out`` (stopped at ``whole_timeout_s``),
        ``source`` (the call whose certificate is returned: ``"reduced"``, ``"whole"``,
        ``"fallback"``, or ``"exact"`` for a single block).
    """
    Z = np.atleast_2d(np.asarray(Z, dtype=complex))
    nblock = np.asarray(nblock, dtype=int)
    itype = np.asarray(itype, dtype=int)
    n = Z.shape[0]
    nan = float("nan")
    info = {"ab13md": nan, "certified": nan, "n_ab13md": 0, "fallback": False,
            "whole_ab13md": nan, "whole_certified": nan, "whole_time_s": 0.0,
            "whole_timed_out": False, "source": "exact"}
    if nblock.size == 1:
        if itype[0] == 2:
            return float(np.linalg.norm(Z, 2)), info
        z = Z[0, 0]
        return (float(abs(z.real)) if z.imag == 0.0 else 0.0), info
    if float(np.linalg.norm(Z, 2)) == 0.0:
        return 0.0, info
    scalar = bool(np.all(nblock == 1))
    real = itype == 1

    def certify(d, g):
        """The certificate of (d, g) on Z, and of the local descent from it."""
        c = mu_certificate(Z, d, g)
        if polish and scalar:
            d2, g2 = _polish(Z, real, np.log(d), g / d ** 2)
            c = min(c, mu_certificate(Z, d2, g2))
        return c

    # the reduced, regularised call
    d0 = _osborne(Z) if scalar else np.ones(n)
    kept = np.arange(nblock.size)
    if scalar and reduce > 0.0:
        B = np.abs(Z) * d0[:, None] / d0[None, :]
        coupling = np.maximum(np.linalg.norm(B, axis=0), np.linalg.norm(B, axis=1))
        mask = (coupling >= reduce * coupling.max()) | (itype == 2)
        if np.count_nonzero(mask) >= 2:
            kept = np.flatnonzero(mask)
    starts = np.r_[0, np.cumsum(nblock)[:-1]]
    rows = np.concatenate([np.arange(starts[i], starts[i] + nblock[i]) for i in kept])
    Zb = (d0[:, None] * Z / d0[None, :])[np.ix_(rows, rows)]      # balanced, reduced
    m = rows.size
    info["n_ab13md"] = int(kept.size)
    rng = np.random.default_rng(12345)
    P = rng.standard_normal((m, m)) + 1j * rng.standard_normal((m, m))
    P /= np.linalg.norm(P, 2)
    d, g = d0.copy(), np.zeros(n)
    same_as_whole = regularise == 0.0 and kept.size == nblock.size
    got = _ab13md_scalings(Zb + regularise * np.linalg.norm(Zb, 2) * P, nblock[kept],
                           itype[kept])
    if got is not None:          # D Zb D⁻¹ = (D D0) Z (D D0)⁻¹; G on Zb is D0 G D0 on Z
        info["ab13md"], dk, gk = got
        c = math.exp(-float(np.mean(np.log(dk))))
        d[rows] = d0[rows] * c * dk
        g[rows] = d0[rows] ** 2 * c * c * gk
    info["certified"] = mu_certificate(Z, d, g)
    best, info["source"] = certify(d, g), ("reduced" if got is not None else "fallback")

    # the whole, unregularised call (the reduced one already was, if η = 0 and none left out)
    if whole and not same_as_whole:
        t0 = _time.perf_counter()
        got_w, info["whole_timed_out"] = _ab13md_scalings_limited(Z, nblock, itype,
                                                                   whole_timeout_s)
        info["whole_time_s"] = _time.perf_counter() - t0
        if got_w is not None:
            info["whole_ab13md"], dw, gw = got_w
            info["whole_certified"] = mu_certificate(Z, dw, gw)
            c = certify(dw, gw)
            if c < best:
                best, info["source"] = c, "whole"
    info["fallback"] = got is None and not np.isfinite(info["whole_certified"])
    return best, info


def delay_weight(w_radps, half_s: float) -> np.ndarray:
    """w(ω) = 2 sin(ω h/2) for ω h ≤ π, else 2: the disc 1 + w δ_c, |δ_c| ≤ 1, holds
    e^{−jωΔ} for every |Δ| ≤ h (|e^{−jωΔ} − 1| = 2|sin(ωΔ/2)|)."""
    x = np.asarray(w_radps, dtype=float) * float(half_s)
    return np.where(x <= math.pi, 2.0 * np.sin(np.minimum(x, math.pi) / 2.0), 2.0)


# ---------------------------------------------------------------------------- the parameters
@dataclass(frozen=True)
class Box:
    """The uncertainty set normalised around the centre of each range.

    deviation_i = centre_i + half_i·δ_i, δ_i ∈ [−1, 1], for the real parameters ``names``;
    the delay deviation [s] = delay_centre_s + delay_half_s·δ_τ.
    """

    names: tuple
    centre: np.ndarray
    half: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    delay_centre_s: float
    delay_half_s: float

    def deviations(self, delta, delay_delta: float = 0.0) -> dict:
        """Deviation dict (:mod:`vega_model.uncertainty` names) of normalised δ and δ_τ."""
        d = {n: float(c + h * x) for n, c, h, x in zip(self.names, self.centre, self.half,
                                                          np.asarray(delta, float))}
        d[DELAY_NAME] = float(self.delay_centre_s + self.delay_half_s * delay_delta)
        return d


def parameter_box(uset, scale: float = 1.0) -> Box:
    """:class:`Box` of an uncertainty set, the half-widths × ``scale`` around the centres.

    Raises
    ------
    ValueError
        If a scaled relative deviation reaches −0.9 (no physical plant there).
    """
    names, c, h = [], [], []
    dc, dh = 0.0, 0.0
    for p in uset:
        mid, half = 0.5 * (p.lower + p.upper), 0.5 * (p.upper - p.lower) * float(scale)
        if p.kind == "relative" and mid - half <= -0.9:
            raise ValueError(f"{p.name}: the box scaled by {scale:g} reaches {mid - half:+.3f} "
                             f"(relative deviations must stay > -0.9)")
        if p.name == DELAY_NAME:
            dc, dh = mid, half
            continue
        names.append(p.name)
        c.append(mid)
        h.append(half)
    c, h = np.array(c), np.array(h)
    return Box(tuple(names), c, h, c - h, c + h, dc, dh)


MODE_STATES = {"psi_mode_1": ("q1", "q1_dot"), "psi_mode_2": ("q2", "q2_dot")}
"""States (:data:`vega_model.dynamics.STATES`) whose amplitude the fit's coordinates rescale by
the mode-shape factor 1 + δψ_i."""


def plant_matrix(context, t_s: float, deviations: Mapping[str, float],
                 input_names: Sequence[str], modal_scaling: bool = True) -> np.ndarray:
    """S = [[A, B], [C, 0]] of actuator + launcher (:func:`.margins.plant_loop_ss`) at the
    parameters of :func:`.margins.corner_plant`, shape (n + ny, n + 1).

    With ``modal_scaling`` the states of mode i are q_i' = (1 + δψ_i)·q_i (δψ_i the
    ``psi_mode_i`` deviation, which scales all of mode i's shapes): a similarity, every
    transfer function unchanged, that moves the whole mode-shape dependence onto mode i's
    input row ((1 + δψ_i)², rank one).
    """
    from vega_model.dynamics import STATES

    p, act, _ = M.corner_plant(context, t_s, deviations)
    A, B, C = M.plant_loop_ss(p, act, input_names)
    n, ny = A.shape[0], C.shape[0]
    if modal_scaling:
        t = np.ones(n)                   # x = diag(t) x'
        for name, states in MODE_STATES.items():
            for state in states:
                t[STATES.index(state)] = 1.0 / (1.0 + float(deviations.get(name, 0.0)))
        A, B, C = A * t[None, :] / t[:, None], B / t[:, None], C * t[None, :]
    S = np.zeros((n + ny, n + 1))
    S[:n, :n], S[:n, n:], S[n:, :n] = A, B, C
    return S


def axis_fit(S_of: Callable[[np.ndarray], np.ndarray], k: int, quadratic: Sequence[bool],
             points: Sequence[float] = AXIS_POINTS):
    """S(δ) ≈ S0 + Σ δ_i S_i + Σ_{quadratic} δ_i² S_ii from single-parameter sweeps.

    S0 = S(0) exactly (the centre plant); S_i (and S_ii) by least squares along axis i at
    δ_i ∈ ``points`` (the others 0): exact where the entries are polynomials of degree ≤ 1
    (≤ 2) in δ_i.

    Returns
    -------
    S0, lin (k, rows, cols), quad {i: (rows, cols)}
    """
    S0 = S_of(np.zeros(k))
    xs = np.asarray(points, dtype=float)
    lin, quad = [], {}
    for i in range(k):
        ys = []
        for x in xs:
            d = np.zeros(k)
            d[i] = x
            ys.append((S_of(d) - S0).ravel())
        X = np.stack([xs, xs * xs], 1) if quadratic[i] else xs[:, None]
        coef = np.linalg.lstsq(X, np.array(ys), rcond=None)[0]
        lin.append(coef[0].reshape(S0.shape))
        if quadratic[i]:
            quad[i] = coef[1].reshape(S0.shape)
    return S0, np.array(lin), quad


def pair_fit(S_of: Callable[[np.ndarray], np.ndarray], k: int, pairs) -> dict:
    """Bilinear coefficients S_ij of δ_i δ_j from the four vertices of each pair (the others
    0): (S(+,+) − S(+,−) − S(−,+) + S(−,−))/4, exact for the δ_i δ_j term (the terms in δ_i or
    δ_j alone cancel)."""
    out = {}
    for i, j in pairs:
        acc = 0.0
        for si, sj in ((1.0, 1.0), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0)):
            d = np.zeros(k)
            d[i], d[j] = si, sj
            acc = acc + si * sj * S_of(d)
        out[(i, j)] = acc / 4.0
    return out


# ------------------------------------------------------------------------------------ the LFT
@dataclass
class ParametricLFT:
    """S(δ) = S0 + Uc (I − Δ E)⁻¹ Δ Vxᵀ, Δ = diag(δ[param[j]]): one real scalar block per j.

    Block j reads z_j = Vx[:, j]ᵀ [x; u] + E[j]·w and returns w_j = δ_{param[j]}·z_j; column
    Uc[:, j] adds w_j to [ẋ; y]. E is nilpotent (inner blocks feed outer ones only), so the
    LFT is well posed for every Δ. ``copies`` = scalar blocks per parameter name (r_i).
    """

    n: int
    ny: int
    S0: np.ndarray
    Uc: np.ndarray
    Vx: np.ndarray
    E: np.ndarray
    param: np.ndarray
    names: tuple
    copies: dict

    @property
    def n_scalars(self) -> int:
        """Number of real 1×1 blocks."""
        return int(self.param.size)

    def matrix(self, delta) -> np.ndarray:
        """S_fit(δ): the fitted, truncated plant matrix the LFT represents."""
        N = self.n_scalars
        if N == 0:
            return self.S0.copy()
        dv = np.asarray(delta, dtype=float)[self.param]
        W = np.linalg.solve(np.eye(N) - dv[:, None] * self.E, dv[:, None] * self.Vx.T)
        return self.S0 + self.Uc @ W


def _psd_sqrt(W: np.ndarray, floor: float = 1e-10):
    """(W^½, W^−½) of a symmetric positive semi-definite W, eigenvalues floored at
    ``floor``·max."""
    lam, Q = np.linalg.eigh(0.5 * (W + W.T))
    lam = np.maximum(lam, floor * max(float(lam.max()), 1e-300))
    return (Q * np.sqrt(lam)) @ Q.T, (Q / np.sqrt(lam)) @ Q.T


def _factor(S, left, right, tol):
    """S ≈ U Vᵀ: SVD of left^½ S right^½ truncated at σ_j > tol·σ_1, mapped back."""
    P, sig, Qt = np.linalg.svd(left[0] @ S @ right[0], full_matrices=False)
    if sig.size == 0 or sig[0] <= 0.0:
        return np.zeros((S.shape[0], 0)), np.zeros((S.shape[1], 0))
    r = int(np.count_nonzero(sig > tol * sig[0]))
    s = np.sqrt(sig[:r])
    return left[1] @ (P[:, :r] * s), right[1] @ (Qt[:r].T * s)


def loop_sensitivities(S0: np.ndarray, n: int, F: np.ndarray, w: np.ndarray):
    """First-order loop change at the centre plant: dL(ω) = −a(ω)·dS·b(ω).

    a = F [C(jωI − A)⁻¹, I] (1 × (n + ny)), b = [(jωI − A)⁻¹B; 1] ((n + 1) × 1), with F (nw, ny)
    the controller row of :meth:`MuProblem.controller_row`; L0 = −F·C(jωI − A)⁻¹B.

    Returns
    -------
    a (nw, n + ny), b (nw, n + 1), L0 (nw,)
    """
    A, B, C = S0[:n, :n], S0[:n, n:], S0[n:, :n]
    jw = 1j * np.asarray(w, float)[:, None, None] * np.eye(n)
    X = np.linalg.solve(jw - A, np.broadcast_to(B.astype(complex), (len(w), n, 1)))[:, :, 0]
    Yt = np.linalg.solve((jw - A).transpose(0, 2, 1),
                         np.broadcast_to(C.T.astype(complex), (len(w), n, C.shape[0])))
    a = np.concatenate([np.einsum("ky,kny->kn", F, Yt), F], axis=1)
    b = np.concatenate([X, np.ones((len(w), 1))], axis=1)
    L0 = -np.einsum("ky,yn,kn->k", F, C, X)
    return a, b, L0


def build_lft(S0, lin, inner, names, n, weights, rank_tol=RANK_TOL, keep=None) -> ParametricLFT:
    """Factor the fit into real scalar blocks.

    S(δ) − S0 ≈ Σ_i δ_i·(S_i + Σ_{(j, S_ij) ∈ inner[i]} δ_j S_ij), realised parameter by
    parameter (Horner): each inner term S_ij = U Vᵀ gives blocks w = δ_j·Vᵀ[x; u]; then
    [S_i, U_ij, …] = Ub Vbᵀ gives the outer blocks of δ_i, which read [x; u] and the inner
    outputs. Each factorisation is a truncated SVD in the loop-weighted coordinates.

    Parameters
    ----------
    S0, lin
        Centre plant matrix and linear coefficients (k, rows, cols).
    inner
        {i: [(j, S_ij), …]}: second-order terms δ_i δ_j S_ij held by outer parameter i
        (j = i: the square).
    names
        Parameter names (len k).
    n
        Plant + actuator states.
    weights
        (Wl, Wr): symmetric positive semi-definite row and column weights of S.
    rank_tol
        Relative truncation of the weighted singular values.
    keep
        Bool per parameter (default all): a parameter not kept gets no block.
    """
    k = len(names)
    keep = [True] * k if keep is None else list(keep)
    rows, cols = S0.shape
    Wl, Wr = weights
    left, right = _psd_sqrt(Wl), _psd_sqrt(Wr)
    Uc, Vx, param, links = [], [], [], []
    copies = dict.fromkeys(names, 0)
    for i in range(k):
        if not keep[i]:
            continue
        first_inner, inner_U = len(param), []
        outer_lin = lin[i]
        for j, Sij in inner.get(i, ()):
            U2, V2 = _factor(Sij, left, right, rank_tol)
            direct = np.zeros((rows, U2.shape[1]))
            if j == i and U2.shape[1]:
                # product form: half of δ_i S_i along the square's input directions goes to
                # the inner copy, so that k(1 + aδ)² is realised as k(1 + aδ_a)(1 + aδ_b)
                direct = 0.5 * lin[i] @ V2 @ np.linalg.pinv(V2.T @ V2)
                outer_lin = outer_lin - direct @ V2.T
            for c in range(U2.shape[1]):
                Uc.append(direct[:, c])
                Vx.append(V2[:, c])
                param.append(j)
            copies[names[j]] += U2.shape[1]
            inner_U.append((U2, V2))
        r2 = len(param) - first_inner
        if r2:
            U2all = np.hstack([u for u, _ in inner_U])
            V2all = np.hstack([v for _, v in inner_U])
            ra = _psd_sqrt(V2all.T @ Wr @ V2all)
            rext = tuple(np.block([[r, np.zeros((cols, r2))], [np.zeros((r2, cols)), q]])
                         for r, q in zip(right, ra))
            Ub, Vb = _factor(np.hstack([outer_lin, U2all]), left, rext, rank_tol)
        else:
            Ub, Vb = _factor(lin[i], left, right, rank_tol)
        for c in range(Ub.shape[1]):
            for jj in range(r2):
                links.append((len(param), first_inner + jj, Vb[cols + jj, c]))
            Uc.append(Ub[:, c])
            Vx.append(Vb[:cols, c])
            param.append(i)
        copies[names[i]] += Ub.shape[1]
    N = len(param)
    E = np.zeros((N, N))
    for r_, c_, v_ in links:
        E[r_, c_] = v_
    return ParametricLFT(n, rows - n, S0, np.array(Uc, float).reshape(N, rows).T,
                         np.array(Vx, float).reshape(N, cols).T, E, np.array(param, int),
                         tuple(names), copies)


def interconnection(lft: ParametricLFT, F: np.ndarray, w: np.ndarray, delay_wt: np.ndarray,
                    cover_wt: np.ndarray | None = None) -> np.ndarray:
    """M(jω) seen by Δ = diag(the LFT's real scalars, δ_c [, δ_e]), shape (nw, N + 1 (+1), …).

    ẋ = A0 x + B0 u + Ux w, y = C0 x + Uy w, u = F(ω) y + w_c (+ w_e);
    z = Vxᵀ [x; u] + E w, z_c = w_τ(ω)·F y (so u = (1 + w_τ δ_c) F y: the delay disc),
    z_e = ε(ω)·u (the fit cover: the return difference 1 + L becomes 1 + L − ε δ_e).

    Parameters
    ----------
    lft
        The parametric LFT.
    F
        Controller row (nw, ny): u = F y closes the centre loop (L = −F G).
    w
        Frequencies [rad/s].
    delay_wt
        w_τ(ω) (:func:`delay_weight`).
    cover_wt
        ε(ω), or None for no cover block.
    """
    n, N = lft.n, lft.n_scalars
    A0, B0, C0 = lft.S0[:n, :n], lft.S0[:n, n:], lft.S0[n:, :n]
    Ux, Uy = lft.Uc[:n], lft.Uc[n:]
    Vxx, Vxu = lft.Vx[:n], lft.Vx[n]
    nw = len(w)
    nin = N + 1 + (cover_wt is not None)
    BF = B0[None, :, :] * F[:, None, :]                                 # (nw, n, ny)
    Acl = A0[None] + BF @ C0
    rhs = np.zeros((nw, n, nin), dtype=complex)
    rhs[:, :, :N] = Ux[None] + BF @ Uy[None]
    rhs[:, :, N:] = B0[None, :, :1]
    X = np.linalg.solve(1j * np.asarray(w, float)[:, None, None] * np.eye(n) - Acl, rhs)
    Y = np.einsum("yn,knj->kyj", C0, X)
    Y[:, :, :N] += Uy[None]
    Fy = np.einsum("ky,kyj->kj", F, Y)
    u = Fy.copy()
    u[:, N:] += 1.0
    Mz = np.zeros((nw, nin, nin), dtype=complex)
    Mz[:, :N] = np.einsum("nj,knm->kjm", Vxx, X) + Vxu[None, :, None] * u[:, None, :]
    Mz[:, :N, :N] += lft.E[None]
    Mz[:, N] = np.asarray(delay_wt)[:, None] * Fy
    if cover_wt is not None:
        Mz[:, N + 1] = np.asarray(cover_wt)[:, None] * u
    return Mz


# ------------------------------------------------------------------------ frequency responses
class _Responses:
    """Loops L = −F·C(jωI − A)⁻¹B of a stack of plant matrices at any frequencies
    (eigen-decomposition once per plant; direct solves where it is ill-conditioned, as
    :func:`.margins._transfer`)."""

    def __init__(self, S_stack: np.ndarray, n: int):
        self.S = np.asarray(S_stack, dtype=float)
        self.n = n
        lam, V = np.linalg.eig(self.S[:, :n, :n])
        self.ok = np.linalg.cond(V) < 1e8
        self.lam = lam
        Vs = np.where(self.ok[:, None, None], V, np.eye(n)[None])
        self.Wb = np.linalg.solve(Vs, self.S[:, :n, n:].astype(complex))[:, :, 0]
        self.CV = np.einsum("syn,snm->sym", self.S[:, n:, :n], Vs)

    def loops(self, F: np.ndarray, w: np.ndarray) -> np.ndarray:
        """L[s, k] at the frequencies ``w`` with the controller row F (nw, ny)."""
        w = np.asarray(w, dtype=float)
        R = 1.0 / (1j * w[None, :, None] - self.lam[:, None, :])
        G = np.einsum("syn,skn->sky", self.CV, R * self.Wb[:, None, :])
        n = self.n
        for s in np.flatnonzero(~self.ok):
            G[s] = M._transfer(self.S[s, :n, :n], self.S[s, :n, n:], self.S[s, n:, :n],
                               1j * w)[:, :, 0]
        return -np.einsum("ky,sky->sk", F, G)


def mu_frequency_grid(band1_radps: tuple[float, float], band2_radps: tuple[float, float],
                      omega_centre_radps: Sequence[float], zeta: float, dt_s: float,
                      n_log: int = 24, n_band: int = 10,
                      w_min_radps: float = 0.01) -> np.ndarray:
    """The μ grid [rad/s]: ``n_log`` log-spaced points from ``w_min_radps`` to just below the
    Nyquist frequency π/T; ``n_band`` log-spaced over each bending band; 7 at each centre mode
    frequency, ω_c·(1 + ζ·{0, ±0.5, ±1.5, ±3}) (M's lightly damped centre poles)."""
    top = math.pi / dt_s * (1.0 - 1e-9)
    parts = [np.geomspace(w_min_radps, top, n_log), np.geomspace(*band1_radps, n_band),
             np.geomspace(*band2_radps, n_band)]
    offsets = np.array([-3.0, -1.5, -0.5, 0.0, 0.5, 1.5, 3.0]) * zeta
    for wc in omega_centre_radps:
        parts.append(float(wc) * (1.0 + offsets))
    w = np.unique(np.concatenate(parts))
    return w[(w >= w_min_radps) & (w <= top)]


def _local_maxima(mu: np.ndarray, count: int) -> list[int]:
    j = np.arange(mu.size)
    peaks = j[np.r_[True, mu[1:] >= mu[:-1]] & np.r_[mu[:-1] >= mu[1:], True]]
    return [int(p) for p in peaks[np.argsort(-mu[peaks])][:count]]


# -------------------------------------------------------------------------------- the problem
@dataclass
class MuProblem:
    """One frozen time's LFT, controller and grid (:func:`mu_problem`)."""

    t_s: float
    context: object
    box: Box
    input_names: tuple
    K: tuple
    sign: float
    dt_s: float
    delay_centre_s: float
    v_sched_mps: float
    clamped: bool
    lft: ParametricLFT
    w_radps: np.ndarray
    weights: tuple
    influence: dict
    cross_terms: list
    modal_scaling: bool

    def plant(self, delta) -> np.ndarray:
        """The true plant matrix S(δ) (the fit's coordinates)."""
        return plant_matrix(self.context, self.t_s, self.box.deviations(delta),
                            self.input_names, self.modal_scaling)

    def controller_row(self, w) -> np.ndarray:
        """F(ω) = s·K(e^{jωT})·H(jω)·e^{−jωτ₀}, (nw, ny): u = F y closes the centre loop."""
        w = np.asarray(w, dtype=float)
        Kr = M.discrete_response(*self.K, w, self.dt_s)[:, 0, :]
        return self.sign * Kr * (M.zoh_response(w, self.dt_s)
                                 * np.exp(-1j * w * self.delay_centre_s))[:, None]

    def structure(self, cover: bool) -> tuple[np.ndarray, np.ndarray]:
        """(nblock, itype) for ab13md: the real scalars, the delay disc [, the cover]."""
        nb = np.ones(self.lft.n_scalars + 1 + bool(cover), dtype=int)
        it = np.ones(nb.size, dtype=int)
        it[self.lft.n_scalars:] = 2
        return nb, it

    def closed_loop_matrix(self, w, cover_wt=None) -> np.ndarray:
        """M(jω) at ``w`` (:func:`interconnection`)."""
        w = np.asarray(w, dtype=float)
        return interconnection(self.lft, self.controller_row(w), w,
                               delay_weight(w, self.box.delay_half_s), cover_wt)


def mu_problem(table, context, t_s: float, uset=None, *, box_scale: float = 1.0,
               quadratic: Sequence[str] = QUADRATIC, rank_tol: float = RANK_TOL,
               min_influence: float = MIN_INFLUENCE, cross_min: float = CROSS_MIN,
               max_cross: int = MAX_CROSS, modal_scaling: bool = True, n_log: int = 24,
               n_band: int = 10) -> MuProblem:
    """Fit and factor the LFT of the uncertainty set at flight time ``t_s`` (module docstring).

    Parameters
    ----------
    table
        Controller table (:func:`vega_gnc.controller_table.load_controller_table`); flown as
        :func:`.margins.flown_controller` at the nominal velocity of ``t_s``.
    context
        :class:`vega_model.parameters.ModelContext`.
    t_s
        Frozen flight time [s].
    uset
        :class:`vega_model.uncertainty.UncertaintySet` (default: the vehicle's).
    box_scale
        Half-widths of every range × this, around the centres.
    quadratic, rank_tol, min_influence, cross_min, max_cross
        See :data:`QUADRATIC`, :data:`RANK_TOL`, :data:`MIN_INFLUENCE`, :data:`CROSS_MIN`,
        :data:`MAX_CROSS`.
    modal_scaling
        Fit in the mode-shape-scaled coordinates (:func:`plant_matrix`).
    n_log, n_band
        Grid density (:func:`mu_frequency_grid`).
    """
    from vega_model.uncertainty import UncertaintySet

    uset = uset if uset is not None else UncertaintySet.from_vehicle(context.vehicle)
    box = parameter_box(uset, box_scale)
    k = len(box.names)
    names = tuple(table.input_names)
    p_nom = context.parameters(float(t_s))
    K, v_sched, clamped = M.flown_controller(table, p_nom.v_mps)

    def S_of(delta):
        return plant_matrix(context, t_s, box.deviations(delta), names, modal_scaling)

    S0, lin, quad = axis_fit(S_of, k, [nm in quadratic for nm in box.names])
    n = S0.shape[1] - 1
    p_c = M.corner_plant(context, t_s, box.deviations(np.zeros(k)))[0]
    bands = []
    for i, w0 in enumerate(p_nom.omega_radps, start=1):
        lo, hi = (box.lower[box.names.index(f"bending_frequency_{i}")],
                  box.upper[box.names.index(f"bending_frequency_{i}")])
        bands.append((M.BAND[0] * (1.0 + lo) * w0, M.BAND[1] * (1.0 + hi) * w0))
    w = mu_frequency_grid(bands[0], bands[1], p_c.omega_radps, p_c.zeta, table.dt_s,
                          n_log, n_band)
    problem = MuProblem(float(t_s), context, box, names, K, float(table.measurement_sign),
                        float(table.dt_s), M.total_delay_s(context.vehicle, box.delay_centre_s),
                        float(v_sched), bool(clamped), None, w, None, {}, [], modal_scaling)
    a, b, L0 = loop_sensitivities(S0, n, problem.controller_row(w), w)
    inv = 1.0 / np.maximum(np.abs(1.0 + L0), 1e-12)
    lw = np.log(w)
    quad_w = np.gradient(lw) / (lw[-1] - lw[0])           # ∫ … d log ω over the grid
    Wl = np.real(np.einsum("k,ki,kj->ij", quad_w * inv, np.conj(a), a))
    Wr = np.real(np.einsum("k,ki,kj->ij", quad_w * inv, b, np.conj(b)))

    def infl(Sm):
        return float(np.max(np.abs(np.einsum("ki,ij,kj->k", a, Sm, b)) * inv))

    influence = [infl(lin[i]) + (infl(quad[i]) if i in quad else 0.0) for i in range(k)]
    keep = [x > 0.0 and x >= min_influence for x in influence]
    cand = [(i, j) for i in range(k) for j in range(i + 1, k) if keep[i] and keep[j]]
    cross = pair_fit(S_of, k, cand) if max_cross > 0 else {}
    ranked = sorted(((infl(Sij), ij) for ij, Sij in cross.items()), reverse=True)
    chosen = [ij for x, ij in ranked[:max_cross] if x >= cross_min]
    inner = {i: [(i, quad[i])] for i in quad if keep[i]}
    lin_rank = [int(np.linalg.matrix_rank(lin[i], 1e-9 * max(np.abs(lin[i]).max(), 1e-300)))
                for i in range(k)]
    for i, j in chosen:                   # the pair's term goes to the larger outer factor
        outer, other = (i, j) if lin_rank[i] >= lin_rank[j] else (j, i)
        inner.setdefault(outer, []).append((other, cross[(i, j)]))
    problem.lft = build_lft(S0, lin, inner, box.names, n, (Wl, Wr), rank_tol, keep)
    problem.weights = (Wl, Wr)
    problem.influence = dict(zip(box.names, influence))
    problem.cross_terms = [(box.names[i], box.names[j]) for i, j in chosen]
    return problem


# ------------------------------------------------------------------------------ the fit error
@dataclass
class Validation:
    """Validation sample of the fit (:func:`validate`)."""

    delta: np.ndarray
    vertex_parameters: tuple
    true: _Responses
    fit: _Responses
    matrix_rel: float
    worst: dict

    def errors(self, F: np.ndarray, w: np.ndarray):
        """(|L_true − L_fit|, |L_true − L_fit|/|1 + L_true|) per sample and frequency; the
        largest ratio is kept in ``worst`` (value, frequency)."""
        Lt, Lf = self.true.loops(F, w), self.fit.loops(F, w)
        err = np.abs(Lt - Lf)
        rel = err / np.maximum(np.abs(1.0 + Lt), 1e-300)
        j = np.unravel_index(int(np.argmax(rel)), rel.shape)
        if rel[j] > self.worst["loop_rel"]:
            self.worst.update(loop_rel=float(rel[j]), w_radps=float(w[j[1]]))
        return err, rel

    def cover(self, controller_row: Callable[[np.ndarray], np.ndarray], w: np.ndarray,
              factor: float = COVER_FACTOR, smooth_dec: float = COVER_SMOOTH_DEC) -> np.ndarray:
        """ε(ω) = ``factor`` × the largest |L_true − L_fit| of the sample within ±``smooth_dec``
        decades of ω, the error evaluated at 9 points across that window around every ω (a
        resonance between two points of ``w`` is caught); ``controller_row`` is
        :meth:`MuProblem.controller_row`."""
        w = np.asarray(w, dtype=float)
        lw = np.log10(w)
        dense = 10.0 ** np.unique(np.concatenate(
            [np.linspace(x - smooth_dec, x + smooth_dec, 9) for x in lw]))
        err, _ = self.errors(controller_row(dense), dense)
        emax, ld = err.max(axis=0), np.log10(dense)
        return factor * np.array([emax[np.abs(ld - x) <= smooth_dec + 1e-12].max() for x in lw])


def validate(problem: MuProblem, n_validate: int = N_VALIDATE,
             n_vertex_parameters: int = N_VERTEX_PARAMETERS, seed: int = 0,
             n_sweep: int = N_SWEEP) -> Validation:
    """The validation sample: ``n_validate`` uniform points of the box and all vertices of the
    ``n_vertex_parameters`` parameters of largest loop influence (the others at random
    vertices), seeded; the matrix-level error max ‖S − S_fit‖/max ‖S − S0‖ in the
    loop-weighted Frobenius norm."""
    box, lft = problem.box, problem.lft
    k = len(box.names)
    rng = np.random.default_rng(seed)
    infl = np.array([problem.influence[nm] for nm in box.names])
    top = [int(i) for i in np.argsort(-infl)[:min(n_vertex_parameters, k)]]
    n_vert = 2 ** len(top)
    D = rng.uniform(-1.0, 1.0, size=(n_validate + n_vert, k))
    D[n_validate:] = rng.choice([-1.0, 1.0], size=(n_vert, k))
    grid = np.array(np.meshgrid(*[[-1.0, 1.0]] * len(top), indexing="ij"))
    D[n_validate:, top] = grid.reshape(len(top), -1).T
    # bending sweeps: the resonance moves through the grid with its frequency deviation, the
    # fit error peaks where it sits; a vertex sample alone misses it (measured: fresh plants
    # up to 2.3× the pointwise cover of the vertex sample in the bending bands)
    sweeps = []
    for mode in (1, 2):
        if f"bending_frequency_{mode}" not in box.names:
            continue
        i_w = box.names.index(f"bending_frequency_{mode}")
        i_s = box.names.index(f"psi_mode_{mode}") if f"psi_mode_{mode}" in box.names else None
        for dw in np.linspace(-1.0, 1.0, n_sweep):
            for ds in ((-1.0, 0.0, 1.0) if i_s is not None else (0.0,)):
                d = rng.choice([-1.0, 1.0], size=k)
                d[i_w] = dw
                if i_s is not None:
                    d[i_s] = ds
                sweeps.append(d)
    if sweeps:
        D = np.vstack([D, np.array(sweeps)])
    S_true = np.array([problem.plant(d) for d in D])
    S_fit = np.array([lft.matrix(d) for d in D])
    Lh, Rh = _psd_sqrt(problem.weights[0])[0], _psd_sqrt(problem.weights[1])[0]
    num = np.linalg.norm(Lh[None] @ (S_true - S_fit) @ Rh[None], axis=(1, 2))
    den = np.linalg.norm(Lh[None] @ (S_true - lft.S0[None]) @ Rh[None], axis=(1, 2))
    return Validation(D, tuple(box.names[i] for i in top), _Responses(S_true, lft.n),
                      _Responses(S_fit, lft.n), float(num.max() / max(den.max(), 1e-300)),
                      {"loop_rel": 0.0, "w_radps": float("nan")})


# ------------------------------------------------------------------------------- the analysis
def mu_at_time(table, context, t_s: float, uset=None, *, box_scale: float = 1.0,
               cover: bool = True, cover_factor: float = COVER_FACTOR, seed: int = 0,
               n_validate: int = N_VALIDATE,
               n_vertex_parameters: int = N_VERTEX_PARAMETERS, w_radps=None,
               n_peaks: int = N_PEAKS, n_refine: int = N_REFINE, n_repass: int = N_REPASS,
               whole: bool = True, whole_timeout_s: float | None = WHOLE_TIMEOUT_S,
               **lft_options) -> dict:
    """μ upper bound of the flown frozen loop at ``t_s`` over the uncertainty set.

    Parameters
    ----------
    table, context, t_s, uset, box_scale
        As :func:`mu_problem`.
    cover, cover_factor
        Add the fit-error cover block, ε(ω) = ``cover_factor`` × the largest |L_true − L_fit|
        of the validation sample at ω.
    seed
        Seed of the validation sample.
    n_validate, n_vertex_parameters
        Validation sample (:func:`validate`).
    w_radps
        Frequencies [rad/s] instead of :func:`mu_frequency_grid` (no refinement then).
    n_peaks, n_refine, n_repass
        Refinement around the highest local maxima; the second ab13md pass
        (:data:`REGULARISE_FINE`) at the ``n_repass`` highest values.
    whole
        The second pass also runs ab13md on the whole, unregularised matrix
        (:func:`mu_upper_bound`) and is repeated on the next ``n_repass`` highest values until
        the peak is a value that has had it; without, one second pass as before.
    whole_timeout_s
        Wall-clock limit of each whole-matrix call (:data:`WHOLE_TIMEOUT_S`; None: none).
        Where it stops a call the reduced call's certificate stands; the result then depends
        on the machine's speed (counted in ``whole``'s ``n_timeout``).
    **lft_options
        Passed to :func:`mu_problem` (``quadratic``, ``rank_tol``, ``min_influence``,
        ``cross_min``, ``max_cross``, ``modal_scaling``, ``n_log``, ``n_band``).

    Returns
    -------
    dict
        ``t_s``, ``v_sched_mps``, ``clamped``; ``mu_peak``, ``w_peak_radps``,
        ``robust_margin`` (1/μ_peak: the fraction of the box, around its centre, that the bound
        guarantees; inf if μ_peak = 0); ``centre_stable``, ``centre_max_abs_eig`` (exact
        sampled-data loop of the centre plant); ``fit_error`` (``loop_rel``,
        ``loop_rel_w_radps``, ``matrix_rel``, ``n_samples``, ``n_vertices``,
        ``vertex_parameters``, ``covered``, ``cover_factor``); ``aliasing_centre_rel``;
        ``n_blocks`` (ab13md's blocks), ``n_real_scalars``, ``ranks`` (scalar blocks per
        parameter), ``cross_terms``, ``influence``; ``w_radps``, ``mu_upper`` (the bound per
        frequency), ``mu_ab13md`` (ab13md's own scalings certified, before the local descent);
        ``n_fallback`` (ab13md failures, certified fallbacks); ``whole`` (``n_calls``: values
        that had the whole-matrix call, ``n_better``: where its certificate was the smaller,
        ``time_s``: its ab13md time, ``n_timeout``: calls stopped at ``whole_timeout_s``);
        ``time_s``.
    """
    clock = [_time.perf_counter()]
    explicit = w_radps is not None
    problem = mu_problem(table, context, t_s, uset, box_scale=box_scale, **lft_options)
    if explicit:
        problem.w_radps = np.unique(np.asarray(w_radps, dtype=float))
    val = validate(problem, n_validate, n_vertex_parameters, seed)
    clock.append(_time.perf_counter())
    nb, it = problem.structure(cover)
    fallbacks = [0]
    whole_calls = {"n": 0, "better": 0, "time_s": 0.0, "timeout": 0}

    def evaluate(ws, regularise=REGULARISE, whole_call=False):
        F = problem.controller_row(ws)
        val.errors(F, ws)
        eps = val.cover(problem.controller_row, ws, cover_factor) if cover else None
        Ms = interconnection(problem.lft, F, ws, delay_weight(ws, problem.box.delay_half_s),
                             eps)
        out = [mu_upper_bound(Z, nb, it, regularise, whole=whole_call,
                              whole_timeout_s=whole_timeout_s) for Z in Ms]
        fallbacks[0] += sum(o[1]["fallback"] for o in out)
        if whole_call:
            whole_calls["n"] += len(out)
            whole_calls["better"] += sum(o[1]["source"] == "whole" for o in out)
            whole_calls["time_s"] += sum(o[1]["whole_time_s"] for o in out)
            whole_calls["timeout"] += sum(o[1]["whole_timed_out"] for o in out)
        return np.array([o[0] for o in out]), np.array([o[1]["certified"] for o in out])

    w = problem.w_radps
    mu, mu_ab = evaluate(w)
    for _ in range(0 if explicit else n_refine):
        new = set()
        for j in _local_maxima(mu, n_peaks):
            if j > 0:
                new.add(math.sqrt(w[j - 1] * w[j]))
            if j < w.size - 1:
                new.add(math.sqrt(w[j] * w[j + 1]))
        new_w = np.array(sorted(new))
        mu_new, ab_new = evaluate(new_w)
        order = np.argsort(np.r_[w, new_w])
        w, mu, mu_ab = (np.r_[w, new_w][order], np.r_[mu, mu_new][order],
                        np.r_[mu_ab, ab_new][order])
    # second pass (η of REGULARISE_FINE, and with ``whole`` ab13md on the whole matrix) at
    # the highest values, repeated on the next highest until the peak is a value that has had
    # it: a frequency whose first bound was loose rises to the top and gets the second pass,
    # so the reported peak never rests on the first pass alone
    checked = np.zeros(w.size, dtype=bool)
    while n_repass > 0 and not checked[int(np.argmax(mu))]:
        top = [j for j in np.argsort(-mu) if not checked[j]][:n_repass]
        mu2, _ = evaluate(w[top], REGULARISE_FINE, whole)
        mu[top] = np.minimum(mu[top], mu2)
        checked[top] = True
        if not whole:
            break
    clock.append(_time.perf_counter())

    # the centre loop: exact sampled-data stability; the aliases the μ loop leaves out
    lft, n = problem.lft, problem.lft.n
    A, B, C = lft.S0[:n, :n], lft.S0[:n, n:], lft.S0[n:, :n]
    model = M.sampled_data_model(A, B, problem.dt_s, problem.delay_centre_s)
    stab = M.sampled_data_stability(model, C, problem.K, problem.sign, nyquist=False)
    F = problem.controller_row(w)
    L_ce = -np.sum(F * M.ss_response(A, B, C, np.zeros((C.shape[0], 1)), w)[:, :, 0], axis=1)
    Kr = M.discrete_response(*problem.K, w, problem.dt_s)[:, 0, :]
    Gd = M.sampled_data_response(A, B, C, problem.dt_s, problem.delay_centre_s, w, model)
    L_d = -problem.sign * np.sum(Kr * Gd[:, :, 0], axis=1)
    j = int(np.argmax(mu))
    mu_peak = float(mu[j])
    clock.append(_time.perf_counter())
    return {
        "t_s": float(t_s), "v_sched_mps": problem.v_sched_mps, "clamped": problem.clamped,
        "mu_peak": mu_peak, "w_peak_radps": float(w[j]),
        "robust_margin": (1.0 / mu_peak) if mu_peak > 0.0 else math.inf,
        "centre_stable": bool(stab["n_unstable"] == 0),
        "centre_max_abs_eig": float(stab["max_abs_eig"]),
        "fit_error": {"loop_rel": val.worst["loop_rel"],
                      "loop_rel_w_radps": val.worst["w_radps"],
                      "matrix_rel": val.matrix_rel, "n_samples": int(val.delta.shape[0]),
                      "n_vertices": 2 ** len(val.vertex_parameters),
                      "vertex_parameters": list(val.vertex_parameters),
                      "covered": bool(cover), "cover_factor": float(cover_factor)},
        "aliasing_centre_rel": float(np.max(np.abs(L_d - L_ce) / np.abs(1.0 + L_d))),
        "n_blocks": int(nb.size), "n_real_scalars": lft.n_scalars,
        "ranks": dict(lft.copies),
        "cross_terms": [list(p) for p in problem.cross_terms],
        "influence": dict(problem.influence), "box_scale": float(box_scale),
        "w_radps": w, "mu_upper": mu, "mu_ab13md": mu_ab, "n_fallback": int(fallbacks[0]),
        "whole": {"n_calls": whole_calls["n"], "n_better": whole_calls["better"],
                  "time_s": whole_calls["time_s"], "n_timeout": whole_calls["timeout"]},
        "time_s": {"lft": clock[1] - clock[0], "mu": clock[2] - clock[1],
                   "centre": clock[3] - clock[2], "total": clock[3] - clock[0]},
    }
