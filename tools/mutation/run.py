"""Mutation testing of the core modules with mutmut (``make mutation [MODULE=...]``).

Each module of ``tools/mutation/targets.toml`` is mutated in a scratch copy of the packages and
tests as committed in HEAD (``build/mutation/<module>/``; the checkout itself is never edited, so
other work and test runs in the same tree see the real code, and uncommitted work in progress
does not enter the figures; ``--worktree`` takes the checkout as it is), mutmut runs the
module's covering tests against every mutant, one process at a time, and the outcome is
written to
``bench/results/mutation/<module>.json``; ``bench/results/mutation.md`` is the table of all
modules run so far. Survivors listed in ``tools/mutation/equivalents.toml`` (mutant name and
the diff line it must still have, plus a one-line reason) count as equivalent.

Excluded by configuration (docs/TESTING.md): the text of exceptions raised, log calls and
prints (``DO_NOT_MUTATE_PATTERNS``: the whole statement on such a line is not mutated) and
docstrings (mutmut never mutates triple-quoted strings).

Usage: ``python tools/mutation/run.py [--module NAME ...] [--max-children 1] [--worktree]``;
run it through ``vega-env`` (the Makefile does) so the ROS packages' dependencies import.
"""

from __future__ import annotations

import argparse
import ast
import datetime as _dt
import difflib
import json
import os
import shutil
import subprocess
import sys
import threading
import time
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
HERE = Path(__file__).resolve().parent
TARGETS = HERE / "targets.toml"
EQUIVALENTS = HERE / "equivalents.toml"
WORK = ROOT / "build" / "mutation"
RESULTS = ROOT / "bench" / "results" / "mutation"
TABLE = ROOT / "bench" / "results" / "mutation.md"
# Every run's summary, one JSON line each (the table shows each module's first and last run:
# the "before" and "after" of its *_mutants.py tests).
HISTORY = RESULTS / "history.jsonl"

# Lines whose statement is not mutated: message text of raised exceptions, log calls, prints.
DO_NOT_MUTATE_PATTERNS = [
    r"^\s*raise\b",
    r"\.(debug|info|warning|warn|error|fatal|critical|exception)\(\s*f?['\"]",
    r"get_logger\(\)",
    r"^\s*print\(",
]

# Repository directories the tests and modules read by path from the repository root (docs,
# config tables, messages); linked into the scratch copy and its mutants tree so that
# ``Path(__file__).parents[...]`` still finds them.
ROOT_LINKS = ["ros2_ws", "docs", "bench", "bags", "tools"]
# What is taken from the commit (the rest, e.g. the built ROS install, from the checkout).
TREE_PATHS = ["ros2_ws/src", "offline", "cli", "tests", "docs", "tools"]

# Seconds added to mutmut's per-mutant limit (15 × the covering tests' own durations): module-
# and session-scoped fixtures (an SDP solve, a simulated flight) run again in every mutant's
# process and are not part of the measured test durations; per module: ``timeout_s``.
TIMEOUT_S = 20.0
# Wall-clock limit of one mutant process (all of a module's covering tests take < 15 s here).
MUTANT_WALL_S = 60.0

STATUS = {1: "killed", 3: "killed", 0: "survived", 5: "no tests", 33: "no tests", 34: "skipped",
          36: "timeout", 24: "timeout", -24: "timeout", 152: "timeout", 255: "timeout",
          -9: "timeout",    # SIGKILL: the wall-clock limit of _watchdog
          None: "not checked"}


def _tree(commit):
    """The files the runs read: the committed tree of ``commit`` (extracted once into
    build/mutation/_tree-<commit>/, so that uncommitted edits in the checkout, e.g. other work
    in progress, do not enter the figures), or the working tree itself for ``commit=None``."""
    if commit is None:
        return ROOT
    tree = WORK / f"_tree-{commit}"
    if not (tree / ".complete").is_file():
        if tree.exists():
            shutil.rmtree(tree)
        tree.mkdir(parents=True)
        archive = subprocess.run(["git", "archive", "--format=tar", commit, *TREE_PATHS],
                                 cwd=ROOT, capture_output=True, check=True).stdout
        subprocess.run(["tar", "-x", "-C", str(tree)], input=archive, check=True)
        (tree / ".complete").write_text(commit + "\n")
    return tree


