"""The truth side of many closed-loop flights at once, compiled (numba): actuator, plant, truth
outputs and INS of N samples advanced frame by frame, bit for bit the per-flight step classes.

The batched flight engine (:mod:`vega_sim.batch`) keeps the state of N dispersed flights in
arrays and calls :func:`advance_frames` between two controller steps. Per sample and frame it
does what the per-flight nodes do, in their order and with their floating-point operations:

* the actuator node (:class:`vega_sim.device_steps.ActuatorStep`): commands queued in arrival
  order apply from their stamp + actuator latency, held until the next one; the limited
  servo law of :meth:`vega_model.actuator.TvcActuator.run_tuples` at every physics step (a
  non-finite command holds the last finite one);
* the plant (:class:`vega_sim.plant_step.PlantStep`, nonlinear): the RK4 frame of
  :func:`vega_model.nonlinear_kernel.rk4_frame` itself, with the actuator's samples and
  the sample's wind;
* the truth at the new frame time: α and Qα of :func:`vega_model.dynamics.alpha_and_q_alpha`
  (the operations of ``_airflow``, ``math.hypot`` as CPython computes it:
  :func:`vega_model.nonlinear_kernel._hypot`);
* the INS (:class:`vega_sim.device_steps.InsStep`, :class:`vega_model.ins.InsSensor`): the
  kinematics of :func:`vega_model.dynamics.ins_outputs_tuple` plus σ·n from the sample's noise
  stream (five draws per sample, the generator's order), NaN and ``valid`` false when the truth
  is not finite.

No ``fastmath``; ``sin``, ``cos``, ``atan2`` and ``sqrt`` are the C library's, as CPython's
``math`` calls them (the argument of :mod:`vega_model.nonlinear_kernel`). tests/sim/test_batch.py
compares whole dispersed flights with the per-flight path, every recorded array bit for bit.

Compiled on first use and cached on disk next to this file (``cache=True``).
"""

from __future__ import annotations

import math

import numba

from vega_model.nonlinear_kernel import _hypot, rk4_frame

__all__ = ["TRUTH_FIELDS", "INS_FIELDS", "ACTUATOR_FIELDS", "VIEW_FIELDS", "ACTUATOR_PARAMS",
           "observe", "advance_frames"]

TRUTH_FIELDS = ("t_ms", "theta_rad", "theta_dot_radps", "z_m", "z_dot_mps", "alpha_rad",
                "q_alpha_pa_rad", "q_pa", "mach", "v_mps", "h_m", "wind_mps", "q1", "q2",
                "q1_dot", "q2_dot")
"""Rows of the truth record (one column per frame time)."""
INS_FIELDS = ("stamp_ms", "sample_ms", "theta_rad", "theta_dot_radps", "z_m", "z_dot_mps",
              "v_mps", "valid")
"""Rows of the INS record (one column per frame)."""
ACTUATOR_FIELDS = ("beta_rad", "beta_dot_radps", "beta_ddot_radps2", "beta_cmd_rad")
"""Rows of the actuator record (one column per physics step)."""
VIEW_FIELDS = ("v_mps", "q_pa", "mach", "h_m", "rho_kgpm3", "l_cp_m", "psi_t_ins_0",
               "psi_t_ins_1", "psi_r_ins_0", "psi_r_ins_1", "l_ins_m")
"""Columns of a sample's per-entry parameters (:class:`vega_sim.plant_step.ParameterView`)."""
ACTUATOR_PARAMS = ("p11", "p12", "p21", "p22", "w2", "c", "half_dt", "pos", "rate", "max_step")
"""Columns of a sample's actuator constants (:class:`vega_model.actuator.TvcActuator`)."""

_jit = numba.njit(cache=True, nogil=True)


