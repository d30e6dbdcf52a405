"""The sign-off checks of a controller table (``vega verify``; docs/FLIGHT_DESIGN.md §6.5).

Checks (each the repository's own command, ``vega …`` run as a subprocess, its output kept in
OUT):

* ``sil`` — ``vega sil run --table TABLE`` for each scenario: gated (exit 0 required) for
  :data:`~.record.GATED_SCENARIOS`, reported for :data:`~.record.REPORTED_SCENARIOS`;
* ``margins`` — ``vega margins --table TABLE --dispersed``: gated on its exit status (the
  heritage margins on the nominal plant at every frozen time) and, from its margins.json, on 0
  unstable dispersed loops and the exact bending criterion (docs/FLIGHT_DESIGN.md §3) at every
  dispersed corner and time; reported: the worst nominal margins and the worst rigid margins
  over the dispersed plants, each with its crossover frequency, and the drift loop's gain
  crossovers below the frozen-time floor;
* ``robust`` — ``vega robust --table TABLE --no-mu``: gated on its exit status (no unstable
  plant found, the worst case meets the bending criteria at every time);
* ``mc`` — ``vega mc run --environment thesis-box --table TABLE --runs N``: the thesis-box
  regression campaign, gated on 0 unstable flights and, with a reference number of passes
  (``--mc-reference``: the passes of the flown table), on at least that many; passes, Qα and
  drift failures reported;
* ``flight-day`` — ``vega mc run --environment flight-day --table TABLE --runs M`` (M =
  ``flight_day_runs``, default :data:`DEFAULT_FLIGHT_DAY_RUNS`): the
  sign-off campaign (docs/MONTE_CARLO.md §9), gated on flight-day success of 99.73 % shown at
  90 % confidence (no failure in 852 go samples, at most one in 1 440), 0 unstable, 0 over
  0.5 s on the rate limit, and the design's availability (the LCC's criteria but the ground
  wind, a programme limit the design does not move) ≥ 90 % in every month; the availability
  with the ground-wind criterion reported beside it.

With a held-out reference (a complete campaign of the reference table on another seed,
docs/FLIGHT_DESIGN.md §6.5 "A held-out seed"), one more campaign flies TABLE on that
campaign's samples (its scenario, dispersions, seed and number of flights) and is compared with
it flight by flight (:mod:`vega_campaign.compare`: passes, flights lost and won, McNemar's
exact p); reported, not gated, and not part of the scope that ``vega ship`` checks.

:func:`verify` writes OUT/verify.json (:mod:`.record`) and reports one line per check.
"""

from __future__ import annotations

import json
import subprocess
import sys
import time
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path

from vega_core.errors import BadInput, one_line

from vega_cli.signoff.record import CHECKS, GATED_SCENARIOS, REPORTED_SCENARIOS, sha256_of

__all__ = ["Plan", "plan", "verify", "default_out", "check_sil", "check_margins",
           "check_robust", "check_mc", "check_flight_day", "check_heldout",
           "dispersed_figures", "mc_figures", "flight_day_figures", "flight_day_passed",
           "AVAILABILITY_FLOOR",
           "DEFAULT_RUNS", "DEFAULT_FLIGHT_DAY_RUNS", "DEFAULT_AT", "MAX_RUNS", "MAX_WORKERS"]

DEFAULT_RUNS = 852
"""Flights of the sign-off campaign (:data:`~.record.MIN_RUNS`)."""
DEFAULT_FLIGHT_DAY_RUNS = 1440
"""Samples of the flight-day campaign. Success is judged on the go samples: 99.73 % at 90 %
needs 852 go samples without a failure (or 1 440 with one), and the launch commit criterion
scrubs some (1 210 of 1 440 go with the shipped site file and LCC, docs/MONTE_CARLO.md §9.3;
852 samples gave 729 go, too few)."""
DEFAULT_AT = "0:100:0.5"
"""Frozen times of margins and robust: the whole flight every 0.5 s."""
MAX_RUNS = 100_000
"""Largest number of flights of the sign-off campaign (a sanity bound against typos)."""
MAX_WORKERS = 64
"""Largest number of worker processes given to margins, robust and the campaign."""
AVAILABILITY_FLOOR = 0.9
"""The design's launch availability every month must reach (the flight-day sign-off)."""


