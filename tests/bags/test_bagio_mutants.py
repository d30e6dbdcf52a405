"""Run-bag metadata helpers: tests written for the survivors of `make mutation MODULE=bagio`.

Independent references: a throw-away git repository made here (its commit read from
``.git/HEAD`` and the ref file, not through ``git rev-parse``), hashlib's SHA-256 of the bytes,
and the documented keys of :func:`run_metadata`.
"""

import hashlib
import re
import subprocess
from pathlib import Path

import pytest

from vega_bags.bagio import (META_CONTROLLER_TABLE, META_CONTROLLER_TABLE_SHA256,
                             META_GIT_REVISION, META_GUIDANCE_REFERENCE,
                             META_GUIDANCE_REFERENCE_SHA256, META_SCENARIO, META_SCENARIO_YAML,
                             META_SEED, file_sha256, git_revision, run_metadata)


def _git(repo, *args):
    subprocess.run(["git", "-c", "user.name=t", "-c", "user.email=t@localhost",
                    "-c", "commit.gpgsign=false", *args], cwd=repo, check=True,
                   capture_output=True)


def _head(repo: Path) -> str:
    """The commit of HEAD read from the files of .git (no git command)."""
    head = (repo / ".git" / "HEAD").read_text().strip()
    assert head.startswith("ref: ")
    return (repo / ".git" / head[5:]).read_text().strip()


@pytest.fixture
def repo(tmp_path):
    r = tmp_path / "repo"
    r.mkdir()
    _git(r, "init", "-q")
    (r / "a.txt").write_text("one\n")
    _git(r, "add", "a.txt")
    _git(r, "commit", "-q", "-m", "first")
    return r


def test_clean_repository_gives_its_commit(repo):
    sha = _head(repo)
    assert re.fullmatch(r"[0-9a-f]{40}", sha)
    assert git_revision(repo) == sha
    # untracked files do not make it dirty
    (repo / "new.txt").write_text("untracked\n")
    assert git_revision(repo) == sha


def test_modified_tracked_file_is_dirty(repo):
    (repo / "a.txt").write_text("two\n")
    assert git_revision(repo) == _head(repo) + "+dirty"
    assert git_revision(str(repo)) == _head(repo) + "+dirty"


def test_outside_git_is_unknown(tmp_path):
    plain = tmp_path / "plain"
    plain.mkdir()
    assert git_revision(plain) == "unknown"


def test_status_failing_is_unknown(repo):
    """A corrupt index: `git rev-parse HEAD` still works, `git status` fails → unknown."""
    (repo / ".git" / "index").write_bytes(b"garbage, not an index")
    assert git_revision(repo) == "unknown"


def test_default_is_the_package_checkout():
    rev = git_revision()
    assert rev == "unknown" or re.fullmatch(r"[0-9a-f]{40}(\+dirty)?", rev)
    assert rev != "unknown"          # the tests run from a git checkout


def test_file_sha256_is_hashlib_of_the_bytes(tmp_path):
    data = bytes(range(256)) * 9000          # 2.3 MB: more than one 1 MiB block
    f = tmp_path / "blob"
    f.write_bytes(data)
    assert file_sha256(f) == hashlib.sha256(data).hexdigest()
    assert file_sha256(str(f)) == hashlib.sha256(data).hexdigest()


def test_run_metadata_keys_and_values(tmp_path, repo):
    table = tmp_path / "table.npz"
    table.write_bytes(b"table bytes")
    guide = tmp_path / "guide.csv"
    guide.write_bytes(b"guide bytes")
    meta = run_metadata("nominal", "name: nominal\n", 7, table, git_rev="abc123")
    assert meta == {
        META_SCENARIO: "nominal",
        META_SCENARIO_YAML: "name: nominal\n",
        META_SEED: "7",
        META_CONTROLLER_TABLE: str(table.resolve()),
        META_CONTROLLER_TABLE_SHA256: hashlib.sha256(b"table bytes").hexdigest(),
        META_GIT_REVISION: "abc123",
        META_GUIDANCE_REFERENCE: "none",
    }
    meta = run_metadata("n", "y", 1, str(table), git_rev="r", guidance_reference=str(guide),
                        extra={"vega.plant": "nonlinear", "vega.n": 3})
    assert meta[META_GUIDANCE_REFERENCE] == str(guide.resolve())
    assert meta[META_GUIDANCE_REFERENCE_SHA256] == hashlib.sha256(b"guide bytes").hexdigest()
    assert meta["vega.plant"] == "nonlinear" and meta["vega.n"] == "3"
    # default revision: the package checkout's
    assert run_metadata("n", "y", 1, table)[META_GIT_REVISION] == git_revision()


def test_repository_without_a_commit_is_unknown(tmp_path):
    """`git rev-parse HEAD` fails (prints "HEAD" on stdout) while `git status` works."""
    r = tmp_path / "empty"
    r.mkdir()
    _git(r, "init", "-q")
    assert git_revision(r) == "unknown"
