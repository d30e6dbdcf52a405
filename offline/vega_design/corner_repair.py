"""Step 7 of the structured design: single-parameter repairs of the bending criterion at the
dispersed corners.

Why (docs/FLIGHT_DESIGN.md §4, "Step 7"): steps 1–6 (:func:`.structured.design_flight`) tune
every grid point on its *design set* (190–222 plants), but the table is verified on the 641
dispersed corners of `vega margins --dispersed` at every 0.5 s
(:func:`vega_loops.margins.sweep`), by the flown controller interpolated between grid points.
That verification can find the exact bending criterion missed at a few times where the design
sets meet it; single-parameter edits of the nearest grid point (a deeper first notch, a lower
first low-pass) remove such misses. This step makes those edits by a rule, so that one `vega
design` run makes a table the verification passes, with no hand edit:

1. **Check.** Between every two neighbouring grid points, the flown controller at every
   time of the 0.5 s grid (:func:`.structured.worst_case_times`; the first grid time and the
   times before it too: from 0 s the first point's controller flies alone),
   at every corner of :func:`vega_loops.margins.dispersed_corners`. A *miss* is a (time,
   corner, criterion) where the loop is unstable or a mode misses
   :func:`vega_loops.margins.bending_ok`
   (≤ −6 dB, or phase-stabilised with ≥ 6 dB / 30° in its band: the heritage criterion of
   the margin table).
2. **Candidates.** For a grid point next to a missed time, one parameter moved at a time
   (:data:`EDITS`, sized on the hand edits of docs/FLIGHT_DESIGN.md §4: the notch made deeper
   (its numerator damping × 0.85 or × 0.7), the low-pass corner lowered by 3.4 % or 6.7 %
   (0.015 or 0.03 in log10), the notch centre moved by ∓ 0.02 of the mode frequency), for the
   mode that is missed.
3. **Acceptance**, all of:
   * inside the parameter's search box;
   * no requirement miss added on the design set of the point, nor of the flown controller
     midway to either neighbour (:func:`.structured.requirement_misses` component-wise no
     larger);
   * over the point's two intervals, at every 0.5 s time and every corner, the set of misses
     strictly smaller and no new one (a corner that passed keeps passing);
   * with ``worst_case`` (normally :func:`vega_analysis.robust.worst_case_bending_ok`, as
     step 6 takes it): `vega robust`'s worst case keeps the bending criterion wherever it met
     it before the edit.
   Among the accepted candidates the one with the fewest misses left wins, then the one whose
   formerly missed rows keep the largest distance to the criterion (:func:`bending_slack`,
   the rule a person applies choosing among edits by hand).
4. Points are taken in order of their number of misses, for at most :data:`MAX_ROUNDS` rounds;
   what is left is reported, not hidden.

Candidates are screened on the missed (time, corner) loops alone (a few loops each); only those
that remove a miss there get the full check (all corners of both intervals). The tail-off
(from 86 s, one controller held over several grid points, the 86 s point included) is edited
as one (:func:`units_of`): an edit moves the parameter at every grid point of the hold, its
full check covers every interval of the tail-off and the one into it, its design-set check
every grid time of the hold and every midpoint (the hold can miss the criterion too: mode 1 at
−5.93 dB at 86 and 86.5 s, mode 2 at 100 s, which a deeper second notch or a lower second
low-pass removes; docs/FLIGHT_DESIGN.md §4). Cost on two cores: the check of the whole flight
≈ 6 min at load ≈ 1 (as `vega margins --dispersed`), then ≈ 0.5 min per repaired point; the
hold (32 times from 84.5 to 100 s) ≈ 8.5 min (measured beside a verification, 1 383 s in all,
870 s of them the check: an order of magnitude, not a timing figure).
"""

from __future__ import annotations

import math
import time as _time
from typing import Callable, Mapping, Sequence

import numpy as np

from vega_design import structured as S
from vega_loops.margins import (
    REQUIREMENTS, analyse_loop, bending_ok, corner_plant, dispersed_corners, loop_data,
)

__all__ = ["EDITS", "MAX_ROUNDS", "bending_slack", "row_misses", "interval_times",
           "candidate", "check_intervals", "repair_corner_bending", "recheck_design",
           "units_of", "repair_design"]

