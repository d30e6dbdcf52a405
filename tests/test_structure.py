"""The package structure: layering contracts, no import cycle, declared dependencies.

The contracts live in pyproject.toml (``[tool.importlinter]``) and run in ``make lint``, which
``make test`` runs first; here they run too, and are shown to fail on a violating import: the
real sources of a package are copied to a temporary directory, one import is added (inside a
function where that is the point: function-level imports count), and lint-imports is run with
the copy first on the path.

Independently of import-linter, the package-level import graph (every ``import`` statement,
module-level or inside a function) is read from the sources here: it must have no cycle, and
every package must declare what it imports (package.xml ``<exec_depend>`` for the workspace
and ROS packages, the ``dependencies`` of offline/pyproject.toml and cli/pyproject.toml for the
offline side and the command line).
"""

import ast
import importlib.metadata
import json
import os
import re
import shutil
import subprocess
import sys
import tomllib
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
WS = ROOT / "ros2_ws"
PYPROJECT = ROOT / "pyproject.toml"
OFFLINE = ROOT / "offline"
CLI = ROOT / "cli"

IMPORTLINTER = tomllib.loads(PYPROJECT.read_text(encoding="utf-8"))["tool"]["importlinter"]
ROOT_PACKAGES = IMPORTLINTER["root_packages"]
CONTRACTS = {c["id"]: c for c in IMPORTLINTER["contracts"]}

# offline dependencies used without an import statement
RUNTIME_ONLY = {"clarabel"}  # cvxpy's solver, chosen by name (lpv_synthesis.py)


def _source_dir(package: str) -> Path:
    """Directory of the Python package ``package`` in this repository."""
    ament = WS / "src" / package / package
    if ament.is_dir():
        return ament
    return CLI / package if (CLI / package).is_dir() else OFFLINE / package


def _pip_packages(project: Path) -> list[str]:
    """The Python packages of the pip project in ``project`` (offline/ or cli/)."""
    return sorted(p.parent.name for p in project.glob("*/__init__.py"))


def _ament_python_packages() -> list[str]:
    return sorted(p.parent.name for p in (WS / "src").glob("*/setup.py"))


def _modules(directory: Path, package: str) -> set[str]:
    """Module names of the Python files under ``directory`` (package ``package``)."""
    names = set()
    for path in directory.rglob("*.py"):
        if "__pycache__" in path.parts:
            continue
        parts = [package, *path.relative_to(directory).with_suffix("").parts]
        names.add(".".join(parts[:-1] if parts[-1] == "__init__" else parts))
    return names


