"""The nonlinear plant's RK4 frame, compiled (numba): the same floating-point operations as
:meth:`vega_model.dynamics.NonlinearModel.rk4_step`, bit for bit.

The plant node integrates one 10 ms frame per call: ten RK4 steps of 1 ms, four derivative
evaluations each (thesis Ch. 2 model, :class:`vega_model.dynamics.NonlinearModel`). In plain
Python one step costs ≈ 5.5 µs; compiled it costs ≈ 0.2 µs. The numbers do not change:

* every expression keeps the operand order of :class:`~vega_model.dynamics.NonlinearModel`
  (numba compiles Python's left-to-right evaluation; no ``fastmath``, so LLVM neither
  reassociates nor contracts a multiply and an add into an FMA);
* ``sin``, ``cos``, ``atan2`` and ``sqrt`` are the C library's, the functions CPython's ``math``
  module calls;
* ``math.hypot`` is not the C library's in CPython (3.10+: its own correctly rounded
  ``vector_norm``); :func:`_hypot` is that algorithm for two arguments as CPython 3.11 (the
  venv's Python) has it, subnormal branch included, with the exact product computed by
  Dekker's split (both error-free, so the results are equal);
* the Mach tables are read as :class:`vega_model.aero.ScalarTable` reads them (itself
  bit-identical to ``numpy.interp``).

tests/model/test_nonlinear_kernel.py checks all of this against the plain-Python code on
random states and inputs, and tests/sim/test_closed_loop.py checks the whole run.

Compiled on first use and cached on disk next to this file (``cache=True``, ``__pycache__``):
the first process after a change compiles for ≈ 1.5 s; a process that finds the cache pays
≈ 0.15 s of CPU for ``import numba`` and ≈ 0.2 s to load it (measured 2026-11-27). The plant
normally runs the same function compiled ahead of time by ``make setup`` instead
(:mod:`vega_model.kernels`, no numba in the process); this JIT function is the fallback and
the reference the tests hold the ahead-of-time one to. The kernel's inputs are built by
:mod:`vega_model.kernel_inputs` (re-exported here). See docs/MONTE_CARLO.md §8 "Speed".
"""

from __future__ import annotations

import math

import numba

from vega_model.kernel_inputs import CONSTANTS, MachTables, entry_constants, mach_tables

__all__ = ["CONSTANTS", "entry_constants", "MachTables", "mach_tables", "rk4_frame"]

_jit = numba.njit(cache=True, nogil=True)

_DBL_MIN = 2.2250738585072014e-308
_SPLIT = 134217729.0                       # 2**27 + 1: Veltkamp-Dekker splitting constant


@_jit
def _two_prod(x, y):
    """(x·y rounded, its exact error) — Dekker's product (|x|, |y| < 1 here: no overflow)."""
    z = x * y
    c = _SPLIT * x
    xh = c - (c - x)
    xl = x - xh
    c = _SPLIT * y
    yh = c - (c - y)
    yl = y - yh
    return z, ((xh * yh - z) + xh * yl + xl * yh) + xl * yl


@_jit
def _norm2(a, b, mx):
    """CPython's ``vector_norm`` for two non-negative finite values with max ``mx`` > 0."""
    _, max_e = math.frexp(mx)
    if max_e < -1023:                      # subnormal: ldexp(1, -max_e) would overflow;
        csum, frac = 1.0, 0.0              # CPython 3.11 divides by the max instead
        for x in (a, b):
            x /= mx
            x = x * x
            old = csum
            csum += x
            frac += (old - csum) + x
        return mx * math.sqrt(csum - 1.0 + frac)
    scale = math.ldexp(1.0, -max_e)
    csum, frac1, frac2 = 1.0, 0.0, 0.0
    for x in (a, b):
        x *= scale
        hi, lo = _two_prod(x, x)
        s = csum + hi
        frac2 += (csum - s) + hi
        csum = s
        frac1 += lo
    h = math.sqrt(csum - 1.0 + (frac1 + frac2))
    hi, lo = _two_prod(-h, h)
    s = csum + hi
    frac2 += (csum - s) + hi
    csum = s
    frac1 += lo
    x = csum - 1.0 + (frac1 + frac2)
    h += x / (2.0 * h)
    return h / scale