def _packages(tree):
    """Every Python package of the project: (import name, source directory)."""
    found = [(p.name, p / p.name) for p in sorted((tree / "ros2_ws" / "src").iterdir())
             if (p / p.name / "__init__.py").is_file()]
    found += [(p.name, p) for base in ("offline", "cli") for p in sorted((tree / base).iterdir())
              if (p / "__init__.py").is_file()]
    return found


def _toml_list(items):
    return "[" + ", ".join(json.dumps(str(i)) for i in items) + "]"


def _stage(name, target, tree):
    """Build build/mutation/<name>/: package copies, tests, pyproject with the mutmut config."""
    stage = WORK / name
    if stage.exists():
        shutil.rmtree(stage)
    stage.mkdir(parents=True)
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc")
    names = []
    for pkg, src in _packages(tree):
        shutil.copytree(src, stage / pkg, ignore=ignore, symlinks=True)
        names.append(pkg)
    shutil.copytree(tree / "tests", stage / "tests", ignore=ignore)
    source = Path(target["source"])
    pkg = source.parent.name
    rel = f"{pkg}/{source.name}"
    tests = [str(t) for t in target["tests"] if (tree / t).is_file()]
    missing = [str(t) for t in target["tests"] if not (tree / t).is_file()]
    (stage / "pyproject.toml").write_text(
        "[tool.mutmut]\n"
        f"source_paths = {_toml_list([pkg])}\n"
        f"only_mutate = {_toml_list([rel])}\n"
        f"also_copy = {_toml_list(n for n in names if n != pkg)}\n"
        f"pytest_add_cli_args_test_selection = {_toml_list(tests)}\n"
        'pytest_add_cli_args = ["-p", "no:cacheprovider", "-p", "no:randomly", "-q"]\n'
        f"do_not_mutate_patterns = {_toml_list(DO_NOT_MUTATE_PATTERNS)}\n"
        "use_git_change_detection = false\n"
        # a fork server: wall-clock timeouts (the fork mode has CPU-time limits only, and a
        # mutant process blocked on a lock inherited through fork() then waits forever)
        "process_isolation = \"forkserver\"\n"
        f"timeout_constant = {float(target.get('timeout_s', TIMEOUT_S))}\n"
        "\n[tool.pytest.ini_options]\n"
        'testpaths = ["tests"]\npythonpath = ["tests", "tests/sil"]\n')
    mutants = stage / "mutants"
    mutants.mkdir()
    for link in ROOT_LINKS:
        source = tree / link if (tree / link).exists() else ROOT / link
        if source.exists():
            for where in (stage, mutants):
                (where / link).symlink_to(source)
    return stage, rel, tests, missing


def _equivalents():
    if not EQUIVALENTS.is_file():
        return {}
    return tomllib.loads(EQUIVALENTS.read_text())


def _watchdog(proc, stop, limit_s):
    """SIGKILL a mutant process (a grandchild of mutmut: mutmut → fork server → mutant) that
    has run longer than ``limit_s`` wall-clock seconds; mutmut then records it as killed by
    signal 9, counted as a timeout. (mutmut's own limits are on CPU time, and its wall-clock
    timer did not end mutants spinning in a loop here.)"""
    import psutil

    try:
        root = psutil.Process(proc.pid)
    except psutil.NoSuchProcess:
        return
    while not stop.wait(2.0):
        try:
            servers = root.children()
            mutants = [c for srv in servers for c in srv.children()]
        except psutil.NoSuchProcess:
            return
        for m in mutants:
            try:
                if time.time() - m.create_time() > limit_s:
                    m.kill()
            except psutil.NoSuchProcess:
                pass


def _mutmut(stage, *args, log=None):
    exe = Path(sys.executable).parent / "mutmut"
    if log is None:
        return subprocess.run([str(exe), *args], cwd=stage, text=True, check=False,
                              capture_output=True)
    with open(log, "w") as out:
        proc = subprocess.Popen([str(exe), *args], cwd=stage, text=True, stdout=out,
                                stderr=subprocess.STDOUT)
        stop = threading.Event()
        guard = threading.Thread(target=_watchdog, args=(proc, stop, MUTANT_WALL_S),
                                 daemon=True)
        guard.start()
        proc.wait()
        stop.set()
        guard.join()
        return proc


def _function_sources(path):
    """Source of every mutmut-generated function of a mutated file, by function name."""
    text = path.read_text()
    lines = text.splitlines()
    out = {}
    for node in ast.walk(ast.parse(text)):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and "__mutmut_" in node.name:
            out[node.name] = lines[node.lineno - 1:node.end_lineno]
    return out


