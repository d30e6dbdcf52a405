"""The README holds what the shipped sign-off record says, stays short, and links to real files.

The README's five status lines are the headline of the flown table's sign-off record
(``ros2_ws/src/vega_gnc/config/tvc_controller.signoff.json``, written by ``vega verify`` and
installed by ``vega ship``): every number in them is parsed here and compared with the record,
so a new table shipped without its README status, or a status edited by hand, fails. The
README stays at most 150 lines and 15 000 bytes (details go to docs/), and every relative link
of README.md and docs/README.md (the index of docs/) names a file that exists.
"""

import json
import re
from datetime import datetime
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
README = ROOT / "README.md"
DOCS_INDEX = ROOT / "docs" / "README.md"
SIGNOFF = ROOT / "ros2_ws" / "src" / "vega_gnc" / "config" / "tvc_controller.signoff.json"

MAX_LINES = 150
MAX_BYTES = 15_000

# [text](target) and ![alt](target); the target ends at the first space or ')'
LINK = re.compile(r"\[[^\]]*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)")


def _record() -> dict:
    return json.loads(SIGNOFF.read_text(encoding="utf-8"))


def _check(record: dict, name: str) -> dict:
    found = [c for c in record["checks"] if c["check"] == name]
    assert len(found) == 1, f"sign-off record: {len(found)} checks named {name!r}"
    return found[0]


def _status_section() -> str:
    text = README.read_text(encoding="utf-8")
    match = re.search(r"^## Status\n(.*?)(?=^## )", text, re.S | re.M)
    assert match, "README.md has no '## Status' section followed by another section"
    return match.group(1)


def _status_lines() -> list[str]:
    return [line[2:] for line in _status_section().splitlines() if line.startswith("- ")]


def _line(prefix: str) -> str:
    found = [line for line in _status_lines() if line.startswith(prefix)]
    assert len(found) == 1, f"README status: {len(found)} lines start with {prefix!r}"
    return found[0]


def _match(pattern: str, line: str) -> re.Match:
    match = re.search(pattern, line)
    assert match, f"README status line does not match {pattern!r}: {line!r}"
    return match


def test_status_has_five_lines():
    assert len(_status_lines()) == 5, _status_lines()


def test_status_names_the_record_and_its_date():
    section = _status_section()
    assert "ros2_ws/src/vega_gnc/config/tvc_controller.signoff.json" in section
    finished = datetime.fromisoformat(_record()["finished_utc"]).date().isoformat()
    assert f"finished {finished}" in section
    assert _record()["signed_off"] is True


def test_flight_day_line_is_the_record():
    check = _check(_record(), f"flight-day {_record()['scope']['flight_day_runs']} samples")
    f = check["figures"]
    m = _match(r"^Flight day \(the sign-off\), seed 0: (\d+) of (\d+) go samples of (\d+) pass "
               r"the load allowable and every requirement \(lower bound ([\d.]+) % at 90 % "
               r"confidence\), (\d+) unstable; availability ([\d.]+)–([\d.]+) % by month, "
               r"the design's ([\d.]+)–([\d.]+) %\.$", _line("Flight day"))
    passed, n, runs, lower, unstable, a_lo, a_hi, d_lo, d_hi = m.groups()
    assert (int(passed), int(n)) == (f["passed"], f["n"])
    assert int(runs) == f["n"] + f["scrubbed"] == _record()["scope"]["flight_day_runs"]
    assert lower == f"{100 * f['lower_bound_90']:.2f}"
    assert int(unstable) == f["unstable"]
    assert a_lo == f"{100 * min(f['availability'].values()):.1f}"
    assert a_hi == f"{100 * max(f['availability'].values()):.1f}"
    assert d_lo == f"{100 * min(f['availability_design'].values()):.1f}"
    assert d_hi == f"{100 * max(f['availability_design'].values()):.1f}"
    assert check["passed"] is True


