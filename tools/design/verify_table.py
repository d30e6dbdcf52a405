"""The sign-off checks of a controller table, in one command: what a new design must pass before
it replaces the shipped one (docs/FLIGHT_DESIGN.md §6.5, "How a design is signed off").

Checks (each the repository's own command, run as a subprocess, its output kept in OUT):

* ``sil`` — `vega sil run --table TABLE` for each scenario: gated (exit 0 required) for
  nominal, thesis, gust, wind_change (issue 9 item 6) and the four dispersed scenarios
  (dispersed_bending_low/high, dispersed_mode2, dispersed_worst); reported, not gated, for
  severe (declared off-design in its scenario file) and nominal_no_bias (the guidance's
  no-bias case, expected to fail its drift and load requirements);
* ``margins`` — `vega margins --table TABLE --dispersed`: gated on its exit status (the
  heritage margins on the nominal plant at every 0.5 s) and, from its margins.json, on 0
  unstable dispersed loops and the exact bending criterion (docs/FLIGHT_DESIGN.md §3) at every
  dispersed corner and time; the worst nominal margins are reported;
* ``robust`` — `vega robust --table TABLE --no-mu`: gated on its exit status (no unstable
  plant found, the worst case meets the bending criteria at every time);
* ``mc`` — `vega mc run --table TABLE --runs N`: gated on 0 unstable flights; passes, Qα and
  drift failures reported (and compared with ``--mc-reference PASSED`` when given: a design
  that passes fewer flights than the shipped one is reported as such, and gated).

With ``--heldout-reference DIR`` (a complete campaign of the reference table on another seed,
docs/FLIGHT_DESIGN.md §6.5 "A held-out seed"), one more campaign flies TABLE on the samples of
DIR (its scenario, dispersions, seed and number of flights) and is compared with it flight by
flight (``compare_campaigns.py``: passes, flights lost and won, McNemar's exact p); reported,
not gated, and not part of the sign-off's scope of checks.

Writes OUT/verify.json (the table's path and SHA-256, the scope of the checks — which checks,
scenarios, frozen times, flights and reference —, per check: command, exit status, wall time,
figures, verdict) and prints one line per check; ``tools/design/ship_table.py OUT`` ships a
table only from a complete, passed record of its own bytes. Exit 0 when every gated check
passes, 1 when one fails (or the table file changed while the checks ran: the record is then
not a sign-off of any bytes), 2 on bad input (one line, before anything runs).

Usage: .venv/bin/vega-env python tools/design/verify_table.py TABLE --out DIR
       [--checks sil,margins,robust,mc] [--scenarios A,B] [--runs 852] [--mc-reference 746]
       [--workers 2] [--at 0:100:0.5] [--heldout-reference CAMPAIGN_DIR]
"""

from __future__ import annotations

import argparse
import hashlib
import json
import subprocess
import sys
import time
from datetime import datetime, timezone
from pathlib import Path

from vega_core.errors import BadInput, one_line

CHECKS = ("sil", "margins", "robust", "mc")
GATED_SCENARIOS = ("nominal", "thesis", "gust", "wind_change", "dispersed_bending_low",
                   "dispersed_bending_high", "dispersed_mode2", "dispersed_worst")
REPORTED_SCENARIOS = ("severe", "nominal_no_bias")


def _vega(args, log: Path) -> tuple[int, float]:
    """Run ``vega ARGS`` (this interpreter, the repository's environment), its stdout and
    stderr into ``log``; the exit status and the wall time."""
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


def dispersed_figures(summary: dict) -> dict:
    """From the summary of `vega margins --dispersed` (margins.json): the unstable dispersed
    loops, the times where a stable dispersed loop misses the exact bending criterion, and the
    worst nominal margins (value and time)."""
    everything = summary["dispersed"]["families"]["all"]["requirements"]
    nominal = summary["nominal"]
    return {"unstable_loops": everything["stability"]["n_unstable_loops"],
            "bending_miss_times": max(everything["bending_1"]["n_fail_times"],
                                      everything["bending_2"]["n_fail_times"]),
            "bending_miss_intervals_s": {k: everything[k]["fail_intervals_s"]
                                         for k in ("bending_1", "bending_2")},
            "nominal_worst": {k: [nominal[k]["worst"], nominal[k].get("t_s")]
                              for k in ("gm_low_db", "gm_high_db", "pm_deg", "bending_1",
                                        "bending_2")},
            "nominal_unstable_loops": nominal["stability"]["n_unstable_loops"]}