@_jit
def _observe_one(n, f, t_ms, x, views, e, wind_k, noise, noise_on, sigma, sensor_latency_ms,
                 truth, ins):
    """Truth and INS of sample ``n`` at frame ``f`` (time ``t_ms``, parameter entry ``e``,
    wind ``wind_k`` held over the step starting there)."""
    v, q_pa, mach, h = views[n, e, 0], views[n, e, 1], views[n, e, 2], views[n, e, 3]
    rho, d = views[n, e, 4], views[n, e, 5]
    th, thd, z, zd = x[n, 0], x[n, 1], x[n, 2], x[n, 3]
    q1, q2, q1d, q2d = x[n, 4], x[n, 5], x[n, 6], x[n, 7]
    # dynamics._airflow and alpha_and_q_alpha
    s, c = math.sin(th), math.cos(th)
    vx = v - thd * d * s
    vz = zd - wind_k - thd * d * c
    u = vx * c - vz * s
    w = vx * s + vz * c
    alpha = math.atan2(w, u)
    airspeed = _hypot(vx, vz)
    q_alpha = 0.5 * rho * airspeed * airspeed * alpha
    rec = truth[n]
    rec[0, f], rec[1, f], rec[2, f], rec[3, f], rec[4, f] = t_ms, th, thd, z, zd
    rec[5, f], rec[6, f], rec[7, f], rec[8, f] = alpha, q_alpha, q_pa, mach
    rec[9, f], rec[10, f], rec[11, f] = v, h, wind_k
    rec[12, f], rec[13, f], rec[14, f], rec[15, f] = q1, q2, q1d, q2d
    # InsStep.sample: a truth with a non-finite value gives no measurement
    out = ins[n]
    out[0, f], out[1, f] = t_ms + sensor_latency_ms[n], t_ms
    finite = math.isfinite(v)
    for i in range(8):
        finite = finite and math.isfinite(x[n, i])
    if not finite:
        for i in range(2, 7):
            out[i, f] = math.nan
        out[7, f] = 0.0
        return
    # dynamics.ins_outputs_tuple
    ti0, ti1, ri0, ri1, li = (views[n, e, 6], views[n, e, 7], views[n, e, 8], views[n, e, 9],
                              views[n, e, 10])
    m0 = th - ri0 * q1 - ri1 * q2
    m1 = thd - ri0 * q1d - ri1 * q2d
    m2 = z - li * math.sin(th) + ti0 * q1 + ti1 * q2
    m3 = zd - li * math.cos(th) * thd + ti0 * q1d + ti1 * q2d
    m4 = v
    if noise_on[n]:                       # InsSensor.measure: y + σ·n, five draws per sample
        k = 5 * f
        m0 = m0 + sigma[n, 0] * noise[n, k]
        m1 = m1 + sigma[n, 1] * noise[n, k + 1]
        m2 = m2 + sigma[n, 2] * noise[n, k + 2]
        m3 = m3 + sigma[n, 3] * noise[n, k + 3]
        m4 = m4 + sigma[n, 4] * noise[n, k + 4]
    out[2, f], out[3, f], out[4, f], out[5, f], out[6, f] = m0, m1, m2, m3, m4
    valid = (math.isfinite(m0) and math.isfinite(m1) and math.isfinite(m2)
             and math.isfinite(m3) and math.isfinite(m4))
    out[7, f] = 1.0 if valid else 0.0


@_jit
def observe(f, t_ms, t0_ms, refresh_ms, dt_ms, x, views, wind, noise, noise_on, sigma,
            sensor_latency_ms, truth, ins):
    """Truth and INS of every sample at frame ``f`` (time ``t_ms``): ``truth[:, :, f]`` and
    ``ins[:, :, f]`` (:data:`TRUTH_FIELDS`, :data:`INS_FIELDS`)."""
    e = (t_ms - t0_ms) // refresh_ms
    j = (t_ms - t0_ms) // dt_ms
    for n in range(x.shape[0]):
        _observe_one(n, f, t_ms, x, views, e, wind[n, j], noise, noise_on, sigma,
                     sensor_latency_ms, truth, ins)


@_jit
def _actuator_frame(n, t_ms, steps, dt_ms, act, act_par, queue_t, queue_v, queue_n, out, k0,
                    deflection, rate):
    """One frame of :meth:`vega_sim.device_steps.ActuatorStep.advance` for sample ``n``:
    β, β̇ at the step ends into ``deflection``/``rate`` and (β, β̇, β̈, held) into
    ``out[n, :, k0:k0 + steps]``."""
    p11, p12, p21, p22 = act_par[n, 0], act_par[n, 1], act_par[n, 2], act_par[n, 3]
    w2, c, half_dt, pos = act_par[n, 4], act_par[n, 5], act_par[n, 6], act_par[n, 7]
    lim, max_step = act_par[n, 8], act_par[n, 9]
    neg_rate, neg_pos, neg_step = -lim, -pos, -max_step
    b0, r0, a, held, command = act[n, 0], act[n, 1], act[n, 2], act[n, 3], act[n, 4]
    for k in range(steps):
        while queue_n[n] > 0 and queue_t[n, 0] <= t_ms + k * dt_ms:   # apply, FIFO
            command = queue_v[n, 0]
            for i in range(queue_n[n] - 1):
                queue_t[n, i] = queue_t[n, i + 1]
                queue_v[n, i] = queue_v[n, i + 1]
            queue_n[n] -= 1
        # TvcActuator.run_tuples, one step
        u = command
        if math.isfinite(u):
            held = u
        else:
            u = held
        e = b0 - u
        b = u + p11 * e + p12 * r0
        r = p21 * e + p22 * r0
        if r > lim:
            r = lim
            b = b0 + half_dt * (r0 + r)
        elif r < neg_rate:
            r = neg_rate
            b = b0 + half_dt * (r0 + r)
        d = b - b0
        if d > max_step:
            b = b0 + max_step
        elif d < neg_step:
            b = b0 - max_step
        if b > pos:
            b = pos
            r = min(r, 0.0)
        elif b < neg_pos:
            b = neg_pos
            r = max(r, 0.0)
        a = w2 * (u - b) - c * r
        if (a > 0.0 and (r >= lim or b >= pos)) or (a < 0.0 and (r <= neg_rate
                                                              or b <= neg_pos)):
            a = 0.0
        j = k0 + k
        out[n, 0, j], out[n, 1, j], out[n, 2, j], out[n, 3, j] = b, r, a, held
        deflection[k], rate[k] = b, r
        b0, r0 = b, r
    act[n, 0], act[n, 1], act[n, 2], act[n, 3], act[n, 4] = b0, r0, a, held, command


