"""The document loader's size limit (vega_core.documents.read_text): a file over the limit is
refused with one line naming it and its size, without being read whole — even a device that
reports size 0 and never ends (``/dev/zero``)."""

import os
import subprocess
import sys

import pytest

from vega_core.documents import MAX_DOCUMENT_BYTES, load_yaml, read_text
from vega_core.errors import BadFile
from vega_model.flight_conditions import default_flight_conditions_path
from vega_model.vehicle_data import default_vehicle_path


def test_the_limit_is_1_mib_and_the_shipped_documents_are_far_below_it():
    assert MAX_DOCUMENT_BYTES == 1 << 20
    assert default_vehicle_path().stat().st_size < MAX_DOCUMENT_BYTES // 16
    assert default_flight_conditions_path().stat().st_size < MAX_DOCUMENT_BYTES // 3


def test_a_file_over_the_limit_is_refused_with_its_name_and_size(tmp_path):
    big = tmp_path / "big.yaml"
    big.write_bytes(b"# " + b"x" * MAX_DOCUMENT_BYTES + b"\n")
    size = big.stat().st_size
    with pytest.raises(BadFile) as info:
        load_yaml(big, "scenario")
    assert str(info.value) == (f"{big}: scenario file is {size} bytes, over the 1 MiB "
                               f"(1048576 bytes) limit")


def test_a_file_at_the_limit_is_read(tmp_path):
    edge = tmp_path / "edge.txt"
    edge.write_bytes(b"a" * (MAX_DOCUMENT_BYTES - 1) + b"\n")
    assert len(read_text(edge, "text")) == MAX_DOCUMENT_BYTES


def test_own_limit(tmp_path):
    path = tmp_path / "t.txt"
    path.write_text("0123456789")
    assert read_text(path, "t", max_bytes=10) == "0123456789"
    path.write_text("0123456789a")
    with pytest.raises(BadFile, match=r"t\.txt: t file is 11 bytes, over the 10 bytes limit$"):
        read_text(path, "t", max_bytes=10)


_BOUNDED = """
import resource, sys
resource.setrlimit(resource.RLIMIT_AS, (1 << 30, 1 << 30))  # 1 GiB: reading all of it fails
from vega_core.documents import read_text
try:
    read_text("/dev/zero", "scenario")
except Exception as exc:
    print(type(exc).__name__ + ": " + str(exc))
"""


@pytest.mark.skipif(not os.path.exists("/dev/zero"), reason="no /dev/zero")
def test_dev_zero_is_refused_at_once_without_eating_memory():
    """``/dev/zero`` has st_size 0 and never ends: at most limit + 1 bytes are read (run in a
    child process limited to 1 GiB of address space and 60 s, so a loader that reads it
    whole fails with MemoryError instead of taking the test machine down)."""
    done = subprocess.run([sys.executable, "-c", _BOUNDED], capture_output=True, text=True,
                          timeout=60)
    assert done.stdout == ("BadFile: /dev/zero: scenario file is over the 1 MiB (1048576 "
                           "bytes) limit (more than 1048576 bytes read)\n"), done


def test_newlines_are_normalised_as_in_text_mode(tmp_path):
    path = tmp_path / "crlf.yaml"
    path.write_bytes(b"a: 1\r\nb: 2\rc: 3\n")
    assert read_text(path, "x") == "a: 1\nb: 2\nc: 3\n"


_FIFO = """
import sys
from vega_core.documents import read_text
from vega_gnc.config_files import read_npz
from vega_gnc.controller_table import ControllerTableError
for call in (lambda: read_text(sys.argv[1], "scenario"),
             lambda: read_npz(sys.argv[1], ControllerTableError, "controller table")):
    try:
        call()
    except Exception as exc:
        print(type(exc).__name__ + ": " + str(exc))
"""