def _imports(path: Path) -> list[tuple[str, int]]:
    """Absolute imports of a file, (top-level name, line): every import statement, wherever
    it stands, and ``importlib.import_module("literal")``."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
        if isinstance(node, ast.Import):
            found += [(alias.name.split(".")[0], node.lineno) for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            found.append((node.module.split(".")[0], node.lineno))
        elif (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
              and node.func.attr == "import_module" and node.args
              and isinstance(node.args[0], ast.Constant) and isinstance(node.args[0].value, str)):
            found.append((node.args[0].value.split(".")[0], node.lineno))
    return found


def _package_imports(directory: Path, package: str) -> dict[str, list[str]]:
    """Top-level names ``package`` imports (itself excluded) → where (file:line)."""
    result: dict[str, list[str]] = {}
    for path in sorted(directory.rglob("*.py")):
        if "__pycache__" in path.parts:
            continue
        for name, line in _imports(path):
            if name != package:
                where = path.relative_to(ROOT) if path.is_relative_to(ROOT) else path
                result.setdefault(name, []).append(f"{where}:{line}")
    return result


def _package_graph(dirs: dict[str, Path]) -> dict[str, dict[str, list[str]]]:
    """Package → the packages among ``dirs`` it imports → where."""
    graph = {}
    for package, directory in dirs.items():
        imports = _package_imports(directory, package)
        graph[package] = {name: where for name, where in imports.items() if name in dirs}
    return graph


def _cycles(graph: dict[str, dict]) -> list[list[str]]:
    """The strongly connected components of more than one package (Tarjan)."""
    index, low, stack, on_stack, components = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                components.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return components


def _tool(name: str) -> str:
    path = Path(sys.executable).with_name(name)
    found = str(path) if path.exists() else shutil.which(name)
    assert found, f"{name} is not installed (requirements.txt; make setup)"
    return found


def _lint_imports(*contracts: str, first_on_path: Path | None = None):
    """Run lint-imports as ``make lint`` does, optionally with ``first_on_path`` first on
    PYTHONPATH and only the given contracts."""
    env = dict(os.environ)
    if first_on_path is not None:
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(first_on_path),
                                                          env.get("PYTHONPATH")]))
    command = [_tool("lint-imports"), "--no-logo", "--no-cache", str(PYPROJECT)]
    for contract in contracts:
        command += ["--contract", contract]
    return subprocess.run(command, cwd=ROOT, env=env, capture_output=True, text=True,
                          timeout=300, check=False)


# ------------------------------------------------------------------------- the contracts
def test_the_contracts_cover_every_python_package():
    offline = set(_pip_packages(OFFLINE)) | set(_pip_packages(CLI))
    packages = set(_ament_python_packages()) | offline
    assert set(ROOT_PACKAGES) == packages
    layered = {name.strip() for layer in CONTRACTS["layers"]["layers"]
               for name in layer.split("|")}
    assert layered == packages


def test_the_contracts_see_every_module():
    """The import graph the contracts check holds every module of the sources (and not,
    e.g., a namespace package found in the working directory)."""
    script = ("import grimp, json, sys\n"
              "g = grimp.build_graph(*sys.argv[1:], include_external_packages=True, "
              "cache_dir=None)\n"
              "print(json.dumps(sorted(g.modules)))\n")
    result = subprocess.run([sys.executable, "-c", script, *ROOT_PACKAGES], cwd=ROOT,
                            capture_output=True, text=True, timeout=300, check=False)
    assert result.returncode == 0, result.stderr
    in_graph = {m for m in json.loads(result.stdout) if m.split(".")[0] in ROOT_PACKAGES}
    in_sources = set().union(*(_modules(_source_dir(p), p) for p in ROOT_PACKAGES))
    assert in_graph == in_sources


@pytest.mark.slow
def test_the_contracts_hold():
    result = _lint_imports()
    assert result.returncode == 0, f"lint-imports failed:\n{result.stdout}{result.stderr}"
    for contract in CONTRACTS.values():
        assert f"{contract['name']} KEPT" in result.stdout


# package, file, code appended to the file's copy, contract that must break, the import shown
VIOLATIONS = [
    pytest.param("vega_gnc", "controller_runtime.py",
                 "\n\ndef _injected():\n    import vega_model.actuator\n",
                 "flight-side", "vega_gnc.controller_runtime -> vega_model.actuator",
                 id="flight-side-imports-the-truth-side"),
    pytest.param("vega_reference", "trajectory.py", "\nimport rclpy\n",
                 "offline", "vega_reference.trajectory -> rclpy",
                 id="offline-imports-rclpy"),
    pytest.param("vega_loops", "export.py",
                 "\n\ndef _injected():\n    from vega_cli import cli\n",
                 "offline", "vega_loops.export -> vega_cli.cli",
                 id="offline-imports-the-cli"),
    pytest.param("vega_analysis", "robust.py",
                 "\n\ndef _injected():\n    from vega_design import structured\n",
                 "layers", "vega_analysis.robust -> vega_design.structured",
                 id="analysis-imports-the-design-upward"),
    pytest.param("vega_loops", "margins.py",
                 "\n\ndef _injected():\n    from vega_campaign import campaign\n",
                 "layers", "vega_loops.margins -> vega_campaign.campaign",
                 id="loops-import-the-campaign-upward"),
    pytest.param("vega_campaign", "campaign.py",
                 "\n\ndef _injected():\n    from vega_analysis import robust\n",
                 "layers", "vega_campaign.campaign -> vega_analysis.robust",
                 id="campaign-imports-the-analysis-upward"),
    pytest.param("vega_lpv", "pipeline.py",
                 "\n\ndef _injected():\n    from vega_design import structured\n",
                 "offline-independence", "vega_lpv.pipeline -> vega_design.structured",
                 id="lpv-imports-the-design"),
    pytest.param("vega_sim", "closed_loop.py",
                 "\n\ndef _injected():\n    from vega_loops import margins\n",
                 "layers", "vega_sim.closed_loop -> vega_loops.margins",
                 id="workspace-imports-the-offline-side-upward"),
    pytest.param("vega_model", "wind.py",
                 "\n\ndef _injected():\n    from vega_sim import scenario\n",
                 "layers", "vega_model.wind -> vega_sim.scenario",
                 id="model-imports-upward"),
    pytest.param("vega_gnc", "controller_step.py",
                 "\n\ndef _injected():\n    from vega_bus import shell\n",
                 "plain-python", "vega_gnc.controller_step -> vega_bus.shell",
                 id="controller-step-reaches-rclpy"),
]


def _copy_with(tmp_path: Path, package: str, file: str, code: str) -> Path:
    """Copy of ``package``'s sources under ``tmp_path`` with ``code`` appended to ``file``."""
    copy = tmp_path / package
    shutil.copytree(_source_dir(package), copy, ignore=shutil.ignore_patterns("__pycache__"))
    with open(copy / file, "a", encoding="utf-8") as handle:
        handle.write(code)
    return copy