def _frozen(command: str, table, out: Path, workers: int, at: str, extra=()) -> tuple:
    """`vega COMMAND --table TABLE [EXTRA] --out OUT/COMMAND --workers W --at AT`: exit status,
    wall time, the summary it wrote (COMMAND.json) or None."""
    code, wall = _vega([command, "--table", str(table), *extra, "--out", str(out / command),
                        "--workers", str(workers), "--at", at], out / f"{command}.log")
    path = out / command / f"{command}.json"
    return code, wall, json.loads(path.read_text()) if path.exists() else None


def check_margins(table, out: Path, workers: int, at: str) -> list[dict]:
    """`vega margins --dispersed`: gated on its exit status, 0 unstable dispersed loops and 0
    times missing the exact bending criterion."""
    code, wall, summary = _frozen("margins", table, out, workers, at, ["--dispersed"])
    figures = {"log": "margins.log", **(dispersed_figures(summary) if summary else {})}
    passed = (code == 0 and figures.get("unstable_loops") == 0
              and figures.get("bending_miss_times") == 0)
    return [{"check": "margins --dispersed", "exit": code, "wall_s": round(wall, 1),
             "gated": True, "passed": passed, "figures": figures}]


def check_robust(table, out: Path, workers: int, at: str) -> list[dict]:
    """`vega robust --no-mu`: gated on its exit status (no unstable plant found, the worst
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


def check_mc(table, out: Path, runs: int, workers: int, reference: int | None) -> list[dict]:
    """`vega mc run`: gated on 0 unstable flights and, with a reference, at least that many
    passes."""
    code, wall = _vega(["mc", "run", "--runs", str(runs), "--table", str(table), "--out",
                        str(out / "mc"), "--workers", str(workers)], out / "mc.log")
    figures = {"log": "mc.log"}
    path = out / "mc" / "summary.json"
    passed = False
    if path.exists():
        s = json.loads(path.read_text())
        figures.update(mc_figures(s, reference))
        passed = s["unstable"] == 0 and (reference is None or s["passed"] >= reference)
    return [{"check": f"mc {runs} flights", "exit": code, "wall_s": round(wall, 1),
             "gated": True, "passed": passed, "figures": figures}]


def check_heldout(table, out: Path, workers: int, reference: Path) -> list[dict]:
    """TABLE flown on the samples of the campaign ``reference`` and compared with it flight by
    flight; reported, not gated."""
    from compare_campaigns import SAME_INPUTS, compare, load_campaign, plot

    ref_inputs, ref = load_campaign(reference)
    inputs_dir = out / "heldout_inputs"
    inputs_dir.mkdir()
    scenario = inputs_dir / f"{ref_inputs['scenario']}.yaml"     # a scenario file is named
    scenario.write_text(ref_inputs["scenario_yaml"])                 # after its scenario
    (inputs_dir / "dispersions.yaml").write_text(ref_inputs["dispersions_yaml"])
    seed, runs = str(ref_inputs["seed"]), str(ref_inputs["runs"])
    code, wall = _vega(["mc", "run", "--runs", runs, "--seed", seed, "--table", str(table),
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


def sha256_of(path: Path) -> str:
    """The SHA-256 of the file at ``path`` (hex): ties a sign-off record to the table's bytes,
    so `ship_table.py` can refuse a table changed after it was verified."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def parse(argv):
    """The command line (module docstring)."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("table")
    p.add_argument("--out", required=True)
    p.add_argument("--checks", default=",".join(CHECKS))
    p.add_argument("--scenarios", default=",".join(GATED_SCENARIOS + REPORTED_SCENARIOS))
    p.add_argument("--runs", type=int, default=852)
    p.add_argument("--mc-reference", type=int, default=None)
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--at", default="0:100:0.5",
                   help="frozen times of margins and robust (default 0:100:0.5, the flight)")
    p.add_argument("--heldout-reference", type=Path, default=None,
                   help="a campaign of the reference table on a held-out seed (reported)")
    return p.parse_args(argv)


def validate(args) -> tuple[Path, Path, list[str], list[str]]:
    """Every argument checked before anything runs (:class:`BadInput`)."""
    from vega_gnc.controller_table import load_controller_table

    table = Path(args.table)
    try:
        load_controller_table(table)
    except (BadInput, OSError) as exc:          # anything else is a defect: a traceback
        raise BadInput(f"table {table}: {one_line(exc)}") from None
    out = Path(args.out)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise BadInput(f"--out {out}: exists and is not an empty directory")
    checks = [c for c in args.checks.split(",") if c]
    unknown = [c for c in checks if c not in CHECKS]
    if unknown or not checks:
        raise BadInput(f"--checks {args.checks}: each of {', '.join(CHECKS)}")
    from vega_sim.scenario import load_scenario

    scenarios = [s for s in args.scenarios.split(",") if s]
    for name in scenarios:
        try:
            load_scenario(name)
        except (BadInput, OSError) as exc:
            raise BadInput(f"--scenarios {name}: {one_line(exc)}") from None
    if not 1 <= args.runs <= 100000:
        raise BadInput(f"--runs {args.runs}: must be within 1..100000")
    if not 1 <= args.workers <= 64:
        raise BadInput(f"--workers {args.workers}: must be within 1..64")
    if args.heldout_reference is not None:
        from compare_campaigns import load_campaign

        try:
            load_campaign(args.heldout_reference)
        except BadInput as exc:
            raise BadInput(f"--heldout-reference {exc}") from None
    return table.resolve(), out, checks, scenarios


def main(argv=None) -> int:
    """Run the checks; exit status 0 signed off, 1 a gated check failed, 2 bad input."""
    args = parse(argv)
    try:
        table, out, checks, scenarios = validate(args)
    except BadInput as exc:
        print(f"verify_table: {exc}", file=sys.stderr)
        return 2
    out.mkdir(parents=True, exist_ok=True)
    digest = sha256_of(table)               # when it is read, not when the checks end
    results = []
    for check in checks:
        print(f"verify_table: {check} …", flush=True)
        if check == "sil":
            got = check_sil(table, out, scenarios)
        elif check == "margins":
            got = check_margins(table, out, args.workers, args.at)
        elif check == "robust":
            got = check_robust(table, out, args.workers, args.at)
        else:
            got = check_mc(table, out, args.runs, args.workers, args.mc_reference)
        for r in got:
            verdict = ("pass" if r["passed"] else "FAIL") if r["gated"] else (
                "reported: " + ("pass" if r["passed"] else "fail"))
            shown = {k: v for k, v in r["figures"].items() if k not in ("log", "run")}
            print(f"  {r['check']}: {verdict} (exit {r['exit']}, {r['wall_s']:.0f} s)"
                  + (f" {json.dumps(shown)}" if shown else ""), flush=True)
        results.extend(got)
    if args.heldout_reference is not None:
        print("verify_table: held-out seed …", flush=True)
        got = check_heldout(table, out, args.workers, args.heldout_reference)
        for r in got:
            shown = {k: v for k, v in r["figures"].items() if k not in ("log", "reference")}
            print(f"  {r['check']}: reported: {'pass' if r['passed'] else 'fail'} "
                  f"(exit {r['exit']}, {r['wall_s']:.0f} s) {json.dumps(shown)}", flush=True)
        results.extend(got)
    changed = sha256_of(table) != digest
    ok = all(r["passed"] for r in results if r["gated"]) and not changed
    (out / "verify.json").write_text(json.dumps(
        {"table": str(table), "table_sha256": digest,
         "scope": {"checks": checks, "scenarios": scenarios, "at": args.at, "runs": args.runs,
                   "mc_reference": args.mc_reference,
                   **({"heldout_reference": str(args.heldout_reference)}
                      if args.heldout_reference is not None else {})},
         "finished_utc": datetime.now(timezone.utc).isoformat(timespec="seconds"),
         "checks": results, "signed_off": ok}, indent=1) + "\n")
    verdict = ("every gated check passed" if ok else
               f"{table} changed while the checks ran: not signed off" if changed else
               "a gated check FAILED")
    print(f"verify_table: {verdict}; {out / 'verify.json'}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