def _vega(args, log: Path) -> tuple[int, float]:
    """Run ``vega ARGS`` (this interpreter, this environment) with its stdout and stderr in
    ``log``; its exit status and wall time [s]."""
    start = time.monotonic()
    with open(log, "w") as f:
        code = subprocess.call([sys.executable, "-m", "vega_cli.cli", *args], stdout=f,
                               stderr=subprocess.STDOUT)
    return code, time.monotonic() - start


def check_sil(table, out: Path, scenarios) -> list[dict]:
    """One SIL flight per scenario; gated on exit 0 except :data:`REPORTED_SCENARIOS`."""
    results = []
    for name in scenarios:
        code, wall = _vega(["sil", "run", "--scenario", name, "--table", str(table),
                            "--out", str(out / "sil"), "--run-id", name],
                           out / f"sil_{name}.log")
        gated = name not in REPORTED_SCENARIOS
        results.append({"check": f"sil {name}", "exit": code, "wall_s": round(wall, 1),
                        "gated": gated, "passed": code == 0,
                        "figures": {"log": f"sil_{name}.log", "run": f"sil/{name}"}})
    return results


_NOMINAL_WORST = ("gm_low_db", "gm_high_db", "pm_deg", "bending_1", "bending_2")
_RIGID = ("gm_low_db", "gm_high_db", "pm_deg")


def _w_radps(worst: dict):
    """The frequency [rad/s] a worst figure of margins.json belongs to: the crossover of a
    margin (``w_radps``), the peak of a bending band (``w_peak_radps``); None if not given."""
    return worst.get("w_radps", worst.get("w_peak_radps"))


def _where(worst: dict | None) -> dict | None:
    """A worst figure of margins.json as value, time, corner and frequency (None without one)."""
    if not worst or worst.get("worst") is None:
        return None
    return {"value": worst["worst"], "t_s": worst.get("t_s"), "corner": worst.get("corner"),
            "w_radps": _w_radps(worst)}


def dispersed_figures(summary: dict) -> dict:
    """From the summary of ``vega margins --dispersed`` (margins.json): the unstable dispersed
    loops, the times where a stable dispersed loop misses the exact bending criterion (the
    gated figures); reported: the worst nominal margins (value and time; their frequencies in
    ``nominal_worst_w_radps``: the crossover of a margin, the peak of a bending band), the
    worst rigid margins over the dispersed plants (``dispersed_worst``: value, time, corner,
    crossover frequency; the PM is the distance of the phase from −180° at a gain crossover at
    or above the frozen-time floor), and the gain crossovers below that floor
    (``pm_below_floor``, nominal and dispersed: how many loops have one, the smallest distance
    there and where; not a criterion, docs/FLIGHT_DESIGN.md §3.1)."""
    everything = summary["dispersed"]["families"]["all"]["requirements"]
    nominal = summary["nominal"]
    low = {"nominal": nominal.get("pm_below_floor"), "dispersed": everything.get("pm_below_floor")}
    return {"unstable_loops": everything["stability"]["n_unstable_loops"],
            "bending_miss_times": max(everything["bending_1"]["n_fail_times"],
                                      everything["bending_2"]["n_fail_times"]),
            "bending_miss_intervals_s": {k: everything[k]["fail_intervals_s"]
                                         for k in ("bending_1", "bending_2")},
            "nominal_worst": {k: [nominal[k]["worst"], nominal[k].get("t_s")]
                              for k in _NOMINAL_WORST},
            "nominal_worst_w_radps": {k: _w_radps(nominal[k]) for k in _NOMINAL_WORST},
            "dispersed_worst": {k: _where(everything.get(k)) for k in _RIGID},
            "pm_below_floor": {
                which: None if v is None else {
                    "floor_radps": v.get("floor_radps"), "n_loops": v.get("n_loops"),
                    **(_where(v) or {"value": None})}
                for which, v in low.items()},
            "nominal_unstable_loops": nominal["stability"]["n_unstable_loops"]}


