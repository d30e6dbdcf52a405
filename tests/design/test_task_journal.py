"""The design's task journal (vega_design.task_journal): an interrupted `vega design`
resumes with the finished tasks' results and gives the uninterrupted run's table.

Keys are checked on hand cases (identity does not matter, one bit of a float does), the file on
a kill's cut line, a damaged line and another code's journal, `structured.pool_map` on the
spawned-process path with a result only the journal could have given, and `design_flight` on a
small real design interrupted after its first task and resumed, against the same design run
through without a journal.
"""

import json
import math

import numpy as np
import pytest
from vega_core.errors import BadFile

from vega_design import structured as S
from vega_design import task_journal as J


def test_keys_follow_values_not_identity():
    a = np.array([1.0, 2.0, 3.0])
    same_twice = (0.5, a, a)
    two_copies = (0.5, a.copy(), np.array([1.0, 2.0, 3.0]))
    assert J.task_key(abs, same_twice) == J.task_key(abs, two_copies)
    one_ulp = (0.5, a, np.array([1.0, 2.0, np.nextafter(3.0, 4.0)]))
    assert J.task_key(abs, one_ulp) != J.task_key(abs, same_twice)
    assert J.task_key(abs, (0.5,)) != J.task_key(round, (0.5,))          # the function counts
    assert J.task_key(abs, (1,)) != J.task_key(abs, (1.0,))              # an int is not a float
    assert J.task_key(abs, (np.float64(0.1),)) == J.task_key(abs, (0.1,))
    assert J.task_key(abs, ({"b": 1, "a": (2.0,)},)) == J.task_key(abs, ({"a": (2.0,), "b": 1},))
    assert J.task_key(abs, (a.astype(np.float32),)) != J.task_key(abs, (a,))
    assert J.task_key(abs, (a.reshape(3, 1),)) != J.task_key(abs, (a,))
    with pytest.raises(TypeError):
        J.task_key(abs, (object(),))


def test_results_come_back_bit_for_bit_after_reopening(tmp_path):
    path = tmp_path / "j.jsonl"
    journal = J.TaskJournal(path, digest="d1")
    result = (43.0, np.array([0.1, 1 / 3]), -0.75, {"pm_deg": np.float64(30.02), "n": 3})
    journal.record("k1", result)
    again = J.TaskJournal(path, digest="d1")
    assert len(again) == 1 and "k1" in again and "k2" not in again
    back = again.get("k1")
    assert back[0] == 43.0 and back[2] == -0.75 and back[3] == result[3]
    np.testing.assert_array_equal(back[1], result[1])
    assert again.reused == 1
    header = json.loads(path.read_text().splitlines()[0])
    assert header == {"format": J.FORMAT, "version": J.VERSION, "code": "d1"}


def test_call_runs_a_task_once(tmp_path):
    calls = []

    def square(x):
        calls.append(x)
        return x * x

    journal = J.TaskJournal(tmp_path / "j.jsonl", digest="d")
    assert journal.call(square, 3.0) == 9.0 and journal.call(square, 3.0) == 9.0
    assert J.TaskJournal(tmp_path / "j.jsonl", digest="d").call(square, 3.0) == 9.0
    assert calls == [3.0]


def test_a_line_cut_by_a_kill_is_dropped_and_the_journal_goes_on(tmp_path):
    path = tmp_path / "j.jsonl"
    journal = J.TaskJournal(path, digest="d")
    journal.record("k1", 1.0)
    journal.record("k2", 2.0)
    whole = path.read_bytes()
    path.write_bytes(whole[:-10])                     # the second record cut mid-line
    again = J.TaskJournal(path, digest="d")
    assert "k1" in again and "k2" not in again
    again.record("k3", 3.0)
    third = J.TaskJournal(path, digest="d")
    assert (third.get("k1"), third.get("k3")) == (1.0, 3.0) and "k2" not in third