def _diff(sources, key):
    """The changed lines (+/-) of mutant ``key`` against the original function."""
    func = key.rsplit(".", 1)[-1]
    orig = sources.get(func.rsplit("__mutmut_", 1)[0] + "__mutmut_orig")
    mutant = sources.get(func)
    if orig is None or mutant is None:
        return []
    a = [ln.replace("__mutmut_orig", "") for ln in orig[1:]]
    b = [ln.replace(func.rsplit(".", 1)[-1], "") for ln in mutant[1:]]
    return [ln for ln in difflib.unified_diff(a, b, lineterm="", n=0)
            if ln.startswith(("+", "-")) and not ln.startswith(("+++", "---"))]


def run_module(name, target, max_children, commit, tree, collect=False, only=(), rerun=None):
    """Mutate one module, return its result record (also written to bench/results).

    ``collect``: do not run; read what an earlier (possibly interrupted) run of the module in
    build/mutation/<module>/ has recorded (mutants not yet run count as "not checked").
    ``only``: mutant-name globs (mutmut's own selection, e.g. ``vega_bags.bagio.x_git*``): run
    just those; the others count as "not checked" (a partial run, marked as such).
    ``rerun``: the record of an earlier full run of the same source (:func:`_rerun_base`): only
    its survivors and "no tests" mutants are run again, every other mutant keeps its earlier
    status (killed stays killed: tests were only added), and the counts are those of the whole
    module.
    """
    if collect:
        stage = WORK / name
        link = stage / "ros2_ws"
        if link.is_symlink() and link.resolve().parent.name.startswith("_tree-"):
            tree = link.resolve().parent
            commit = tree.name.removeprefix("_tree-")
        else:
            tree, commit = ROOT, commit + "+worktree"
        source = Path(target["source"])
        rel = f"{source.parent.name}/{source.name}"
        tests = [str(t) for t in target["tests"] if (tree / t).is_file()]
        missing = [str(t) for t in target["tests"] if not (tree / t).is_file()]
        log = stage / "mutmut.log"
        elapsed = log.stat().st_mtime - (stage / "pyproject.toml").stat().st_mtime
        returncode = 0
    else:
        stage, rel, tests, missing = _stage(name, target, tree)
        started = time.monotonic()
        log = stage / "mutmut.log"
        print(f"mutation: {name}: mutmut run (log {log.relative_to(ROOT)})", flush=True)
        returncode = _mutmut(stage, "run", "--max-children", str(max_children), *only,
                             log=log).returncode
        elapsed = time.monotonic() - started
    meta = stage / "mutants" / (rel + ".meta")
    if returncode != 0 or not meta.is_file():
        print(f"mutation: mutmut run failed for {name} (exit {returncode}); log: {log}",
              file=sys.stderr)
        return None
    codes = json.loads(meta.read_text())["exit_code_by_key"]
    sources = _function_sources(stage / "mutants" / rel)
    equivalents = _equivalents().get(name, {})
    mutants = []
    for key, code in sorted(codes.items(), key=lambda kv: (kv[0].rsplit("_", 1)[0],
                                                           int(kv[0].rsplit("_", 1)[1]))):
        status = STATUS.get(code, "suspicious")
        record = {"name": key, "status": status}
        if status != "killed":
            record["diff"] = _diff(sources, key)
            eq = equivalents.get(key)
            if status == "survived" and eq and eq["line"] in "\n".join(record["diff"]):
                record["status"] = "equivalent"
                record["reason"] = eq["reason"]
        mutants.append(record)
    if rerun is not None:
        mutants = _merge_rerun(rerun, mutants)
    counts = {s: sum(m["status"] == s for m in mutants)
              for s in ("killed", "survived", "equivalent", "timeout", "no tests", "suspicious",
                        "not checked")}
    killed_percent, strict_percent = percentages(len(mutants), counts)
    result = {
        "module": name, "source": target["source"], "tests": tests, "missing_tests": missing,
        "commit": commit + (f" (survivors of the full run at {rerun['commit']} re-run)"
                            if rerun is not None else
                            " (partial: " + ", ".join(only) + ")" if only else ""),
        "date": _dt.datetime.now(_dt.UTC).strftime("%Y-%m-%d %H:%M UTC"),
        "seconds": round(elapsed, 1), "max_children": max_children, "total": len(mutants),
        "counts": counts,
        "killed_percent": killed_percent, "strict_percent": strict_percent,
        "not_killed": [m for m in mutants if m["status"] not in ("killed", "not checked")],
    }
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / f"{name}.json").write_text(json.dumps(result, indent=1) + "\n")
    if not collect:
        summary = {k: result[k] for k in ("module", "commit", "date", "seconds", "total",
                                          "counts", "killed_percent")}
        with open(HISTORY, "a") as out:
            out.write(json.dumps(summary) + "\n")
    return result