@_jit
def _hypot(x, y):
    """``math.hypot(x, y)`` of CPython 3.10+ (correctly rounded), bit for bit."""
    a, b = abs(x), abs(y)
    if math.isinf(a) or math.isinf(b):
        return math.inf
    if math.isnan(a) or math.isnan(b):
        return math.nan
    mx = a if a >= b else b
    if mx == 0.0:
        return mx
    return _norm2(a, b, mx)


@_jit
def _lookup(xs, ys, slopes, v):
    """:meth:`vega_model.aero.ScalarTable.__call__`."""
    n = xs.shape[0]
    if v >= xs[n - 1]:
        return ys[n - 1]
    if v <= xs[0]:
        return ys[0]
    if v != v:
        return v
    lo, hi = 0, n                          # bisect_right(xs, v) - 1
    while lo < hi:
        mid = (lo + hi) // 2
        if v < xs[mid]:
            hi = mid
        else:
            lo = mid + 1
    j = lo - 1
    if xs[j] == v:
        return ys[j]
    return slopes[j] * (v - xs[j]) + ys[j]


@_jit
def _rates(c, nx, ny, ns, ax, ay, asl, theta, theta_dot, z_dot, q1, q2, q1d, q2d,
           wind, beta, fnx, fnz, jn_bdd, lc_fnz, modal, in1, in2):
    """θ̈, z̈, q̈1, q̈2: ``rates`` of :class:`vega_model.dynamics.NonlinearModel`."""
    v, a, s_ref, half_rho, d, T, m, J = c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]
    tp0, tp1, rp0, rp1 = c[9], c[10], c[11], c[12]
    neg_t, lc_t = c[14], c[15]
    mode1_q, mode1_qd, mode2_q, mode2_qd, k_cf = c[19], c[20], c[21], c[22], c[23]
    st, ct = math.sin(theta), math.cos(theta)
    vx = v - theta_dot * d * st
    vz = z_dot - wind - theta_dot * d * ct
    alpha = math.atan2(vx * st + vz * ct, vx * ct - vz * st)
    airspeed = _hypot(vx, vz)
    mach = airspeed / a
    qbar_s = half_rho * airspeed * airspeed * s_ref
    cna = _lookup(nx, ny, ns, mach)
    ca = _lookup(ax, ay, asl, mach)
    sa = math.sin(alpha)
    normal = qbar_s * (cna * sa * math.cos(alpha) + k_cf * sa * abs(sa))
    axial = qbar_s * ca
    beta_eff = beta - (rp0 * q1 + rp1 * q2)
    offset = tp0 * q1 + tp1 * q2
    ce, se = math.cos(beta_eff), math.sin(beta_eff)
    fx = T * ce - axial + fnx
    fz = neg_t * se - normal + fnz
    moment = d * normal + T * ce * offset - lc_t * se - jn_bdd + lc_fnz
    return (moment / J,
            (-fx * st + fz * ct) / m,
            mode1_q * q1 - mode1_qd * q1d + tp0 * modal + in1,
            mode2_q * q2 - mode2_qd * q2d + tp1 * modal + in2)