def _frozen(command: str, table, out: Path, workers: int, at: str, extra=()) -> tuple:
    """``vega COMMAND --table TABLE [EXTRA] --out OUT/COMMAND --workers W --at AT``: exit
    status, wall time, the summary it wrote (COMMAND.json) or None."""
    code, wall = _vega([command, "--table", str(table), *extra, "--out", str(out / command),
                        "--workers", str(workers), "--at", at], out / f"{command}.log")
    path = out / command / f"{command}.json"
    return code, wall, json.loads(path.read_text()) if path.exists() else None


def check_margins(table, out: Path, workers: int, at: str) -> list[dict]:
    """``vega margins --dispersed``: gated on its exit status, 0 unstable dispersed loops and
    0 times missing the exact bending criterion."""
    code, wall, summary = _frozen("margins", table, out, workers, at, ["--dispersed"])
    figures = {"log": "margins.log", **(dispersed_figures(summary) if summary else {})}
    passed = (code == 0 and figures.get("unstable_loops") == 0
              and figures.get("bending_miss_times") == 0)
    return [{"check": "margins --dispersed", "exit": code, "wall_s": round(wall, 1),
             "gated": True, "passed": passed, "figures": figures}]


def check_robust(table, out: Path, workers: int, at: str) -> list[dict]:
    """``vega robust --no-mu``: gated on its exit status (no unstable plant found, the worst
    case meets the bending criteria at every time)."""
    code, wall, result = _frozen("robust", table, out, workers, at, ["--no-mu"])
    summary = (result or {}).get("summary", {})
    figures = {"log": "robust.log", **{k: summary.get(k) for k in (
        "unstable_times_s", "worst_case_bending_fail_times_s", "robust_stability_pass",
        "worst_case_bending_pass")}}
    return [{"check": "robust --no-mu", "exit": code, "wall_s": round(wall, 1),
             "gated": True, "passed": code == 0, "figures": figures}]


def mc_figures(summary: dict, reference: int | None) -> dict:
    """From a campaign's summary.json: flights, passes, unstable flights, failures counted per
    requirement (a failed sample names its requirements comma-separated, e.g.
    ``"q_alpha,drift_rate"``: it counts once for each), the 90 % lower bound, the reference."""
    kinds: dict = {}
    for f in summary["failed_samples"]:
        for kind in str(f["failed"]).split(","):
            kinds[kind.strip()] = kinds.get(kind.strip(), 0) + 1
    return {"runs": summary["runs"], "passed": summary["passed"],
            "unstable": summary["unstable"], "failures_by_requirement": kinds,
            "pass_fraction_lower_90": summary["pass_fraction_lower_90"],
            "reference_passed": reference}


def _campaign(table, out: Path, environment: str, runs: int, workers: int,
              name: str) -> tuple[int, float, dict | None]:
    """``vega mc run --environment ENVIRONMENT`` of TABLE into OUT/NAME (its log OUT/NAME.log):
    the exit status, the wall time and the campaign's summary.json (None if it wrote none)."""
    code, wall = _vega(["mc", "run", "--environment", environment, "--runs", str(runs),
                        "--table", str(table), "--out", str(out / name), "--workers",
                        str(workers)], out / f"{name}.log")
    path = out / name / "summary.json"
    return code, wall, json.loads(path.read_text()) if path.exists() else None


