"""The run report (vega_bags.report): bag → JSON + Markdown + PNG plots, and the verdict."""

import json

import pytest

from fixture_bags import messages_on, short_run, write_bag
from vega_bus import topics
from vega_bags import bagio, report
from vega_cli import cli

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    return short_run(tmp_path_factory.mktemp("run"))


@pytest.mark.slow
def test_report_of_a_good_run(run, tmp_path):
    bag = write_bag(tmp_path / "bag", run)
    check = report.write_report(bag, tmp_path / "report")
    assert check.passed and check.exit_code == 0
    out = tmp_path / "report"
    data = json.loads((out / "report.json").read_text())
    assert data.pop("plots") == report.PLOTS
    assert data == json.loads(json.dumps(check.to_dict()))
    for name in report.PLOTS:
        assert (out / name).read_bytes()[:8] == PNG_SIGNATURE, name
    md = (out / "report.md").read_text()
    assert "**Verdict: PASS**" in md
    # the ∫|β|dt row stays one table row: its pipes are escaped
    row = next(line for line in md.splitlines() if "∫" in line and line.startswith("|"))
    assert "∫\\|β\\|dt" in row and row.count(" | ") == 8
    for name in report.PLOTS:
        assert f"]({name})" in md
    # Qα: worst-margin sample and max |Qα| in one row; the 3° objective as an info line
    q = check.requirements["q_alpha"]
    row = next(line for line in md.splitlines() if line.startswith("| Load performance |"))
    assert f"{abs(q.peak_value) * q.display_scale:.6g} Pa*deg at {q.peak_time_s:.3f} s" in row
    row = next(line for line in md.splitlines() if line.startswith("| Load objective"))
    assert "| info: " in row and "Qα sensitivity" in md


@pytest.mark.slow
def test_report_names_the_failure(run, tmp_path, capsys):
    def mutate(messages):
        i = messages_on(messages, topics.TRUTH.name)[200]
        messages[i][2].drift_rate_mps = 16.25
    bag = write_bag(tmp_path / "bag", run, mutate)
    status = cli.main(["check", str(bag), "--report", str(tmp_path / "report")])
    out = capsys.readouterr().out
    assert status == 1 and "verdict: FAIL" in out
    md = (tmp_path / "report" / "report.md").read_text()
    assert "**Verdict: FAIL**" in md
    assert "- Lateral control performance ż: 16.25 m/s at 12.000 s exceeds its bound " \
           "15 m/s by 1.25 m/s" in md
    assert json.loads((tmp_path / "report" / "report.json").read_text())["exit_code"] == 1


def test_bad_bag_writes_nothing(tmp_path):
    with pytest.raises(bagio.BagError, match="no such file"):
        report.write_report(tmp_path / "missing", tmp_path / "report")
    assert not (tmp_path / "report").exists()


@pytest.mark.slow
def test_plot_labels_fit_their_figures(run, tmp_path):
    """The plots are laid out with fixed margins (no tight_layout, docs/SIL_SPEED.md): every
    title, tick label, axis label and legend of every report plot lies inside its figure, and
    stacked axes do not overlap (with 1 px of rounding)."""
    import matplotlib.pyplot as plt

    check = report.check_bag(write_bag(tmp_path / "bag", run))
    figs = report._figures(check, None)
    assert sorted(figs) == sorted(report.PLOTS)
    for name, fig in figs.items():
        renderer = fig.canvas.get_renderer()
        box = fig.bbox
        tight = [ax.get_tightbbox(renderer) for ax in fig.axes]
        for ax, tb in zip(fig.axes, tight):
            assert (tb.x0 >= box.x0 - 1 and tb.y0 >= box.y0 - 1 and tb.x1 <= box.x1 + 1
                    and tb.y1 <= box.y1 + 1), (name, ax.get_ylabel(), tb, box)
        # stacked axes: the lower one's labels and title stay below the upper one's ticks
        for upper, lower in zip(tight, tight[1:]):
            assert lower.y1 <= upper.y0 + 1, (name, upper, lower)
        plt.close(fig)


@pytest.mark.slow
@pytest.mark.parametrize("timeout_s", [30.0, 0.0])
def test_forked_plots_are_the_serial_plots(run, tmp_path, monkeypatch, timeout_s):
    """Half of the plots are drawn by a forked child (report._plot): the files are the bytes
    a single process draws (report._save of all six). With no time for the child (timeout
    0: it is killed at once), this process draws its half too: the same files."""
    check = report.check_bag(write_bag(tmp_path / "bag", run))
    serial, forked = tmp_path / "serial", tmp_path / "forked"
    serial.mkdir()
    forked.mkdir()
    report._save(check, None, serial, list(report.PLOTS))
    monkeypatch.setattr(report, "PLOT_CHILD_TIMEOUT_S", timeout_s)
    paths = report._plot(check, None, forked)
    assert [p.name for p in paths] == list(report.PLOTS)
    for name in report.PLOTS:
        assert (forked / name).read_bytes() == (serial / name).read_bytes(), name
