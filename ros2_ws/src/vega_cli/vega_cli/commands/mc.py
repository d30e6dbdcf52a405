"""``vega mc``: Monte Carlo dispersion campaigns (offline_synthesis.campaign, campaign_run).

``vega mc margins --runs N [--at T|A:B:C] …`` computes the classical margins of the flown
controller at frozen times for N dispersed plants (the same samples), with the same statistics.

``vega mc rerun DIR --sample I [--out RUNDIR]`` flies that sample through the ROS 2 nodes (``vega
sil run`` on the sample's scenario) and checks that its bag's metrics equal the campaign row.

``vega mc run --scenario NAME|PATH --runs N [--dispersions FILE] [--seed S] [--out DIR]
[--table FILE] [--workers K | --scheduler ADDRESS] [--resume DIR]`` flies N dispersed copies of
the scenario in process on a Dask cluster (a LocalCluster of K worker processes on 127.0.0.1 by
default), writes every finished sample as it comes, then ``results.parquet``, ``summary.json``,
``summary.md`` and plots. Exit status: 0 if every flight passed, 1 if one failed, 2 on bad
input (checked before anything starts).
"""

from __future__ import annotations

import argparse
import json
import time

from vega_core.errors import BadArgument

__all__ = ["register"]

DEFAULT_OUT = "campaigns"


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be >= 1, got {text!r}")
    return value


def _run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from offline_synthesis.campaign import load_dispersions, parse_dispersions
    from offline_synthesis.campaign_run import (plot_campaign, read_rows, run_campaign,
                                                summarise, summary_markdown, write_results)
    from offline_synthesis.margins import check_table_stabilises
    from vega_bringup.planning import _checked_seed
    from vega_model.parameters import default_context
    from vega_gnc.controller_table import default_table_path, load_controller_table
    from vega_sim.closed_loop import scenario_reference
    from vega_sim.scenario import load_scenario, parse_scenario

    if args.workers is not None and args.scheduler:
        raise BadArgument("--workers and --scheduler exclude each other")
    t0 = time.monotonic()
    if args.resume:
        out = Path(args.resume)
        path = out / "campaign.json"
        if not path.is_file():
            raise BadArgument(f"--resume {out}: no campaign.json (not a campaign directory)")
        inputs = json.loads(path.read_text())
        scenario = parse_scenario(inputs["scenario_yaml"], f"{path}: scenario_yaml")
        disp = parse_dispersions(inputs["dispersions_yaml"], inputs["dispersions_path"])
        seed, runs, table_path = inputs["seed"], inputs["runs"], Path(inputs["table"])
    else:
        if args.runs is None:
            raise BadArgument("--runs N is required (or --resume DIR)")
        scenario = load_scenario(args.scenario)
        disp = load_dispersions(args.dispersions)
        seed = _checked_seed(args.seed) or 0
        runs = args.runs
        table_path = Path(args.table) if args.table else default_table_path()
        out = Path(args.out) / f"{scenario.name}-seed{seed}-n{runs}" if args.out_is_parent \
            else Path(args.out)
    table = load_controller_table(table_path)    # a bad table: one line, exit 2, before start
    check_table_stabilises(table, default_context(), scenario.t_start_s, scenario.t_end_s)
    scenario_reference(scenario)                 # likewise the guidance reference it names
    rows = run_campaign(scenario, disp, runs=runs, seed=seed, out=out,
                        table_path=table_path.resolve(), workers=args.workers,
                        scheduler=args.scheduler, resume=bool(args.resume))
    inputs = json.loads((out / "campaign.json").read_text())
    write_results(out, rows)
    summary = summarise(rows, inputs, wall_s=time.monotonic() - t0)
    (out / "summary.json").write_text(json.dumps(summary, indent=1, sort_keys=True) + "\n")
    (out / "summary.md").write_text(summary_markdown(summary))
    plot_campaign(out, read_rows(out), summary)
    print(summary_markdown(summary), end="")
    print(f"vega mc: {out}/ (results.parquet, summary.json, summary.md, histograms.png, "
          f"sensitivity_q_alpha.png)")
    return 0 if summary["passed"] == summary["runs"] else 1