def check_mc(table, out: Path, runs: int, workers: int, reference: int | None) -> list[dict]:
    """``vega mc run --environment thesis-box``: gated on 0 unstable flights and, with a
    reference, at least that many passes."""
    code, wall, s = _campaign(table, out, "thesis-box", runs, workers, "mc")
    figures = {"log": "mc.log"}
    passed = False
    if s is not None:
        figures.update(mc_figures(s, reference))
        passed = s["unstable"] == 0 and (reference is None or s["passed"] >= reference)
    return [{"check": f"mc {runs} flights", "exit": code, "wall_s": round(wall, 1),
             "gated": True, "passed": passed, "figures": figures}]


def flight_day_figures(summary: dict) -> dict:
    """From a flight-day campaign's summary.json: the flight-day counts and bound, the
    availability per month with and without the ground-wind criterion, and the verdict's
    parts."""
    fd = summary["flight_day"]
    design = summary.get("availability_design", summary["availability"])
    return {"n": fd["n"], "passed": fd["passed"], "failed": fd["failed"],
            "scrubbed": fd["scrubbed"], "lower_bound_90": fd["lower_bound_90"],
            "demonstrated_99_73_at_90": fd["demonstrated_99_73_at_90"],
            "unstable": fd["unstable"], "rate_limited": fd["rate_limited"],
            "scrub_reasons": fd["scrub_reasons"],
            "availability_design": design, "availability": summary["availability"],
            "availability_design_min": min(design.values()),
            "availability_min": min(summary["availability"].values()),
            "max_abs_q_alpha_pa_deg": summary["max_abs_q_alpha_pa_deg"]["go_max"]}


def flight_day_passed(f: dict) -> bool:
    """The flight-day gate on :func:`flight_day_figures`: 99.73 % at 90 % shown, no unstable
    or rate-limited go sample, the design's availability ≥ :data:`AVAILABILITY_FLOOR` in every
    month (the availability with the ground wind is reported, not gated)."""
    return bool(f["demonstrated_99_73_at_90"] and f["unstable"] == 0
                and f["rate_limited"] == 0
                and f["availability_design_min"] >= AVAILABILITY_FLOOR)


def check_flight_day(table, out: Path, runs: int, workers: int) -> list[dict]:
    """``vega mc run --environment flight-day``: gated on 99.73 % at 90 % shown, 0 unstable,
    0 rate-limited and the design's availability ≥ :data:`AVAILABILITY_FLOOR` every month."""
    code, wall, s = _campaign(table, out, "flight-day", runs, workers, "flight_day")
    figures = {"log": "flight_day.log"}
    passed = False
    if s is not None:
        figures.update(flight_day_figures(s))
        passed = flight_day_passed(figures)
    return [{"check": f"flight-day {runs} samples", "exit": code, "wall_s": round(wall, 1),
             "gated": True, "passed": passed, "figures": figures}]