@pytest.mark.parametrize("damage, message", [
    (lambda text: "not json\n", "line 1 is not a 'vega design task journal' header"),
    (lambda text: text.replace('"version": 1', '"version": 7'), "version 7, this code reads 1"),
    (lambda text: text.replace('"code": "d"', '"code": "other"'),
     "written by other design code"),
    (lambda text: text.replace('"result": "', '"result": "!!', 1), "line 2 is not a finished"),
    (lambda text: text.replace('{"key"', '{"kee"', 1), "line 2 is not a finished task"),
])
def test_damaged_or_foreign_journals_are_refused_and_left_alone(tmp_path, damage, message):
    path = tmp_path / "j.jsonl"
    J.TaskJournal(path, digest="d").record("k1", 1.0)
    path.write_text(damage(path.read_text()) + "cut")
    before = path.read_bytes()
    with pytest.raises(BadFile, match=message):
        J.TaskJournal(path, digest="d")
    assert path.read_bytes() == before                 # not truncated, not appended to


def test_the_code_digest_follows_the_code_files_not_the_caches(tmp_path, monkeypatch):
    package = tmp_path / "journal_probe_pkg"
    (package / "__pycache__").mkdir(parents=True)
    (package / "__init__.py").write_text("X = 1\n")
    (package / "data.yaml").write_text("a: 1\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(J, "CODE_PACKAGES", ("vega_design", "journal_probe_pkg"))
    digest = J.code_digest()
    assert len(digest) == 64 and digest == J.code_digest()
    (package / "__pycache__" / "x.pyc").write_bytes(b"cache")
    (package / "ext.so").write_bytes(b"compiled")
    assert J.code_digest() == digest
    (package / "data.yaml").write_text("a: 2\n")                # data is code here
    changed = J.code_digest()
    assert changed != digest
    (package / "data.yaml").rename(package / "data2.yaml")      # so are the names
    assert J.code_digest() != changed


@pytest.mark.slow
def test_pool_map_reuses_journalled_results_and_records_the_others(tmp_path):
    """The spawned-process path: the journal holds a (deliberately wrong) result for 9.0, so a
    -1 can only come from the journal; 4.0 and 16.0 are computed and recorded."""
    journal = J.TaskJournal(tmp_path / "j.jsonl", digest="d")
    journal.record(J.task_key(math.sqrt, 9.0), -1.0)
    assert list(S.pool_map(math.sqrt, [4.0, 9.0, 16.0, 25.0], 2, journal=journal)) == [
        2.0, -1.0, 4.0, 5.0]
    again = J.TaskJournal(tmp_path / "j.jsonl", digest="d")
    assert len(again) == 4 and again.get(J.task_key(math.sqrt, 16.0)) == 4.0
    # everything journalled: nothing is started, in order
    assert list(S.pool_map(math.sqrt, [25.0, 4.0], 2, journal=again)) == [5.0, 2.0]
    assert list(S.pool_map(math.sqrt, [4.0, 9.0], 2)) == [2.0, 3.0]      # no journal


class _Stop(Exception):
    pass


@pytest.mark.slow
def test_an_interrupted_design_resumes_to_the_uninterrupted_result(tmp_path):
    """Two anchors (40 and 44 s, 1 generation) and a 2 s grid: the anchors, the walk of 42 s
    and whatever steps 3-4 tune. Interrupted at its first progress line (the first anchor
    finished), then resumed from the journal: the same grid and parameters, bit for bit, as a
    run without a journal, with the finished task reused, not re-run."""
    from vega_model.parameters import default_context

    context = default_context()
    kwargs = dict(anchors_s=(40.0, 44.0), grid_step_s=2.0, maxiter=1, popsize=2,
                  polish_maxfev=20, local_maxiter=1, workers=0, drift_scale=1.0)
    reference = S.design_flight(context, progress=lambda line: None, **kwargs)

    def stop(line):
        raise _Stop(line)

    path = tmp_path / "j.jsonl"
    with pytest.raises(_Stop, match="anchor t = 40 s"):
        S.design_flight(context, progress=stop, journal=J.TaskJournal(path), **kwargs)
    assert len(J.TaskJournal(path)) == 1
    journal = J.TaskJournal(path)
    resumed = S.design_flight(context, progress=lambda line: None, journal=journal, **kwargs)
    assert journal.reused == 1
    np.testing.assert_array_equal(resumed.grid_times_s, reference.grid_times_s)
    np.testing.assert_array_equal(resumed.x, reference.x)
    assert resumed.tuning["how"] == reference.tuning["how"]