def _rerun_base(name, target, commit):
    """The last recorded full run of ``name`` whose source file is the same as at ``commit``
    (so that every mutant name means the same edit), with the names of its survivors.

    Raises SystemExit (one line) if there is none.
    """
    path = RESULTS / f"{name}.json"
    if not path.is_file():
        raise SystemExit(f"mutation: {name}: no earlier run to re-run the survivors of")
    base = json.loads(path.read_text())
    old = base["commit"].split()[0]
    if "(partial" in base["commit"] or base["counts"].get("not checked", 0):
        raise SystemExit(f"mutation: {name}: the last run ({base['commit']}) is not a full "
                         f"run; --rerun-survivors needs one")
    same = subprocess.run(["git", "diff", "--quiet", old, commit.removesuffix("+worktree"),
                           "--", target["source"]], cwd=ROOT, check=False).returncode == 0
    if not same:
        raise SystemExit(f"mutation: {name}: {target['source']} changed since {old}: run the "
                         f"whole module")
    # "no tests" too: a test added since may now run the function
    base["survivors"] = [m["name"] for m in base["not_killed"]
                         if m["status"] in ("survived", "no tests")]
    base["commit"] = old
    return base


def _merge_rerun(base, rerun_mutants):
    """Every mutant of ``base``'s full run, its survivors with their re-run statuses."""
    again = {m["name"]: m for m in rerun_mutants if m["status"] != "not checked"}
    out = [again.get(m["name"], m) if m["status"] in ("survived", "no tests") else m
           for m in base["not_killed"]]
    # the full run's killed mutants are not listed by name in its record: counted as such
    out += [{"name": f"(killed in the full run, #{i})", "status": "killed"}
            for i in range(base["counts"]["killed"])]
    if len(out) != base["total"]:
        raise SystemExit(f"mutation: {base['module']}: the re-run does not add up "
                         f"({len(out)} of {base['total']} mutants)")
    return out


def percentages(total: int, counts: dict) -> tuple[float | None, float | None]:
    """(killed %, strict %) of one module's run, one decimal; None when nothing was judged.

    killed % = (killed + timeout) / (all − equivalent − no tests − not checked): of the
    mutants a covering test executed. strict % = (killed + timeout) / (all − equivalent − not
    checked): a "no tests" mutant (its function run by no covering test) counts as not killed,
    the reading of the target "≥ 90 % of the non-equivalent mutants killed" (docs/TESTING.md,
    Results)."""
    done = counts["killed"] + counts["timeout"]
    base = total - counts["equivalent"] - counts.get("not checked", 0)
    judged = base - counts["no tests"]
    return (round(100.0 * done / judged, 1) if judged else None,
            round(100.0 * done / base, 1) if base else None)


def write_table(order):
    """bench/results/mutation.md from every module's JSON (modules in targets order)."""
    rows = []
    for name in order:
        path = RESULTS / f"{name}.json"
        if not path.is_file():
            continue
        r = json.loads(path.read_text())
        c = r["counts"]
        rows.append(f"| {name} | {r['total']} | {c['killed']} | {c['survived']} | "
                    f"{c['equivalent']} | {c['timeout']} | {c['no tests'] + c['suspicious']} | "
                    f"{c.get('not checked', 0)} | "
                    f"{r['killed_percent']} | {percentages(r['total'], c)[1]} | "
                    f"{r['seconds']:.0f} | {r['commit']} | {r['date']} |")
    history = _history_rows(order)
    TABLE.parent.mkdir(parents=True, exist_ok=True)
    TABLE.write_text(
        "# Mutation testing: per-module table (written by `make mutation`)\n\n"
        "killed % = (killed + timeout) / (all - equivalent - no tests - not checked); strict % "
        "= (killed + timeout) / (all - equivalent - not checked), a 'no tests' mutant counted "
        "as not killed (issue 15's measure); one worker process. other = no tests (no covering "
        "test runs the function) + suspicious; not checked = not reached by an interrupted "
        "run.\n"
        "Survivor diffs: bench/results/mutation/<module>.json. How to run: docs/TESTING.md.\n\n"
        "| module | mutants | killed | survived | equivalent | timeout | other | not checked "
        "| killed % | strict % | run time s | commit | date |\n"
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|\n"
        + "\n".join(rows) + "\n" + history)