@pytest.mark.slow
@pytest.mark.parametrize("package, file, code, contract, shown", VIOLATIONS)
def test_a_violating_import_breaks_its_contract(tmp_path, package, file, code, contract,
                                                shown):
    _copy_with(tmp_path, package, file, code)
    result = _lint_imports(contract, first_on_path=tmp_path)
    output = result.stdout + result.stderr
    assert result.returncode == 1, output
    assert f"{CONTRACTS[contract]['name']} BROKEN" in output
    assert shown in output


@pytest.mark.slow
def test_the_copies_are_what_the_contracts_read(tmp_path):
    """Control of the test above: an unchanged copy breaks nothing that the original keeps."""
    _copy_with(tmp_path, "vega_gnc", "controller_runtime.py", "")
    result = _lint_imports("flight-side", "layers", first_on_path=tmp_path)
    assert result.returncode == 0, result.stdout + result.stderr


# ------------------------------------------------------------------ no cycle, declarations
@pytest.mark.slow
def test_no_import_cycle_between_packages():
    graph = _package_graph({p: _source_dir(p) for p in ROOT_PACKAGES})
    cycles = _cycles(graph)
    detail = {" <-> ".join(c): {a: {b: graph[a][b] for b in c if b in graph[a]} for a in c}
              for c in cycles}
    assert not cycles, f"import cycles between packages: {detail}"


@pytest.mark.slow
def test_the_cycle_check_finds_an_injected_cycle(tmp_path):
    copy = _copy_with(tmp_path, "vega_model", "wind.py",
                      "\n\ndef _injected():\n    from vega_sim import scenario\n")
    dirs = {p: _source_dir(p) for p in ROOT_PACKAGES} | {"vega_model": copy}
    assert ["vega_model", "vega_sim"] in _cycles(_package_graph(dirs))


def _ros_packages() -> set[str]:
    from ament_index_python.packages import get_packages_with_prefixes

    known = set(get_packages_with_prefixes())
    assert {"rclpy", "std_msgs", "vega_msgs"} <= known, "ament index incomplete (environment?)"
    return known


@pytest.mark.parametrize("package", _ament_python_packages())
def test_package_xml_declares_what_the_package_imports(package):
    """Every workspace or ROS package (ament index) the code imports is an exec_depend."""
    xml = ET.parse(WS / "src" / package / "package.xml").getroot()
    declared = {e.text.strip() for e in xml if e.tag in ("depend", "exec_depend")}
    own = {p.name for p in (WS / "src").iterdir() if (p / "package.xml").exists()}
    wanted = own | set(ROOT_PACKAGES) | _ros_packages()
    imports = _package_imports(_source_dir(package), package)
    missing = {name: where for name, where in imports.items()
               if name in wanted and name not in declared}
    assert not missing, f"{package}/package.xml lacks <exec_depend> for {missing}"


def _distribution(name: str) -> str:
    """Canonical distribution name (PEP 503)."""
    return re.sub(r"[-_.]+", "-", name).lower()


@pytest.mark.slow
@pytest.mark.parametrize("project", [OFFLINE, CLI], ids=["offline", "cli"])
def test_pip_projects_declare_what_they_import(project):
    """offline/ and cli/: every third-party and workspace package their code imports is a
    ``dependencies`` entry (the offline packages as the one distribution vega_offline), and
    every entry is imported."""
    meta = tomllib.loads((project / "pyproject.toml").read_text(encoding="utf-8"))
    declared = {_distribution(re.split(r"[\s;<>=!~\[(]", d, maxsplit=1)[0])
                for d in meta["project"]["dependencies"]}
    own = set(_pip_packages(project))
    offline = set(_pip_packages(OFFLINE))
    imports: dict[str, list[str]] = {}
    for package in own:
        for name, where in _package_imports(_source_dir(package), package).items():
            if name not in own:
                imports.setdefault("vega_offline" if name in offline else name, []).extend(where)
    third_party = {n: w for n, w in imports.items()
                   if n not in sys.stdlib_module_names and n != "__future__"}
    dists = importlib.metadata.packages_distributions()
    needed = {_distribution(dists.get(n, [n])[0]): w for n, w in third_party.items()}
    missing = {n: w for n, w in needed.items() if n not in declared}
    assert not missing, f"{project.name}/pyproject.toml lacks dependencies {missing}"
    unused = declared - set(needed) - {_distribution(n) for n in RUNTIME_ONLY}
    assert not unused, f"declared but never imported: {sorted(unused)}"