def check_heldout(table, out: Path, workers: int, reference: Path) -> list[dict]:
    """TABLE flown on the samples of the campaign ``reference`` and compared with it flight by
    flight; reported, not gated."""
    from vega_campaign.compare import SAME_INPUTS, compare, load_campaign, plot

    ref_inputs, ref = load_campaign(reference)
    inputs_dir = out / "heldout_inputs"
    inputs_dir.mkdir()
    scenario = inputs_dir / f"{ref_inputs['scenario']}.yaml"     # a scenario file is named
    scenario.write_text(ref_inputs["scenario_yaml"])                 # after its scenario
    (inputs_dir / "dispersions.yaml").write_text(ref_inputs["dispersions_yaml"])
    seed, runs = str(ref_inputs["seed"]), str(ref_inputs["runs"])
    code, wall = _vega(["mc", "run", "--environment", "thesis-box", "--runs", runs, "--seed",
                        seed, "--table", str(table),
                        "--scenario", str(scenario),
                        "--dispersions", str(inputs_dir / "dispersions.yaml"),
                        "--out", str(out / "mc_heldout"), "--workers", str(workers)],
                       out / "mc_heldout.log")
    figures, passed = {"log": "mc_heldout.log", "reference": str(reference)}, False
    if (out / "mc_heldout" / "results.parquet").exists():
        inputs, got = load_campaign(out / "mc_heldout")
        differ = [k for k in SAME_INPUTS if inputs.get(k) != ref_inputs.get(k)]
        if differ:      # the same inputs were passed: a defect, not bad input
            raise RuntimeError(f"held-out campaign differs from {reference} in {differ}")
        report = compare(ref, got)
        plot(ref, got, report, out / "mc_heldout_compare.png", ("reference", "table"))
        figures.update({"seed": int(seed), "runs": report["runs"],
                        "reference_passed": report["passed_a"], "passed": report["passed_b"],
                        "lost": [f["sample"] for f in report["lost"]],
                        "won": [f["sample"] for f in report["won"]],
                        "mcnemar_exact_p": round(report["mcnemar_exact_p"], 4)})
        passed = report["passed_b"] >= report["passed_a"]
    return [{"check": f"mc held-out seed {seed}", "exit": code, "wall_s": round(wall, 1),
             "gated": False, "passed": passed, "figures": figures}]


def default_out(now: datetime | None = None) -> Path:
    """``bags/verify-<UTC time>`` (relative to the working directory): a new directory per
    sign-off run, where ``make verify-design`` puts it."""
    now = now or datetime.now(timezone.utc)
    return Path("bags") / f"verify-{now.strftime('%Y%m%dT%H%M%SZ')}"


@dataclass(frozen=True)
class Plan:
    """A checked sign-off run: what :func:`verify` runs and records."""

    table: Path                 # resolved
    out: Path
    checks: list
    scenarios: list
    at: str
    runs: int
    mc_reference: int | None
    workers: int
    heldout_reference: Path | None
    flight_day_runs: int = DEFAULT_FLIGHT_DAY_RUNS


def plan(table, out, checks: str = ",".join(CHECKS),
         scenarios: str = ",".join(GATED_SCENARIOS + REPORTED_SCENARIOS),
         runs: int = DEFAULT_RUNS, mc_reference: int | None = None, workers: int = 2,
         at: str = DEFAULT_AT, heldout_reference=None,
         flight_day_runs: int = DEFAULT_FLIGHT_DAY_RUNS) -> Plan:
    """Every input checked before anything runs; ``checks`` and ``scenarios`` are
    comma-separated lists.

    Raises
    ------
    BadInput
        One line naming the input: a table the flight loader refuses, an OUT that exists and is
        not an empty directory, an unknown check or scenario, runs or workers out of range, a
        held-out reference that is not a complete campaign.
    """
    from vega_gnc.controller_table import load_controller_table
    from vega_sim.scenario import load_scenario

    table = Path(table)
    try:
        load_controller_table(table)
    except (BadInput, OSError) as exc:          # anything else is a defect: a traceback
        raise BadInput(f"table {table}: {one_line(exc)}") from None
    out = Path(out)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise BadInput(f"--out {out}: exists and is not an empty directory")
    chosen = [c for c in checks.split(",") if c]
    unknown = [c for c in chosen if c not in CHECKS]
    if unknown or not chosen:
        raise BadInput(f"--checks {checks}: each of {', '.join(CHECKS)}")
    flown = [s for s in scenarios.split(",") if s]
    for name in flown:
        try:
            load_scenario(name)
        except (BadInput, OSError) as exc:
            raise BadInput(f"--scenarios {name}: {one_line(exc)}") from None
    if not 1 <= runs <= MAX_RUNS:
        raise BadInput(f"--runs {runs}: must be within 1..{MAX_RUNS}")
    if not 1 <= flight_day_runs <= MAX_RUNS:
        raise BadInput(f"--flight-day-runs {flight_day_runs}: must be within 1..{MAX_RUNS}")
    if not 1 <= workers <= MAX_WORKERS:
        raise BadInput(f"--workers {workers}: must be within 1..{MAX_WORKERS}")
    if heldout_reference is not None:
        from vega_campaign.compare import load_campaign

        heldout_reference = Path(heldout_reference)
        try:
            ref_inputs, _ = load_campaign(heldout_reference)
        except BadInput as exc:
            raise BadInput(f"--heldout-reference {exc}") from None
        if ref_inputs.get("environment") is not None:
            raise BadInput(f"--heldout-reference {heldout_reference}: a flight-day campaign "
                           "(the held-out comparison flies thesis-box campaigns)")
    return Plan(table.resolve(), out, chosen, flown, at, runs, mc_reference, workers,
                heldout_reference, flight_day_runs)