def _history_rows(order):
    """Markdown: each module's first and last recorded run (before / after its new tests)."""
    if not HISTORY.is_file():
        return ""
    runs = {}
    for line in HISTORY.read_text().splitlines():
        if line.strip():
            r = json.loads(line)
            runs.setdefault(r["module"], []).append(r)
    rows = []
    for name in order:
        for label, r in (("before", runs.get(name, [None])[0]),
                         ("after", runs.get(name, [None])[-1])):
            if r is None or (label == "after" and len(runs[name]) == 1):
                continue
            c = r["counts"]
            rows.append(f"| {name} | {label} | {r['total']} | {c['killed']} | {c['survived']} "
                        f"| {c['equivalent']} | {c['timeout']} | "
                        f"{c['no tests'] + c['suspicious']} | {r['killed_percent']} | "
                        f"{r['seconds']:.0f} | {r['commit']} | {r['date']} |")
    if not rows:
        return ""
    return ("\n## Before and after (first and last run recorded in "
            "bench/results/mutation/history.jsonl)\n\n"
            "| module | run | mutants | killed | survived | equivalent | timeout | other "
            "| killed % | run time s | commit | date |\n"
            "|---|---|---|---|---|---|---|---|---|---|---|---|\n" + "\n".join(rows) + "\n")


def main(argv=None):
    """Run the selected modules, print a summary line each, rewrite the table."""
    targets = tomllib.loads(TARGETS.read_text())["module"]
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--module", action="append", choices=sorted(targets),
                        help="module of tools/mutation/targets.toml (repeatable; default: all)")
    parser.add_argument("--max-children", type=int, default=1,
                        help="parallel mutant processes (default 1)")
    parser.add_argument("--worktree", action="store_true",
                        help="mutate the checkout as it is, uncommitted edits included (default: "
                             "the committed HEAD, so that the table names exactly what it ran)")
    parser.add_argument("--only", action="append", default=[], metavar="GLOB",
                        help="run only the mutants whose names match (mutmut's glob; "
                             "repeatable): a partial run, the rest is 'not checked'")
    parser.add_argument("--rerun-survivors", action="store_true",
                        help="run again only the survivors and 'no tests' mutants of the "
                             "module's last full run (same source file), keep every other "
                             "mutant's status; the table shows the whole module")
    parser.add_argument("--collect", action="store_true",
                        help="do not run: tabulate what the last (possibly interrupted) run of "
                             "each module recorded in build/mutation/<module>/")
    args = parser.parse_args(argv)
    if args.max_children < 1:
        print("mutation: --max-children must be >= 1", file=sys.stderr)
        return 2
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, text=True,
                            capture_output=True, check=False).stdout.strip() or "unknown"
    tree = ROOT if args.collect else _tree(None if args.worktree else commit)
    if args.worktree:
        commit += "+worktree"
    failed = []
    for name in args.module or list(targets):
        rerun = _rerun_base(name, targets[name], commit) if args.rerun_survivors else None
        only = tuple(rerun["survivors"]) if rerun is not None else tuple(args.only)
        if rerun is not None and not only:
            print(f"mutation: {name}: no survivors to re-run")
            continue
        result = run_module(name, targets[name], args.max_children, commit, tree,
                            collect=args.collect, only=only, rerun=rerun)
        if result is None:
            failed.append(name)
            continue
        c = result["counts"]
        print(f"mutation: {name}: {result['total']} mutants, {c['killed']} killed, "
              f"{c['survived']} survived, {c['equivalent']} equivalent, {c['timeout']} timeout, "
              f"{c['no tests']} no tests ({result['killed_percent']} % killed, strict "
              f"{result['strict_percent']} %) in {result['seconds']:.0f} s")
        for m in result["not_killed"]:
            if m["status"] == "survived":
                print(f"  survived {m['name']}: {' | '.join(m['diff'])}")
    write_table(list(targets))
    print(f"mutation: table {TABLE.relative_to(ROOT)}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