@_jit
def advance_frames(f0, n_frames, t0_ms, frame_ms, refresh_ms, dt_ms, push, push_t, push_v,
                   x, plant_in, consts, nx, ny, ns, ax, ay, asl, views, wind, noise, noise_on,
                   sigma, sensor_latency_ms, act, act_par, queue_t, queue_v, queue_n,
                   truth, ins, act_out, deflection, rate):
    """Advance every sample ``n_frames`` frames from frame ``f0``; record the truth and the
    INS at the frames reached and the actuator's physics steps.

    Parameters
    ----------
    f0, n_frames
        First frame [index from t_start] and number of frames.
    t0_ms, frame_ms, refresh_ms, dt_ms
        Track start, frame, parameter refresh and physics step [ms].
    push, push_t, push_v
        If ``push``: a command per sample queued first, applying from ``push_t`` [ms]
        (stamp + actuator latency) with the deflection ``push_v`` [rad].
    x, plant_in
        Plant states (N, 8) and the plant's β, β̇ at the frame start (N, 2), updated.
    consts, nx, ny, ns, ax, ay, asl
        Per sample: :func:`vega_model.kernel_inputs.entry_constants` of every entry
        (N, entries, 24) and the Mach tables (N, length each).
    views, wind
        Per sample: the entries' :data:`VIEW_FIELDS` (N, entries, 11) and the wind held over
        every physics step of the track (N, steps) [m/s].
    noise, noise_on, sigma, sensor_latency_ms
        Per sample: the INS's standard normal draws (N, ≥ 5 per frame), noise flag, σ of the
        five channels (N, 5) and sensor latency [ms].
    act, act_par, queue_t, queue_v, queue_n
        Per sample: actuator state (β, β̇, β̈, held, command in force), constants
        (:data:`ACTUATOR_PARAMS`) and the queue of pending commands (application time [ms],
        deflection [rad], count), updated.
    truth, ins, act_out
        Records, one row per field: (N, 16, frames + 1), (N, 8, frames + 1) and
        (N, 4, 1 + steps) — physics step j of the flight in column 1 + j (column 0 is the
        caller's, for the initial state) — written.
    deflection, rate
        Work arrays (steps per frame,).
    """
    steps = frame_ms // dt_ms
    inv_dt = 1.0 / (dt_ms / 1000.0)
    h = dt_ms / 1000.0
    for n in range(x.shape[0]):
        if push:
            q = queue_n[n]
            queue_t[n, q], queue_v[n, q] = push_t[n], push_v[n]
            queue_n[n] = q + 1
        xn, cn = x[n], consts[n]
        nxn, nyn, nsn, axn, ayn, asn = nx[n], ny[n], ns[n], ax[n], ay[n], asl[n]
        for f in range(f0, f0 + n_frames):
            t_ms = t0_ms + f * frame_ms
            _actuator_frame(n, t_ms, steps, dt_ms, act, act_par, queue_t, queue_v, queue_n,
                            act_out, 1 + f * steps, deflection, rate)
            # PlantStep.advance, nonlinear: the plant's own compiled frame
            j0 = (t_ms - t0_ms) // dt_ms
            rk4_frame(xn, cn, nxn, nyn, nsn, axn, ayn, asn, deflection, rate,
                      wind[n, j0:j0 + steps], plant_in[n, 0], plant_in[n, 1], inv_dt, h, t_ms,
                      t0_ms, refresh_ms, dt_ms)
            plant_in[n, 0], plant_in[n, 1] = deflection[steps - 1], rate[steps - 1]
            t1 = t_ms + frame_ms
            _observe_one(n, f + 1, t1, x, views, (t1 - t0_ms) // refresh_ms,
                         wind[n, (t1 - t0_ms) // dt_ms], noise, noise_on, sigma,
                         sensor_latency_ms, truth, ins)