EDITS = (
    # (parameter, "scale" or "add", amount, mode it acts on)
    ("notch1_zeta_num", "scale", 0.85, 1),
    ("notch1_zeta_num", "scale", 0.70, 1),
    ("log10_lp1_radps", "add", -0.015, 1),
    ("log10_lp1_radps", "add", -0.030, 1),
    ("notch1_ratio", "add", -0.02, 1),
    ("notch1_ratio", "add", +0.02, 1),
    ("notch2_zeta_num", "scale", 0.85, 2),
    ("notch2_zeta_num", "scale", 0.70, 2),
    ("log10_lp2_radps", "add", -0.015, 2),
    ("log10_lp2_radps", "add", -0.030, 2),
    ("notch2_ratio", "add", -0.02, 2),
    ("notch2_ratio", "add", +0.02, 2),
)
"""The candidate edits (assumption: the sizes of the hand edits recorded in ``solver.edits`` of
tests/data/tvc_controller_2026-11-27.npz, docs/FLIGHT_DESIGN.md §4 — notch1_zeta_num 0.0482 →
0.035 (× 0.73) at 43 s, 0.0467 → 0.040 (× 0.86) at 82 s, log10_lp1_radps 1.184 → 1.17
(−0.014) at 34.5 s; notch1_ratio −0.02 was tried there by hand — bracketed; small enough that
the rigid-body margins, which every grid point holds with ≥ 0.3 dB / 1° of design margin, are
checked rather than expected to move)."""

MAX_ROUNDS = 3
"""Rounds over the points with misses (an edit can leave a miss that a neighbour's edit then
removes; assumption: three rounds, each at most one edit per point, bound the run time)."""

MIN_STEP = 1e-4
"""An edit moving its parameter by less than this is no edit (a notch damping already ≈ 0: the
34.5 s point's first notch has ζ_num = 3e-6)."""


def bending_slack(row: Mapping, mode: int, req: Mapping = REQUIREMENTS) -> float:
    """Distance of mode ``mode`` to :func:`vega_loops.margins.bending_ok` in dB-equivalents
    (≥ 0 passes).

    A gain-stabilised mode (peak ≤ −6 dB): −6 dB − peak, the gain it may still gain (its
    in-band GM and PM are infinite when it has no crossover there: no distance to read).
    Otherwise the better of that (negative) and the phase-stabilised distance, the smaller of
    in-band GM − 6 dB and (PM − 30°)/5 (5° counted as 1 dB, the weighting of the design cost's
    exact-criterion term)."""
    gain = req["bending_db"] - row[f"b{mode}_peak_db"]
    if gain >= 0.0:
        return float(gain)
    phase = min(row[f"b{mode}_gm_db"] - req["bending_phase_gm_db"],
                (row[f"b{mode}_pm_deg"] - req["bending_phase_pm_deg"]) / 5.0)
    return float(max(gain, phase))


def row_misses(row: Mapping) -> set:
    """The misses of one analysed loop: ``(t_s, corner, criterion)`` for every criterion of
    ``("bending_1", "bending_2", "stable")`` it fails."""
    key = (round(float(row["t_s"]), 6), int(row["corner"]))
    out = set()
    if row["n_unstable"] > 0:
        out.add(key + ("stable",))
    for mode in (1, 2):
        if not bending_ok(row, mode):
            out.add(key + (f"bending_{mode}",))
    return out


def interval_times(left_s: float, right_s: float, first: bool = False) -> list[float]:
    """The 0.5 s-grid times flown between the grid points ``left_s`` and ``right_s``, the right
    one included; with ``first`` (``left_s`` is the first grid point checked) the left one too,
    and when it is the table's first grid point (the design's, :data:`.structured.
    DEFAULT_ANCHORS_S`) the times before it that its controller flies alone from the first INS
    sample on (:data:`.structured.PAD_TIMES_S`, as its design set holds them)."""
    times = S.worst_case_times(left_s, right_s)
    if not first:
        return times
    pad = ([float(t) for t in S.PAD_TIMES_S if t < left_s - 1e-9]
           if left_s <= S.DEFAULT_ANCHORS_S[0] + 1e-9 else [])
    return pad + [float(left_s)] + times


def candidate(x, edit) -> np.ndarray | None:
    """Parameter vector ``x`` with one edit of :data:`EDITS` applied; None when it leaves the
    search box or moves the parameter by less than :data:`MIN_STEP`."""
    name, how, amount, _ = edit
    i = [p[0] for p in S.PARAMETERS].index(name)
    new = np.array(x, dtype=float)
    new[i] = new[i] * amount if how == "scale" else new[i] + amount
    if abs(new[i] - float(x[i])) < MIN_STEP or not S.LOWER[i] <= new[i] <= S.UPPER[i]:
        return None
    return new


