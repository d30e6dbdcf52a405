"""``vega mc``: Monte Carlo dispersion campaigns (vega_campaign.campaign, campaign_run).

``vega mc margins --runs N [--at T|A:B:C] …`` computes the classical margins of the flown
controller at frozen times for N dispersed plants (the same samples), with the same statistics.

``vega mc rerun DIR --sample I [--out RUNDIR]`` flies that sample through the ROS 2 nodes (``vega
sil run`` on the sample's scenario) and checks that its bag's metrics equal the campaign row.

``vega mc compare A B [--out FILE.json] [--plot FILE.png]`` compares two complete campaigns
of the same samples flight by flight (:mod:`vega_campaign.compare`): passes, the flights B lost
and won, McNemar's exact p; exit 0 after the report, 2 for campaigns that are not complete or do
not fly the same samples.

``vega mc run --scenario NAME|PATH --runs N [--dispersions FILE] [--seed S] [--out DIR]
[--table FILE] [--workers K | --scheduler ADDRESS] [--batch B] [--resume DIR]
[--environment thesis-box|flight-day [--site FILE] [--month M] [--lag-s L] [--mode MODE]
[--lcc FILE]]`` flies N dispersed
copies of the scenario in process on a Dask cluster (a LocalCluster of K worker processes on
127.0.0.1 by default), in batches of up to B samples per task (the batched engine; ``--batch 1``:
one flight per task, the per-flight path; the same rows either way), writes every finished
sample as it comes, then ``results.parquet``, ``summary.json``, ``summary.md`` and plots. Exit
status: 2 on bad input (checked before anything starts). The default environment,
``flight-day`` (:mod:`vega_signoff.flight_day`), is the sign-off's: the site's statistical
winds, the guidance re-biased per sample to its sounding, the launch commit criterion judged
before each sample flies (every sample is flown); exit 0 when at least one sample was go and
every go sample passes the flight-day verdict, 1 otherwise. ``--environment thesis-box``: the
thesis' one wind profile scaled and shifted (docs/MONTE_CARLO.md §1–§5; ``vega verify``'s
regression campaign against the flown table); exit 0 if every flight passed, 1 if one failed.
"""

from __future__ import annotations

import argparse
import json
import time

from vega_core.errors import BadArgument, BadInput

__all__ = ["register"]

DEFAULT_OUT = "campaigns"

MAX_RUNS = 1_000_000
"""Largest ``--runs`` [flights or plants]. Assumption (a sanity bound, not a physical one): a
dispersed 100 s flight costs about 0.5 CPU s (docs/MONTE_CARLO.md §8, 203-209x real time per
CPU second), so 10^6 flights are about 6 CPU-days; the campaign lists every sample index in
memory before it starts, and a larger N (a typo such as 10^12) would exhaust the memory before
the first flight instead of being refused."""

MAX_BATCH = 512
"""Largest ``--batch`` [samples per task]. A batch holds ≈ 9 MB of records per 100-s sample
while it flies (vega_sim.batch), so 512 is ≈ 4.6 GB per worker process; the CPU per flight no
longer falls beyond ≈ 64-128 (docs/MONTE_CARLO.md §8)."""

MAX_WORKERS = 64
"""Largest ``--workers`` of the LocalCluster (worker processes on this host), the bound
``vega robust`` and ``vega design`` use; a larger K would start that many processes."""