def test_a_fifo_is_refused_before_it_is_opened(tmp_path):
    """Opening a FIFO blocks until a writer comes (`--scenario FIFO`, `--table FIFO` and a
    node's `--params-file FIFO` would hang for ever; docs/ADVERSARIAL.md): refused in one
    line, as a scenario and as a controller table (in a child process with a time limit, so
    that a regression hangs the child, not the suite)."""
    fifo = tmp_path / "pipe.yaml"
    os.mkfifo(fifo)
    done = subprocess.run([sys.executable, "-c", _FIFO, str(fifo)], capture_output=True,
                          text=True, timeout=60)
    assert done.stdout.splitlines() == [
        f"BadFile: {fifo}: cannot read scenario (a FIFO or socket, not a regular file)",
        f"ControllerTableError: {fifo}: cannot read controller table (a FIFO or socket, not a "
        "regular file)"], done


@pytest.mark.slow
def test_a_fifo_scenario_is_one_line_and_exit_2(tmp_path):
    """The same through the CLI: `vega sil run --scenario FIFO`, exit 2, one line."""
    fifo = tmp_path / "pipe.yaml"
    os.mkfifo(fifo)
    done = subprocess.run([sys.executable, "-m", "vega_cli.cli", "sil", "run", "--scenario",
                           str(fifo), "--out", str(tmp_path / "run")], capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 2, done
    assert done.stderr.count("\n") == 1 and "a FIFO or socket" in done.stderr, done.stderr


@pytest.mark.slow
@pytest.mark.parametrize("text", ["[" * 100_000, "a:\n" + "- " * 50_000 + "x\n",
                                  "{a: " * 100_000])
def test_yaml_nested_too_deeply_is_one_line(text):
    """A small file nested 100 000 levels deep can make a YAML parser exhaust the stack
    (RecursionError, a traceback, exit 1; docs/ADVERSARIAL.md): one line instead."""
    from vega_core.documents import parse_yaml

    with pytest.raises(BadFile) as err:
        parse_yaml(text, "deep.yaml")
    assert str(err.value) == "deep.yaml: YAML nested too deeply"


def _project_yaml_files():
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    return sorted(p for p in (root / "ros2_ws" / "src").rglob("*.yaml")
                  if "__pycache__" not in p.parts)


def test_libyaml_and_the_python_loader_build_the_same_trees_for_the_project_files():
    """Every YAML file of the project, as parse_yaml reads it (libyaml when short), against
    PyYAML's pure-Python SafeLoader; the short ones do go through libyaml."""
    import yaml

    from vega_core import documents

    files = _project_yaml_files()
    assert len(files) >= 8
    short = 0
    for path in files:
        text = path.read_text()
        if len(text) <= documents.C_PARSER_MAX_CHARS:
            short += 1
            assert documents._loader(yaml, text) is yaml.CSafeLoader
        want = yaml.load(text, Loader=yaml.SafeLoader)
        if isinstance(want, dict):
            assert documents.parse_yaml(text, str(path)) == want, path
    assert short >= 8


@pytest.mark.slow
@pytest.mark.parametrize("unit", ["[", "- ", "{a: "])
def test_the_deepest_text_libyaml_gets_parses_in_a_thread_too(unit):
    """A text of C_PARSER_MAX_CHARS characters nested as deep as it can (one level per
    character or two): libyaml returns or raises a YAML error, in a thread (a smaller stack
    than the main thread's on some systems) — it does not crash the process."""
    import threading

    import yaml

    from vega_core import documents

    n = documents.C_PARSER_MAX_CHARS
    text = (unit * n)[:n]
    assert documents._loader(yaml, text) is yaml.CSafeLoader
    assert documents._loader(yaml, text + " ") is yaml.SafeLoader
    outcome = []

    def parse():
        try:
            documents.parse_yaml(text, "deep.yaml")
            outcome.append("parsed")
        except BadFile as exc:
            outcome.append(str(exc))

    thread = threading.Thread(target=parse)
    thread.start()
    thread.join()
    assert len(outcome) == 1 and outcome[0] != "parsed"   # unclosed, or too deep: refused