def _analyse(context, pair, times, corners) -> list[dict]:
    """Rows of the flown controller of ``pair`` (a two-point table) at ``times`` for the
    ``corners`` ((index, deviations) pairs); no Nyquist cross-check (the eigenvalues decide)."""
    rows = []
    for t in times:
        data = loop_data(pair, context, float(t))
        for index, dev in corners:
            p, act, tau = corner_plant(context, float(t), dev)
            row = {"t_s": float(t), "corner": int(index)}
            row.update(analyse_loop(data, p, act, tau, nyquist=False))
            rows.append(row)
    return rows


def _interval_task(args) -> tuple[float, list[dict]]:
    left, right, times, corner_ids = args
    from vega_model.parameters import default_context
    from vega_model.uncertainty import UncertaintySet

    context = default_context()
    corners = dispersed_corners(UncertaintySet.from_vehicle(context.vehicle))
    pair = S._pair_table(context, left, right)
    return left[0], ([] if pair is None else
                     _analyse(context, pair, times, [(i, corners[i]) for i in corner_ids]))


def check_intervals(context, done: Mapping[float, tuple], corner_ids: Sequence[int],
                    until_s: float = S.TAIL_OFF_HOLD_S, workers: int = 2,
                    progress: Callable[[str], None] | None = None) -> dict:
    """Step 7.1: the rows of every interval between neighbouring grid points up to
    ``until_s`` (``done`` maps grid time → (x, ...)); returns left grid time → rows."""
    times = sorted(done)
    tasks = [((a, done[a][0]), (b, done[b][0]), interval_times(a, b, first=(k == 0)),
              list(corner_ids))
             for k, (a, b) in enumerate(zip(times[:-1], times[1:])) if b <= until_s + 1e-9]
    start = _time.perf_counter()
    out: dict[float, list[dict]] = {}

    every = max(1, len(tasks) // 10)
    for k, (left, rows) in enumerate(S.pool_map(_interval_task, tasks, workers), start=1):
        out[left] = rows
        if progress is not None and (k % every == 0 or k == len(tasks)):
            progress(f"corner check: {k}/{len(tasks)} intervals ({len(corner_ids)} corners), "
                     f"{_time.perf_counter() - start:.0f} s elapsed")
    return out


def _misses(rows) -> set:
    out: set = set()
    for row in rows:
        out |= row_misses(row)
    return out


def recheck_design(context, uset, new: Mapping[float, np.ndarray],
                   old: Mapping[float, np.ndarray], intervals: Sequence[tuple]) -> bool:
    """No requirement miss added by an edit: ``new`` and ``old`` map the edited grid times to
    their parameters after and before it (one point, or every point of the tail-off hold),
    ``intervals`` are the ``((t_a, x_a), (t_b, x_b))`` neighbour pairs the edited points fly
    in, with the parameters before the edit. Checked on the design set of every edited grid
    time and of the flown controller midway through every interval."""
    def no_worse(K_new, K_old, at):
        ds = S.design_set(context, at, uset)
        after = S.requirement_misses(S.evaluate_discrete(K_new, ds, detail=True)[1])
        before = S.requirement_misses(S.evaluate_discrete(K_old, ds, detail=True)[1])
        return all(a <= b for a, b in zip(after, before))

    dt = 1.0 / float(context.vehicle["controller.rate_hz"])
    for t_s in sorted(new):
        omega = context.parameters(float(t_s)).omega_radps
        if not no_worse(S.discretise(*S.controller_ss(new[t_s], omega), dt),
                        S.discretise(*S.controller_ss(old[t_s], omega), dt), float(t_s)):
            return False
    for (ta, xa), (tb, xb) in intervals:
        a_new = (ta, new.get(ta, xa))
        b_new = (tb, new.get(tb, xb))
        mid = 0.5 * (ta + tb)
        if not no_worse(S.flown_between(context, a_new, b_new, mid),
                        S.flown_between(context, (ta, xa), (tb, xb), mid), mid):
            return False
    return True


def units_of(times: Sequence[float], until_s: float) -> list[tuple]:
    """What step 7 edits, each as a tuple of grid times: every grid point before ``until_s``
    alone, and the grid points from ``until_s`` on together (the tail-off hold: they hold one
    controller, so one edit moves them all)."""
    times = sorted(float(t) for t in times)
    hold = tuple(t for t in times if t >= until_s - 1e-9)
    return [(t,) for t in times if t < until_s - 1e-9] + ([hold] if hold else [])


def repair_corner_bending(context, done: Mapping[float, tuple],
                          corner_ids: Sequence[int] | None = None,
                          until_s: float = S.TAIL_OFF_HOLD_S, workers: int = 2,
                          worst_case: Callable[[object, object, float], bool] | None = None,
                          progress: Callable[[str], None] | None = None,
                          rows: Mapping[float, list] | None = None) -> tuple[dict, dict]:
    """Step 7 (module docstring): returns the updated ``done`` (grid time → (x, detail, how))
    and a record ``{"edits": [...], "misses_before": n, "misses_after": n, "left":
    [(t, corner, criterion), ...], "corners": n}``.

    ``until_s`` is where the tail-off hold starts (:func:`units_of`: the grid points from it on
    are edited as one). ``corner_ids`` (default every corner of
    :func:`vega_loops.margins.dispersed_corners`) and ``rows`` (the check of step 7.1 already
    made, left grid time → rows) let a test run the step on a few corners or reuse a check."""
    from vega_model.uncertainty import UncertaintySet

    uset = UncertaintySet.from_vehicle(context.vehicle)
    corners = dispersed_corners(uset)
    ids = list(range(len(corners))) if corner_ids is None else [int(i) for i in corner_ids]
    say = progress or (lambda line: None)
    done = dict(done)
    times = sorted(done)
    units = units_of(times, until_s)
    if rows is None:        # the whole flight, the tail-off included
        rows = check_intervals(context, done, ids, math.inf, workers, progress)
    by_left = {float(a): list(r) for a, r in rows.items()}
    first = times[0]
    eps = 1e-9

    def intervals_of(unit):
        """The (left, right) neighbour pairs of grid times whose flown controller uses a point
        of ``unit``."""
        return [(a, b) for a, b in zip(times[:-1], times[1:]) if a in unit or b in unit]

    def misses_at(unit):
        return set().union(*(_misses(by_left.get(a, [])) for a, _ in intervals_of(unit)))

    def name(unit):
        return f"{unit[0]:g} s" if len(unit) == 1 else f"{unit[0]:g}–{unit[-1]:g} s (hold)"

    before = set().union(*(_misses(r) for r in by_left.values())) if by_left else set()
    edits = []
    for rnd in range(1, MAX_ROUNDS + 1):
        todo = sorted((u for u in units if misses_at(u)), key=lambda u: -len(misses_at(u)))
        if not todo:
            break
        changed = False
        for unit in todo:
            old_miss = misses_at(unit)
            if not old_miss:
                continue
            x_old = {t: np.asarray(done[t][0], dtype=float) for t in unit}
            modes = {int(c[-1][-1]) for c in old_miss if c[2].startswith("bending")} or {1, 2}
            pairs = intervals_of(unit)

            def flown(a, b, x_new):
                return S._pair_table(context, (a, x_new.get(a, done[a][0])),
                                     (b, x_new.get(b, done[b][0])))

            screened = []
            for edit in EDITS:
                if edit[3] not in modes:
                    continue
                x_new = {t: candidate(x_old[t], edit) for t in unit}
                if any(x is None for x in x_new.values()):
                    continue
                # screening: the missed loops only
                fixed, slack = 0, math.inf
                for a, b in pairs:
                    # the loops flown with the unit's points: not those at an end point
                    # outside it (that point's own controller alone flies there)
                    others = [o for o in (a, b) if o not in unit]
                    missed = {(tm, c) for tm, c, _ in old_miss
                              if (a < tm <= b + eps or (a == first and tm <= a + eps))
                              and all(abs(tm - o) > eps for o in others)}
                    if not missed:
                        continue
                    pair = flown(a, b, x_new)
                    if pair is None:
                        continue
                    for tm in sorted({tm for tm, _ in missed}):
                        cs = [(c, corners[c]) for m, c in sorted(missed) if m == tm]
                        for row in _analyse(context, pair, [tm], cs):
                            crit = {m[2] for m in row_misses(row)}
                            was = {m[2] for m in old_miss if m[:2] == (round(tm, 6),
                                                                          row["corner"])}
                            fixed += len(was - crit)
                            for m in was:
                                if m.startswith("bending"):
                                    slack = min(slack, bending_slack(row, int(m[-1])))
                if fixed:
                    screened.append((-fixed, -slack, edit, x_new))
            accepted = None
            for _, _, edit, x_new in sorted(screened, key=lambda s: s[:2]):
                if not recheck_design(context, uset, x_new, x_old,
                                      [((a, done[a][0]), (b, done[b][0])) for a, b in pairs]):
                    say(f"corner repair {name(unit)}: {edit[0]} {edit[1]} {edit[2]:g} refused "
                        "(adds a requirement miss on a design set)")
                    continue
                new_rows, ok = {}, True
                for a, b in pairs:
                    pair = flown(a, b, x_new)
                    new_rows[a] = ([] if pair is None else _analyse(
                        context, pair, interval_times(a, b, first=(a == first)),
                        [(i, corners[i]) for i in ids]))
                    if worst_case is not None and pair is not None and ok:
                        old_pair = S._pair_table(context, (a, done[a][0]), (b, done[b][0]))
                        for tau in S.worst_case_times(a, b):
                            if not worst_case(pair, context, tau) and worst_case(
                                    old_pair, context, tau):
                                ok = False
                                break
                new_miss = set().union(*(_misses(r) for r in new_rows.values()))
                if not ok or not (new_miss < old_miss):
                    say(f"corner repair {name(unit)}: {edit[0]} {edit[1]} {edit[2]:g} refused "
                        f"({'worst case' if not ok else 'misses'} {len(old_miss)} -> "
                        f"{len(new_miss)}{'' if new_miss <= old_miss else ', new ones'})")
                    continue
                accepted = (edit, x_new, new_rows, new_miss)
                break
            if accepted is None:
                say(f"corner repair {name(unit)}: no candidate removes a miss "
                    f"({len(old_miss)} left)")
                continue
            edit, x_new, new_rows, new_miss = accepted
            i = [p[0] for p in S.PARAMETERS].index(edit[0])
            for t in unit:
                _, detail = S.evaluate(x_new[t], S.design_set(context, t, uset), detail=True)
                how = (f"{done[t][2]}; {edit[0]} {x_old[t][i]:.6g} -> {x_new[t][i]:.6g} "
                       "(corner repair, step 7)")
                done[t] = (x_new[t], detail, how)
            by_left.update(new_rows)
            t0 = unit[0]
            edits.append({"t_s": float(t0), "parameter": edit[0], "from": float(x_old[t0][i]),
                          "to": float(x_new[t0][i]), "round": rnd,
                          "misses": [len(old_miss), len(new_miss)],
                          **({"held_s": [float(t) for t in unit]} if len(unit) > 1 else {})})
            say(f"corner repair {name(unit)}: {edit[0]} {x_old[t0][i]:.4g} -> "
                f"{x_new[t0][i]:.4g}, misses in its intervals {len(old_miss)} -> "
                f"{len(new_miss)}")
            changed = True
        if not changed:
            break
    after = set().union(*(_misses(r) for r in by_left.values())) if by_left else set()
    record = {"edits": edits, "misses_before": len(before), "misses_after": len(after),
              "left": sorted(after), "corners": len(ids), "until_s": float(until_s),
              "worst_case_checked": worst_case is not None}
    return done, record


def repair_design(context, design: "S.StructuredDesign", workers: int = 2,
                  worst_case: Callable[[object, object, float], bool] | None = None,
                  progress: Callable[[str], None] | None = None) -> "S.StructuredDesign":
    """A whole design through step 7 (:func:`repair_corner_bending`, every corner): ``vega
    design`` runs it after steps 1–6 (unless ``--no-corner-repair``). The tuning record gets
    the step's record appended to ``corner_repair`` (a list, one entry per application: the
    format of the tables' ``solver.corner_repair``) and ``how`` per grid point."""
    from vega_model.uncertainty import UncertaintySet

    uset = UncertaintySet.from_vehicle(context.vehicle)
    done = {}
    how = dict(design.tuning.get("how", {}))
    for t, x, d in zip(design.grid_times_s, design.x, design.details):
        done[float(t)] = (np.asarray(x, dtype=float), d, how.get(f"{float(t):g}", "given"))
    done, record = repair_corner_bending(context, done, workers=workers, worst_case=worst_case,
                                         progress=progress)
    grid_t = np.array(sorted(done))
    details = [done[float(t)][1] or S.evaluate(done[float(t)][0],
                                               S.design_set(context, float(t), uset),
                                               detail=True)[1] for t in grid_t]
    tuning = dict(design.tuning)
    tuning["corner_repair"] = list(tuning.get("corner_repair", [])) + [record]
    tuning["how"] = {f"{t:g}": done[float(t)][2] for t in grid_t}
    return S.StructuredDesign(grid_t, np.array([context.parameters(float(t)).v_mps
                                                for t in grid_t]),
                              np.array([done[float(t)][0] for t in grid_t]), details,
                              tuple(design.anchors_s), tuning)
