"""metadata.yaml lies outside the MCAP CRCs: a run bag whose metadata.yaml lists another message
count for a topic than its MCAP file holds is refused by `vega check` in one line, exit 2
(docs/ADVERSARIAL.md row 80: the count in metadata.yaml is what `ros2 bag info` shows, and no
CRC covers it)."""

import shutil

import pytest
import yaml

from fixture_bags import short_run, write_bag
from vega_bags import bagio
from vega_cli import cli


@pytest.fixture(scope="module")
def bag(tmp_path_factory):
    run = short_run(tmp_path_factory.mktemp("run"), span_s=(20.0, 22.0))
    return write_bag(tmp_path_factory.mktemp("bag") / "bag", run)


def _edited(bag, dst, topic, delta):
    """A copy of ``bag`` whose metadata.yaml count of ``topic`` is changed by ``delta``
    (file-wide message_count left alone); returns (copy, the count the file holds)."""
    shutil.copytree(bag, dst)
    meta = dst / "metadata.yaml"
    tree = yaml.safe_load(meta.read_text())
    (entry,) = [t for t in tree["rosbag2_bagfile_information"]["topics_with_message_count"]
                if t["topic_metadata"]["name"] == topic]
    held = entry["message_count"]
    entry["message_count"] = held + delta
    meta.write_text(yaml.safe_dump(tree, sort_keys=False))
    return dst, held


@pytest.mark.slow
def test_the_written_counts_are_the_files(bag):
    loaded = bagio.read_run_bag(bag)
    tree = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    listed = {t["topic_metadata"]["name"]: t["message_count"]
              for t in tree["topics_with_message_count"]}
    assert listed == {name: len(cols) for name, cols in loaded.topics.items()}


@pytest.mark.slow
@pytest.mark.parametrize("topic, delta", [("/vega/truth", 9398), ("/vega/ins", -1),
                                          ("/clock", 1)])
def test_an_edited_count_is_refused_in_one_line(bag, tmp_path, capsys, topic, delta):
    edited, held = _edited(bag, tmp_path / "edited", topic, delta)
    assert cli.main(["check", str(edited)]) == 2
    err = capsys.readouterr().err
    assert err == (f"vega: error: bag {edited}: metadata.yaml lists {held + delta} messages on "
                   f"{topic}, the MCAP file holds {held}\n")
    with pytest.raises(bagio.BagError, match="metadata.yaml lists"):
        bagio.read_run_bag(edited)