def _rerun(args: argparse.Namespace) -> int:
    """``vega mc margins --runs N [--at T|A:B:C] …`` computes the classical margins of the flown
controller at frozen times for N dispersed plants (the same samples), with the same statistics.

``vega mc rerun DIR --sample I``: the sample through the ROS 2 nodes; its bag's metrics
    against the campaign's row."""
    from pathlib import Path

    from offline_synthesis.campaign import flight_metrics, parse_dispersions, sample_scenario
    from vega_bags import bagio
    from vega_bags.bagcheck import bag_result
    from vega_cli import cli
    from vega_sim.scenario import dump_scenario, parse_scenario

    camp = Path(args.dir)
    path = camp / "campaign.json"
    if not path.is_file():
        raise BadArgument(f"{camp}: no campaign.json (not a campaign directory)")
    inputs = json.loads(path.read_text())
    if not 0 <= args.sample < inputs["runs"]:
        raise BadArgument(f"--sample {args.sample}: the campaign has samples "
                          f"0-{inputs['runs'] - 1}")
    row_path = camp / "samples" / f"{args.sample:06d}.json"
    if not row_path.is_file():
        raise BadArgument(f"--sample {args.sample}: not flown yet in {camp} (--resume it first)")
    row = json.loads(row_path.read_text())
    base = parse_scenario(inputs["scenario_yaml"], f"{path}: scenario_yaml")
    disp = parse_dispersions(inputs["dispersions_yaml"], inputs["dispersions_path"])
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
    got = flight_metrics(bag_result(bagio.read_run_bag(bag_dir)))
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
    from pathlib import Path

    from offline_synthesis.campaign import load_dispersions, parse_dispersions
    from offline_synthesis.campaign_run import (margins_markdown, run_campaign,
                                                summarise_margins, write_results)
    from vega_bringup.planning import _checked_seed
    from vega_cli.commands.margins import parse_at
    from vega_gnc.controller_table import default_table_path, load_controller_table
    from vega_sim.scenario import load_scenario, parse_scenario

    if args.workers is not None and args.scheduler:
        raise BadArgument("--workers and --scheduler exclude each other")
    t0 = time.monotonic()
    if args.resume:
        out = Path(args.resume)
        path = out / "campaign.json"
        if not path.is_file():
            raise BadArgument(f"--resume {out}: no campaign.json (not a campaign directory)")
        inputs = json.loads(path.read_text())
        if inputs.get("kind") != "margins":
            raise BadArgument(f"--resume {out}: a flight campaign (use vega mc run --resume)")
        scenario = parse_scenario(inputs["scenario_yaml"], f"{path}: scenario_yaml")
        disp = parse_dispersions(inputs["dispersions_yaml"], inputs["dispersions_path"])
        seed, runs, table_path = inputs["seed"], inputs["runs"], Path(inputs["table"])
        times = inputs["times_s"]
    else:
        if args.runs is None:
            raise BadArgument("--runs N is required (or --resume DIR)")
        times = parse_at(args.at)
        scenario = load_scenario("nominal")
        disp = load_dispersions(args.dispersions)
        seed = _checked_seed(args.seed) or 0
        runs = args.runs
        table_path = Path(args.table) if args.table else default_table_path()
        out = Path(args.out) if args.out else Path(DEFAULT_OUT) / f"margins-seed{seed}-n{runs}"
    load_controller_table(table_path)            # a bad table: one line, exit 2, before start
    rows = run_campaign(scenario, disp, runs=runs, seed=seed, out=out,
                        table_path=table_path.resolve(), workers=args.workers,
                        scheduler=args.scheduler, resume=bool(args.resume), kind="margins",
                        times_s=times)
    inputs = json.loads((out / "campaign.json").read_text())
    write_results(out, rows)
    summary = summarise_margins(rows, inputs, wall_s=time.monotonic() - t0)
    (out / "summary.json").write_text(json.dumps(summary, indent=1, sort_keys=True) + "\n")
    (out / "summary.md").write_text(margins_markdown(summary))
    print(margins_markdown(summary), end="")
    print(f"vega mc: {out}/ (results.parquet, summary.json, summary.md)")
    return 0 if summary["passed"] == summary["runs"] else 1


def _no_action(args) -> int:
    raise BadArgument("vega mc: choose an action (run, margins, rerun)")


def register(subparsers) -> None:
    """Add the ``mc`` sub-command (action ``run``)."""
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
    run.add_argument("--runs", type=_positive_int, default=None, metavar="N",
                     help="number of dispersed flights")
    run.add_argument("--dispersions", default=None, metavar="FILE",
                     help="dispersion file (default: the shipped "
                          "offline_synthesis/data/dispersions.yaml)")
    run.add_argument("--seed", default=None, metavar="S", help="campaign seed (default 0)")
    run.add_argument("--out", default=None, metavar="DIR",
                     help=f"campaign directory (must not exist or be empty; default: "
                          f"{DEFAULT_OUT}/<scenario>-seed<S>-n<N>)")
    run.add_argument("--table", default=None, metavar="FILE",
                     help="controller table (default: the installed one)")
    run.add_argument("--workers", type=_positive_int, default=None, metavar="K",
                     help="worker processes of the LocalCluster (default: one per core)")
    run.add_argument("--scheduler", default=None, metavar="ADDRESS",
                     help="run on an existing Dask scheduler (e.g. tcp://127.0.0.1:8786)")
    run.add_argument("--resume", default=None, metavar="DIR",
                     help="finish the campaign in DIR (its own inputs; the others are ignored)")
    run.set_defaults(func=_run_entry)
    margins = actions.add_parser(
        "margins", help="margins of the flown controller over dispersed plants",
        description="Classical margins (exact sampled-data loop, vega margins) of the flown "
                    "controller on the nominal schedule at frozen times, for N plants drawn "
                    "from the dispersions (sample i: the campaign seed and i only). Exit 0 "
                    "every plant stable at every time, 1 not, 2 bad input.")
    margins.add_argument("--runs", type=_positive_int, default=None, metavar="N",
                         help="number of dispersed plants")
    margins.add_argument("--at", default="10:90:10", metavar="T|START:STOP:STEP",
                         help="frozen times [s] (default 10:90:10)")
    margins.add_argument("--dispersions", default=None, metavar="FILE",
                         help="dispersion file (default: the shipped one)")
    margins.add_argument("--seed", default=None, metavar="S", help="campaign seed (default 0)")
    margins.add_argument("--out", default=None, metavar="DIR",
                         help=f"campaign directory (default {DEFAULT_OUT}/margins-seed<S>-n<N>)")
    margins.add_argument("--table", default=None, metavar="FILE",
                         help="controller table (default: the installed one)")
    margins.add_argument("--workers", type=_positive_int, default=None, metavar="K",
                         help="worker processes of the LocalCluster (default: one per core)")
    margins.add_argument("--scheduler", default=None, metavar="ADDRESS",
                         help="run on an existing Dask scheduler")
    margins.add_argument("--resume", default=None, metavar="DIR",
                         help="finish the margins campaign in DIR")
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


def _run_entry(args: argparse.Namespace) -> int:
    args.out_is_parent = args.out is None
    if args.out is None:
        args.out = DEFAULT_OUT
    return _run(args)