def _shown(result: dict, hidden) -> str:
    shown = {k: v for k, v in result["figures"].items() if k not in hidden}
    return f" {json.dumps(shown)}" if shown else ""


def _say(line: str) -> None:
    print(line, flush=True)


def verify(p: Plan, say=_say) -> dict:
    """Run the checks of ``p``, write ``p.out``/verify.json and return the record.

    ``say`` (default: print to stdout, flushed) gets one line per check as it starts and one
    per result (the verdict, the exit status, the wall time and the figures). The record's
    ``signed_off`` is true when every gated check passed and the table's bytes are those read
    before the first check.
    """
    p.out.mkdir(parents=True, exist_ok=True)
    digest = sha256_of(p.table)               # when it is read, not when the checks end
    results = []
    for check in p.checks:
        say(f"vega verify: {check} …")
        if check == "sil":
            got = check_sil(p.table, p.out, p.scenarios)
        elif check == "margins":
            got = check_margins(p.table, p.out, p.workers, p.at)
        elif check == "robust":
            got = check_robust(p.table, p.out, p.workers, p.at)
        elif check == "mc":
            got = check_mc(p.table, p.out, p.runs, p.workers, p.mc_reference)
        else:
            got = check_flight_day(p.table, p.out, p.flight_day_runs, p.workers)
        for r in got:
            verdict = ("pass" if r["passed"] else "FAIL") if r["gated"] else (
                "reported: " + ("pass" if r["passed"] else "fail"))
            say(f"  {r['check']}: {verdict} (exit {r['exit']}, {r['wall_s']:.0f} s)"
                + _shown(r, ("log", "run")))
        results.extend(got)
    if p.heldout_reference is not None:
        say("vega verify: held-out seed …")
        got = check_heldout(p.table, p.out, p.workers, p.heldout_reference)
        for r in got:
            say(f"  {r['check']}: reported: {'pass' if r['passed'] else 'fail'} "
                f"(exit {r['exit']}, {r['wall_s']:.0f} s)" + _shown(r, ("log", "reference")))
        results.extend(got)
    changed = sha256_of(p.table) != digest
    ok = all(r["passed"] for r in results if r["gated"]) and not changed
    record = {"table": str(p.table), "table_sha256": digest,
              "scope": {"checks": p.checks, "scenarios": p.scenarios, "at": p.at,
                        "runs": p.runs, "mc_reference": p.mc_reference,
                        "flight_day_runs": p.flight_day_runs,
                        **({"heldout_reference": str(p.heldout_reference)}
                           if p.heldout_reference is not None else {})},
              "finished_utc": datetime.now(timezone.utc).isoformat(timespec="seconds"),
              "checks": results, "signed_off": ok}
    (p.out / "verify.json").write_text(json.dumps(record, indent=1) + "\n")
    verdict = ("every gated check passed" if ok else
               f"{p.table} changed while the checks ran: not signed off" if changed else
               "a gated check FAILED")
    say(f"vega verify: {verdict}; {p.out / 'verify.json'}")
    return record