def test_monte_carlo_line_is_the_record():
    mc = _check(_record(), "mc 852 flights")
    figures = mc["figures"]
    m = _match(r"^Thesis-box Monte Carlo \(regression\), seed 0: (\d+) of (\d+) flights pass "
               r"\(([\d.]+) %; lower bound ([\d.]+) % at 90 % confidence\), (\d+) unstable; "
               r"failures by requirement: (\d+) Qα, (\d+) drift\.$",
               _line("Thesis-box Monte Carlo"))
    passed, runs, percent, lower, unstable, q_alpha, drift = m.groups()
    assert int(passed) == figures["passed"]
    assert int(runs) == figures["runs"] == _record()["scope"]["runs"]
    assert percent == f"{100 * figures['passed'] / figures['runs']:.1f}"
    assert lower == f"{100 * figures['pass_fraction_lower_90']:.1f}"
    assert int(unstable) == figures["unstable"]
    assert {"q_alpha": int(q_alpha), "drift": int(drift)} == figures["failures_by_requirement"]


def test_nominal_margins_line_is_the_record():
    worst = _check(_record(), "margins --dispersed")["figures"]["nominal_worst"]
    m = _match(r"^Nominal margins 0–100 s: GM ([\d.]+) dB low, ([\d.]+) dB high, PM ([\d.]+)° "
               r"\(requirement 6 dB, 30°\)\.$", _line("Nominal margins"))
    gm_low, gm_high, pm = m.groups()
    assert gm_low == f"{worst['gm_low_db'][0]:.2f}"
    assert gm_high == f"{worst['gm_high_db'][0]:.2f}"
    assert pm == f"{worst['pm_deg'][0]:.2f}"
    assert _record()["scope"]["at"] == "0:100:0.5"


def test_dispersed_line_is_the_record():
    margins = _check(_record(), "margins --dispersed")
    robust = _check(_record(), "robust --no-mu")
    m = _match(r"^Dispersed frozen loops: (\d+) unstable, (\d+) bending-criterion misses; "
               r"`vega robust --no-mu` (passes|fails)\.$", _line("Dispersed frozen loops"))
    unstable, misses, verdict = m.groups()
    assert int(unstable) == margins["figures"]["unstable_loops"]
    assert int(misses) == margins["figures"]["bending_miss_times"]
    assert margins["passed"] is True
    assert (verdict == "passes") == (robust["passed"] and robust["gated"])


def test_sil_line_is_the_record():
    sil = [c for c in _record()["checks"] if c["check"].startswith("sil ")]
    gated = [c for c in sil if c["gated"]]
    reported = [c["check"].removeprefix("sil ") for c in sil if not c["gated"]]
    m = _match(r"^SIL: (\d+) of (\d+) gated scenarios pass; (.+) are reported, not gated\.$",
               _line("SIL:"))
    passed, total, named = m.groups()
    assert int(total) == len(gated) == len(set(_record()["scope"]["scenarios"]) - set(reported))
    assert int(passed) == sum(c["passed"] for c in gated)
    names = re.findall(r"([a-z_]+)(?: \([^)]*\))?(?:,| and|$)", named)
    assert sorted(names) == sorted(reported)


def test_readme_is_short():
    data = README.read_bytes()
    assert len(data.decode("utf-8").splitlines()) <= MAX_LINES
    assert len(data) <= MAX_BYTES


@pytest.mark.parametrize("page", [README, DOCS_INDEX], ids=lambda p: str(p.relative_to(ROOT)))
def test_relative_links_point_to_existing_files(page):
    targets = LINK.findall(page.read_text(encoding="utf-8"))
    assert targets, f"{page}: no links found"
    missing = []
    for target in targets:
        if re.match(r"^[a-z][a-z0-9+.-]*:", target) or target.startswith("#"):
            continue  # http:, https:, mailto: ...; anchors within the page
        path = (page.parent / target.split("#", 1)[0]).resolve()
        if not path.is_file():
            missing.append(target)
    assert not missing, f"{page.relative_to(ROOT)}: links to missing files: {missing}"


def test_docs_index_lists_every_page():
    index = DOCS_INDEX.read_text(encoding="utf-8")
    listed = {Path(t.split("#", 1)[0]).name for t in LINK.findall(index)}
    pages = {p.name for p in (ROOT / "docs").glob("*.md")} - {"README.md"}
    assert not pages - listed, f"docs/README.md does not list {sorted(pages - listed)}"