def _positive_int(highest: int):
    """argparse type: an integer in 1..``highest``."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
        if value < 1:
            raise argparse.ArgumentTypeError(f"must be >= 1, got {text!r}")
        if value > highest:
            raise argparse.ArgumentTypeError(f"must be <= {highest}, got {text!r}")
        return value
    return parse


_CAMPAIGN_FIELDS = {"scenario_yaml": str, "dispersions_yaml": str, "dispersions_path": str,
                    "seed": int, "runs": int, "table": str, "table_sha256": str}
"""The campaign.json fields ``--resume`` reads (vega_campaign.campaign_run._inputs) and
their JSON types; ``kind`` (a string) and ``times_s`` (null or a list of numbers) may be
absent."""


def _json_object(path, what: str) -> dict:
    """The JSON object in ``path`` (at most 1 MiB of UTF-8); one line (BadFile) otherwise."""
    from vega_core.documents import read_text
    from vega_core.errors import BadFile

    text = read_text(path, what)
    try:
        value = json.loads(text)
    except json.JSONDecodeError as exc:
        raise BadFile(f"{path}: not a {what} ({exc})") from None
    if not isinstance(value, dict):
        raise BadFile(f"{path}: not a {what} (a JSON object expected)")
    return value


def _resumed_inputs(path) -> dict:
    """A campaign directory's campaign.json, checked before anything starts: at most 1 MiB of
    UTF-8 JSON, an object with every field of :data:`_CAMPAIGN_FIELDS` of its type, ``runs``
    in 1..``MAX_RUNS`` and ``seed`` in the int64 range; one line (BadFile, exit 2) otherwise —
    a damaged or edited file is bad input, not a defect."""
    from vega_bringup.planning import _checked_seed
    from vega_core.errors import BadFile

    inputs = _json_object(path, "campaign.json")
    for key, kind in _CAMPAIGN_FIELDS.items():
        value = inputs.get(key)
        if not isinstance(value, kind) or isinstance(value, bool):
            raise BadFile(f"{path}: field '{key}': must be a JSON "
                          f"{'string' if kind is str else 'integer'}, got {value!r:.60}")
    if not isinstance(inputs.get("kind", "flights"), str):
        raise BadFile(f"{path}: field 'kind': must be a JSON string")
    times = inputs.get("times_s")
    if times is not None and not (isinstance(times, list) and all(
            isinstance(t, (int, float)) and not isinstance(t, bool) for t in times)):
        raise BadFile(f"{path}: field 'times_s': must be null or a list of numbers")
    if inputs.get("environment") is not None:
        from vega_signoff.flight_day import parse_environment

        parse_environment(inputs["environment"], str(path))
    if not 1 <= inputs["runs"] <= MAX_RUNS:
        raise BadFile(f"{path}: field 'runs': must be within 1..{MAX_RUNS}, got "
                      f"{inputs['runs']}")
    try:
        _checked_seed(inputs["seed"])
    except BadInput as exc:
        raise BadFile(f"{path}: field 'seed': {exc}") from None
    return inputs


def _campaign(args: argparse.Namespace, kind: str) -> dict:
    """The inputs of a ``kind`` campaign ("flights" or "margins"): from ``--resume DIR``'s
    campaign.json (a campaign of the other kind refused), else from the arguments. Every input
    file is loaded and checked here, before anything starts (one line, exit 2)."""
    from pathlib import Path

    from vega_campaign.campaign import load_dispersions, parse_dispersions
    from vega_bringup.planning import _checked_seed
    from vega_gnc.controller_table import default_table_path
    from vega_sim.scenario import load_scenario, parse_scenario

    if args.workers is not None and args.scheduler:
        raise BadArgument("--workers and --scheduler exclude each other")
    if args.resume:
        out = Path(args.resume)
        path = out / "campaign.json"
        if not path.is_file():
            raise BadArgument(f"--resume {out}: no campaign.json (not a campaign directory)")
        inputs = _resumed_inputs(path)
        if inputs.get("kind", "flights") != kind:
            other = "run" if kind == "margins" else "margins"
            raise BadArgument(f"--resume {out}: a {inputs.get('kind', 'flights')} campaign "
                              f"(use vega mc {other} --resume)")
        return {"scenario": parse_scenario(inputs["scenario_yaml"], f"{path}: scenario_yaml"),
                "disp": parse_dispersions(inputs["dispersions_yaml"],
                                          inputs["dispersions_path"]),
                "seed": inputs["seed"], "runs": inputs["runs"],
                "table_path": Path(inputs["table"]), "out": out,
                "times": inputs.get("times_s"), "environment": inputs.get("environment")}
    if args.runs is None:
        raise BadArgument("--runs N is required (or --resume DIR)")
    seed = _checked_seed(args.seed) or 0
    if kind == "margins":
        from vega_cli.commands.margins import parse_at

        times, scenario = parse_at(args.at), load_scenario("nominal")
        default_name = f"margins-seed{seed}-n{args.runs}"
    else:
        times, scenario = None, load_scenario(args.scenario)
        default_name = f"{scenario.name}-seed{seed}-n{args.runs}"
    environment = _environment(args) if kind == "flights" else None
    if environment is not None:
        default_name = f"{scenario.name}-flight-day-seed{seed}-n{args.runs}"
    return {"scenario": scenario, "disp": load_dispersions(args.dispersions), "seed": seed,
            "runs": args.runs,
            "table_path": Path(args.table) if args.table else default_table_path(),
            "out": Path(args.out) if args.out else Path(DEFAULT_OUT) / default_name,
            "times": times, "environment": environment}


_FLIGHT_DAY_OPTIONS = ("site", "month", "lag_s", "mode", "lcc")


def _environment(args: argparse.Namespace) -> dict | None:
    """The flight-day environment of ``vega mc run`` (None: the thesis box), its files loaded
    and checked now; a flight-day option without ``--environment flight-day`` is refused."""
    from vega_signoff.flight_day import FLIGHT_DAY, environment_settings

    if getattr(args, "environment", None) != FLIGHT_DAY:
        given = [o for o in _FLIGHT_DAY_OPTIONS if getattr(args, o, None) is not None]
        if given:
            raise BadArgument(f"--{given[0].replace('_', '-')} needs --environment flight-day")
        return None
    return environment_settings(args.site, args.month, args.lag_s, args.mode, args.lcc)


def _fly(args: argparse.Namespace, c: dict, kind: str) -> tuple[list[dict], dict]:
    """Run (or finish) the campaign ``c`` on Dask; its rows and its campaign.json inputs."""
    from vega_campaign.campaign_run import DEFAULT_BATCH, run_campaign, write_results

    rows = run_campaign(c["scenario"], c["disp"], runs=c["runs"], seed=c["seed"], out=c["out"],
                        table_path=c["table_path"].resolve(), workers=args.workers,
                        scheduler=args.scheduler, resume=bool(args.resume), kind=kind,
                        times_s=c["times"], batch=getattr(args, "batch", DEFAULT_BATCH),
                        environment=c.get("environment"), task=_task(c.get("environment")))
    write_results(c["out"], rows)
    return rows, json.loads((c["out"] / "campaign.json").read_text())


def _task(environment: dict | None):
    """The Dask task of a campaign in ``environment`` (None: the thesis box's own)."""
    if environment is None:
        return None
    from vega_signoff.flight_day import fly_flight_day_batch

    return fly_flight_day_batch


def _write_summary(out, summary: dict, markdown: str, files: str) -> int:
    (out / "summary.json").write_text(json.dumps(summary, indent=1, sort_keys=True) + "\n")
    (out / "summary.md").write_text(markdown)
    print(markdown, end="")
    print(f"vega mc: {out}/ ({files})")
    if "flight_day" in summary:     # nothing is shown when every sample was scrubbed
        fd = summary["flight_day"]
        return 0 if fd["failed"] == 0 and fd["n"] > 0 else 1
    return 0 if summary["passed"] == summary["runs"] else 1


def _run(args: argparse.Namespace) -> int:
    """``vega mc run``: dispersed flights."""
    from vega_campaign.campaign_run import (plot_campaign, read_rows, summarise,
                                                summary_markdown)
    from vega_loops.margins import check_table_stabilises
    from vega_gnc.controller_table import load_controller_table
    from vega_model.parameters import default_context
    from vega_sim.closed_loop import scenario_reference

    t0 = time.monotonic()
    c = _campaign(args, "flights")
    table = load_controller_table(c["table_path"])   # a bad table: one line, exit 2
    check_table_stabilises(table, default_context(), c["scenario"].t_start_s,
                           c["scenario"].t_end_s)
    scenario_reference(c["scenario"])                 # likewise the guidance reference
    rows, inputs = _fly(args, c, "flights")
    summary = summarise(rows, inputs, wall_s=time.monotonic() - t0)
    markdown = summary_markdown(summary)
    files = ("results.parquet, summary.json, summary.md, histograms.png, "
             "sensitivity_q_alpha.png, q_alpha_band.png")
    not_dispersed: tuple = ()
    if inputs.get("environment") is not None:
        from vega_signoff.flight_day import (NOT_DISPERSED, flight_day_markdown,
                                             plot_flight_day, summarise_flight_day)

        summary.update(summarise_flight_day(rows))
        summary["environment"] = {k: v for k, v in inputs["environment"].items()
                                  if not k.endswith("_yaml")}
        markdown += flight_day_markdown(summary, summary["environment"])
        plot_flight_day(c["out"], rows)
        files += ", availability_by_month.png, q_alpha_allowable.png"
        not_dispersed = NOT_DISPERSED
    plot_campaign(c["out"], read_rows(c["out"]), summary, not_dispersed)
    return _write_summary(c["out"], summary, markdown, files)


def _rerun(args: argparse.Namespace) -> int:
    """``vega mc rerun DIR --sample I``: the sample through the ROS 2 nodes; its bag's metrics
    against the campaign's row."""
    from pathlib import Path

    from vega_campaign.campaign import flight_metrics, parse_dispersions, sample_scenario
    from vega_bags import bagio
    from vega_bags.bagcheck import bag_result
    from vega_cli import cli
    from vega_sim.scenario import dump_scenario, parse_scenario

    camp = Path(args.dir)
    path = camp / "campaign.json"
    if not path.is_file():
        raise BadArgument(f"{camp}: no campaign.json (not a campaign directory)")
    inputs = _resumed_inputs(path)
    if not 0 <= args.sample < inputs["runs"]:
        raise BadArgument(f"--sample {args.sample}: the campaign has samples "
                          f"0-{inputs['runs'] - 1}")
    row_path = camp / "samples" / f"{args.sample:06d}.json"
    if not row_path.is_file():
        raise BadArgument(f"--sample {args.sample}: not flown yet in {camp} (--resume it first)")
    row = _json_object(row_path, "campaign sample row")
    base = parse_scenario(inputs["scenario_yaml"], f"{path}: scenario_yaml")
    disp = parse_dispersions(inputs["dispersions_yaml"], inputs["dispersions_path"])
    extra = None
    if inputs.get("environment") is not None:   # the flight day: the campaign's own reference
        from vega_signoff.flight_day import flight_day_metrics, scenario_path

        recorded = scenario_path(camp, args.sample)
        if not recorded.is_file():
            raise BadArgument(f"--sample {args.sample}: {recorded} is missing (the scenario "
                              f"the flight-day sample flew)")
        scenario = parse_scenario(recorded.read_text(), str(recorded))
        extra = flight_day_metrics
    else:
        scenario, _ = sample_scenario(base, disp, inputs["seed"], args.sample)
    out = Path(args.out) if args.out else camp / "reruns"
    out.mkdir(parents=True, exist_ok=True)
    scenario_file = out / f"{scenario.name}.yaml"
    scenario_file.write_text(dump_scenario(scenario))
    run_id = f"{scenario.name}-seed{scenario.seed}"
    status = cli.main(["sil", "run", "--scenario", str(scenario_file), "--table",
                       inputs["table"], "--out", str(out), "--run-id", run_id])
    bag_dir = out / run_id / "bag"
    if status not in (0, 1) or not bag_dir.is_dir():
        print(f"vega mc rerun: the SIL run ended with exit status {status}; no comparison")
        return status if status else 1
    result = bag_result(bagio.read_run_bag(bag_dir))
    got = flight_metrics(result)
    if extra is not None:
        got.update(extra(result))
    # compared as JSON text: NaN (an empty Mach bin) equals NaN, floats to the last bit
    differ = [k for k, v in got.items() if json.dumps(v) != json.dumps(row[k])]
    for k in differ:
        print(f"  {k}: campaign {row[k]!r}, SIL bag {got[k]!r}")
    print(f"vega mc rerun: sample {args.sample} through the ROS 2 nodes ({bag_dir}): "
          + ("every metric of the campaign row identical" if not differ
             else f"{len(differ)} metrics differ"))
    return 0 if not differ else 1


def _margins(args: argparse.Namespace) -> int:
    """``vega mc margins``: classical margins at frozen times over N dispersed plants."""
    from vega_campaign.campaign_run import margins_markdown, summarise_margins
    from vega_gnc.controller_table import load_controller_table

    t0 = time.monotonic()
    c = _campaign(args, "margins")
    load_controller_table(c["table_path"])            # a bad table: one line, exit 2
    rows, inputs = _fly(args, c, "margins")
    summary = summarise_margins(rows, inputs, wall_s=time.monotonic() - t0)
    return _write_summary(c["out"], summary, margins_markdown(summary),
                          "results.parquet, summary.json, summary.md")


def _compare(args: argparse.Namespace) -> int:
    """``vega mc compare A B``: two campaigns of the same samples, flight by flight."""
    from pathlib import Path

    from vega_campaign.compare import (check_same_samples, compare, load_campaign, plot,
                                       report_lines)

    dir_a, dir_b = Path(args.a), Path(args.b)
    inputs_a, a = load_campaign(dir_a)
    inputs_b, b = load_campaign(dir_b)
    check_same_samples(inputs_a, inputs_b, dir_a, dir_b)
    report = compare(a, b)
    report["a"] = {"dir": str(dir_a), "table_sha256": inputs_a.get("table_sha256")}
    report["b"] = {"dir": str(dir_b), "table_sha256": inputs_b.get("table_sha256")}
    print("\n".join(report_lines(report, inputs_a.get("seed"))))
    if args.out:
        Path(args.out).write_text(json.dumps(report, indent=1) + "\n")
    if args.plot:
        plot(a, b, report, Path(args.plot), (dir_a.name, dir_b.name))
    return 0


def _no_action(args) -> int:
    raise BadArgument("vega mc: choose an action (run, margins, rerun, compare)")


def _campaign_arguments(parser, what: str, default_out: str) -> None:
    """The arguments ``vega mc run`` and ``vega mc margins`` share."""
    parser.add_argument("--runs", type=_positive_int(MAX_RUNS), default=None, metavar="N",
                        help=f"number of dispersed {what} (1..{MAX_RUNS})")
    parser.add_argument("--dispersions", default=None, metavar="FILE",
                        help="dispersion file (default: the shipped "
                             "offline/vega_campaign/data/dispersions.yaml)")
    parser.add_argument("--seed", default=None, metavar="S", help="campaign seed (default 0)")
    parser.add_argument("--out", default=None, metavar="DIR",
                        help=f"campaign directory (must not exist or be empty; default: "
                             f"{DEFAULT_OUT}/{default_out})")
    parser.add_argument("--table", default=None, metavar="FILE",
                        help="controller table (default: the installed one)")
    parser.add_argument("--workers", type=_positive_int(MAX_WORKERS), default=None, metavar="K",
                        help=f"worker processes of the LocalCluster (1..{MAX_WORKERS}; "
                             f"default: one per core)")
    parser.add_argument("--scheduler", default=None, metavar="ADDRESS",
                        help="run on an existing Dask scheduler (e.g. tcp://127.0.0.1:8786)")
    parser.add_argument("--resume", default=None, metavar="DIR",
                        help="finish the campaign in DIR (its own inputs; the others are "
                             "ignored)")


def _default_batch() -> int:
    """The default ``--batch`` (the campaign runner's)."""
    from vega_campaign.campaign_run import DEFAULT_BATCH

    return DEFAULT_BATCH


def register(subparsers) -> None:
    """Add the ``mc`` sub-command (actions ``run``, ``margins``, ``rerun``, ``compare``)."""
    parser = subparsers.add_parser(
        "mc", help="Monte Carlo dispersion campaigns on Dask",
        description="Fly dispersed copies of a scenario in process on a Dask cluster and "
                    "state the pass fraction with its confidence bounds.")
    parser.set_defaults(func=_no_action)
    actions = parser.add_subparsers(dest="action", metavar="ACTION")
    run = actions.add_parser(
        "run", help="fly a campaign",
        description="N dispersed flights of a scenario (sample i depends on the campaign seed "
                    "and i only). Exit 0 all passed, 1 a flight failed, 2 bad input.")
    run.add_argument("--scenario", default="nominal", metavar="NAME|PATH",
                     help="shipped scenario name or YAML file (default: nominal)")
    _campaign_arguments(run, "flights", "<scenario>-seed<S>-n<N>")
    run.add_argument("--batch", type=_positive_int(MAX_BATCH), default=_default_batch(),
                     metavar="B",
                     help=f"most samples flown at once per Dask task by the batched engine "
                          f"(1..{MAX_BATCH}; default %(default)s; 1: one flight per task, the "
                          f"per-flight path; the rows are the same either way, also when "
                          f"resuming)")
    run.add_argument("--environment", choices=("thesis-box", "flight-day"),
                     default="flight-day",
                     help="wind environment: flight-day (default, the sign-off: the site's "
                          "statistical winds, guidance re-biased per sample, launch commit "
                          "criterion) or thesis-box (the thesis profile scaled and shifted)")
    run.add_argument("--site", default=None, metavar="FILE",
                     help="flight-day: wind site file (default: the shipped Kourou file)")
    run.add_argument("--month", type=_positive_int(12), default=None, metavar="M",
                     help="flight-day: every sample in month M (1..12; default: the 12 "
                          "months in turn)")
    run.add_argument("--lag-s", type=float, default=None, metavar="L",
                     help="flight-day: sounding-to-lift-off lag [s] (default: the site "
                          "model's, 5400)")
    run.add_argument("--mode", choices=("full_speed", "in_plane"), default=None,
                     help="flight-day: flight-plane mode of the wind (default full_speed)")
    run.add_argument("--lcc", default=None, metavar="FILE",
                     help="flight-day: launch commit criterion file (default: the shipped "
                          "offline/vega_signoff/data/lcc.yaml)")
    run.set_defaults(func=_run)
    margins = actions.add_parser(
        "margins", help="margins of the flown controller over dispersed plants",
        description="Classical margins (exact sampled-data loop, vega margins) of the flown "
                    "controller on the nominal schedule at frozen times, for N plants drawn "
                    "from the dispersions (sample i: the campaign seed and i only). Exit 0 "
                    "every plant stable at every time, 1 not, 2 bad input.")
    margins.add_argument("--at", default="10:90:10", metavar="T|START:STOP:STEP",
                         help="frozen times [s] (default 10:90:10)")
    _campaign_arguments(margins, "plants", "margins-seed<S>-n<N>")
    margins.set_defaults(func=_margins)
    rerun = actions.add_parser(
        "rerun", help="fly one campaign sample through the ROS 2 nodes",
        description="Fly sample I of the campaign in DIR with `vega sil run` (the dispersed "
                    "scenario written to OUT), then compare the bag's metrics with the "
                    "campaign's row. Exit 0 identical, 1 different (or the run failed), 2 bad "
                    "input.")
    rerun.add_argument("dir", metavar="DIR", help="campaign directory")
    rerun.add_argument("--sample", type=int, required=True, metavar="I", help="sample index")
    rerun.add_argument("--out", default=None, metavar="RUNDIR",
                       help="where the scenario and the run go (default: DIR/reruns)")
    rerun.set_defaults(func=_rerun)
    comp = actions.add_parser(
        "compare", help="compare two campaigns of the same samples flight by flight",
        description="Pair the samples of two complete campaigns with the same scenario, "
                    "dispersions, seed and runs (A the reference, B the candidate): passes, "
                    "the flights B lost and won with their requirements and Qα ratios, "
                    "McNemar's exact p on those, the median Qα-ratio change. Exit 0 after the "
                    "report, 2 for campaigns that are not complete or do not fly the same "
                    "samples.")
    comp.add_argument("a", metavar="A", help="reference campaign directory")
    comp.add_argument("b", metavar="B", help="candidate campaign directory")
    comp.add_argument("--out", default=None, metavar="FILE.json",
                      help="also write the comparison as JSON")
    comp.add_argument("--plot", default=None, metavar="FILE.png",
                      help="also write the Qα-ratio scatter, B against A")
    comp.set_defaults(func=_compare)