@_jit
def _rk4_step(c, nx, ny, ns, ax, ay, asl, x, beta, beta_dd, wind, beta_d, h):
    """:meth:`vega_model.dynamics.NonlinearModel.rk4_step` on ``x`` (8 floats, in place)."""
    lc, neg_mn_ln, neg_t, jn, jn_rp0, jn_rp1 = c[8], c[13], c[14], c[16], c[17], c[18]
    # NonlinearModel's ``inputs``
    sb, cb = math.sin(beta), math.cos(beta)
    fnx = neg_mn_ln * (beta_dd * sb + beta_d * beta_d * cb)
    fnz = neg_mn_ln * (beta_dd * cb - beta_d * beta_d * sb)
    modal = neg_t * sb + fnz
    jn_bdd, lc_fnz, in1, in2 = jn * beta_dd, lc * fnz, jn_rp0 * beta_dd, jn_rp1 * beta_dd
    h2, h6 = 0.5 * h, h / 6.0
    th, thd, z, zd, q1, q2, q1d, q2d = x[0], x[1], x[2], x[3], x[4], x[5], x[6], x[7]
    a1, b1, c1, d1 = _rates(c, nx, ny, ns, ax, ay, asl, th, thd, zd, q1, q2, q1d, q2d,
                            wind, beta, fnx, fnz, jn_bdd, lc_fnz, modal, in1, in2)
    th2, thd2, zd2 = th + h2 * thd, thd + h2 * a1, zd + h2 * b1
    q12, q22, q1d2, q2d2 = q1 + h2 * q1d, q2 + h2 * q2d, q1d + h2 * c1, q2d + h2 * d1
    a2, b2, c2, d2 = _rates(c, nx, ny, ns, ax, ay, asl, th2, thd2, zd2, q12, q22, q1d2, q2d2,
                            wind, beta, fnx, fnz, jn_bdd, lc_fnz, modal, in1, in2)
    th3, thd3, zd3 = th + h2 * thd2, thd + h2 * a2, zd + h2 * b2
    q13, q23, q1d3, q2d3 = q1 + h2 * q1d2, q2 + h2 * q2d2, q1d + h2 * c2, q2d + h2 * d2
    a3, b3, c3, d3 = _rates(c, nx, ny, ns, ax, ay, asl, th3, thd3, zd3, q13, q23, q1d3, q2d3,
                            wind, beta, fnx, fnz, jn_bdd, lc_fnz, modal, in1, in2)
    th4, thd4, zd4 = th + h * thd3, thd + h * a3, zd + h * b3
    q14, q24, q1d4, q2d4 = q1 + h * q1d3, q2 + h * q2d3, q1d + h * c3, q2d + h * d3
    a4, b4, c4, d4 = _rates(c, nx, ny, ns, ax, ay, asl, th4, thd4, zd4, q14, q24, q1d4, q2d4,
                            wind, beta, fnx, fnz, jn_bdd, lc_fnz, modal, in1, in2)
    x[0] = th + h6 * (thd + 2.0 * (thd2 + thd3) + thd4)
    x[1] = thd + h6 * (a1 + 2.0 * (a2 + a3) + a4)
    x[2] = z + h6 * (zd + 2.0 * (zd2 + zd3) + zd4)
    x[3] = zd + h6 * (b1 + 2.0 * (b2 + b3) + b4)
    x[4] = q1 + h6 * (q1d + 2.0 * (q1d2 + q1d3) + q1d4)
    x[5] = q2 + h6 * (q2d + 2.0 * (q2d2 + q2d3) + q2d4)
    x[6] = q1d + h6 * (c1 + 2.0 * (c2 + c3) + c4)
    x[7] = q2d + h6 * (d1 + 2.0 * (d2 + d3) + d4)


@_jit
def rk4_frame(x, consts, nx, ny, ns, ax, ay, asl, deflection, rate, wind, b0, r0, inv_dt, h,
              t_ms, t0_ms, refresh_ms, dt_ms):
    """Integrate one frame in place: the nonlinear branch of
    :meth:`vega_sim.plant_step.PlantStep.advance`.

    Parameters
    ----------
    x
        State (8,) [:data:`vega_model.dynamics.STATES`], overwritten with the state at the
        frame's end.
    consts
        :func:`entry_constants` of every parameter entry (n_entries, len(CONSTANTS)).
    nx, ny, ns, ax, ay, asl
        :func:`mach_tables`.
    deflection, rate, wind
        β, β̇ at the ends of the frame's physics steps and the wind held over each (steps,).
    b0, r0
        β, β̇ at the frame's start.
    inv_dt, h
        1/dt [1/s] and dt [s] of a physics step.
    t_ms, t0_ms, refresh_ms, dt_ms
        Frame time, track start, parameter refresh and physics step [ms]: step k uses entry
        (t_ms + k·dt_ms − t0_ms) // refresh_ms.
    """
    for k in range(deflection.shape[0]):
        b1, r1 = deflection[k], rate[k]
        e = (t_ms + k * dt_ms - t0_ms) // refresh_ms
        _rk4_step(consts[e], nx, ny, ns, ax, ay, asl, x, 0.5 * (b0 + b1), (r1 - r0) * inv_dt,
                  wind[k], 0.5 * (r0 + r1), h)
        b0, r0 = b1, r1
