"""The run-bag reader (:func:`vega_bags.bagio.read_run_bag`) on bags it must read or refuse.

Bags written here by plain rosbags (no vega code) hold exactly the topics, types and bytes
typed out in each test: topics other than the graph's are listed and ignored; a bag with no
data topic (only /clock, or only foreign topics, named sorted) is a foreign bag; a message
count in metadata.yaml other than the MCAP file's is refused; big-endian CDR is read through
rosbags' deserialiser with the same values; a truncated message is undecodable (one line
naming topic and type); topics without messages give empty columns of the message's shapes
and dtypes.
"""

import numpy as np
import pytest

import msg_samples
from bagio_bytes import META, _raw, _small_bag
from vega_bags import bagio
from vega_bus import topics


def test_run_bag_has_only_its_topics(tmp_path):
    path = tmp_path / "bag"
    with bagio.RunBagWriter(path, META) as bag:
        bag.write(topics.INS.name, 1, _raw("InsMeasurement"))
    run = bagio.read_run_bag(path)
    assert run.has(topics.INS.name) is True
    assert run.has("/vega/nothing") is False
    with pytest.raises(bagio.BagError, match=r"no topic /vega/nothing"):
        run["/vega/nothing"]


def _plain_bag(path, entries, metadata=None):
    """A bag written by plain rosbags (no vega code): entries (topic, type, [(t, raw)])."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    store = bagio.vega_typestore()
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        for key, value in (metadata or {}).items():
            writer.set_custom_data(key, value)
        conns = [(writer.add_connection(topic, msgtype, typestore=store), msgs)
                 for topic, msgtype, msgs in entries]
        for conn, msgs in conns:
            for t, raw in msgs:
                writer.write(conn, t, raw)
    return path


def _string_msg(text):
    store = bagio.vega_typestore()
    return bytes(store.serialize_cdr(store.types["std_msgs/msg/String"](data=text),
                                     "std_msgs/msg/String"))


def test_other_topics_are_listed_and_ignored(tmp_path):
    ins = _raw("InsMeasurement")
    path = _plain_bag(tmp_path / "bag", [
        ("/zeta", "std_msgs/msg/String", [(1, _string_msg("z"))]),
        (topics.INS.name, topics.INS.type_name, [(2, ins), (3, ins)]),
        ("/alpha", "std_msgs/msg/String", [(4, _string_msg("a"))]),
        (topics.CLOCK.name, topics.CLOCK.type_name, []),
    ], metadata={"vega.seed": "11"})
    bag = bagio.read_run_bag(path)
    assert bag.other_topics == ("/alpha", "/zeta")
    assert set(bag.topics) == {topics.INS.name, topics.CLOCK.name}
    assert bag.metadata == {"vega.seed": "11"} and bag.path == str(path)
    assert bag[topics.INS.name].log_time_ns.tolist() == [2, 3]
    assert bag[topics.INS.name].log_time_ns.dtype == np.int64
    clock = bag[topics.CLOCK.name]
    assert (clock.topic, clock.type_name) == (topics.CLOCK.name, topics.CLOCK.type_name)
    assert (bag[topics.INS.name].topic, bag[topics.INS.name].type_name) == \
        (topics.INS.name, topics.INS.type_name)
    assert clock.log_time_ns.dtype == np.int64 and clock.log_time_ns.shape == (0,)
    assert len(clock) == 0 and list(clock.columns) == ["stamp_ns"]
    assert clock["stamp_ns"].shape == (0,) and clock["stamp_ns"].dtype == np.int64
    assert [(t, n) for t, n, _ in bagio.iter_raw_messages(path)] == \
        [(topics.INS.name, 2), (topics.INS.name, 3)]
    assert list(bagio.iter_raw_messages(path, {"/alpha"})) == []
    assert list(bagio.iter_raw_messages(path, [topics.INS.name]))[1][2] == ins


def test_only_clock_is_a_foreign_bag(tmp_path):
    """/clock alone is no run bag: at least one data topic (vega_bus.topics.DATA_TOPICS)."""
    path = _plain_bag(tmp_path / "bag", [(topics.CLOCK.name, topics.CLOCK.type_name, []),
                                         (topics.DIAGNOSTICS.name,
                                          topics.DIAGNOSTICS.type_name, [])])
    with pytest.raises(bagio.BagError, match=r"foreign bag: none of the vega topics.*it "
                                             r"holds no topics$"):
        bagio.read_run_bag(path)
    with pytest.raises(bagio.BagError, match="foreign bag"):
        list(bagio.iter_raw_messages(path))
    assert bagio.read_run_bag(_plain_bag(tmp_path / "b2", [
        (topics.TRUTH.name, topics.TRUTH.type_name, [])])).topics.keys() == {topics.TRUTH.name}


def test_a_count_in_metadata_yaml_other_than_the_files_is_refused(tmp_path):
    import yaml

    path = _small_bag(tmp_path / "bag")
    path = path.parent
    meta = path / "metadata.yaml"
    tree = yaml.safe_load(meta.read_text())
    for entry in tree["rosbag2_bagfile_information"]["topics_with_message_count"]:
        if entry["topic_metadata"]["name"] == topics.INS.name:
            entry["message_count"] = 12
    meta.write_text(yaml.safe_dump(tree, sort_keys=False))
    with pytest.raises(bagio.BagError) as info:
        bagio.read_run_bag(path)
    assert str(info.value) == (f"bag {path}: metadata.yaml lists 12 messages on "
                               f"{topics.INS.name}, the MCAP file holds 13")


def test_big_endian_messages_are_read_by_the_deserialiser(tmp_path):
    """The fast reader takes little-endian CDR only; big-endian messages (encapsulation
    0x0000) come back through rosbags' deserialiser with the same values."""
    store = bagio.vega_typestore()
    little = _raw("InsMeasurement")
    msg = store.deserialize_cdr(little, topics.INS.type_name)
    big = bytes(store.serialize_cdr(msg, topics.INS.type_name, little_endian=False))
    assert big[:2] == b"\x00\x00" and len(big) == len(little)
    sample = msg_samples.SAMPLES["InsMeasurement"]
    for first, second in ((big, big), (little, big)):
        path = _plain_bag(tmp_path / f"bag{len(list(tmp_path.iterdir()))}",
                          [(topics.INS.name, topics.INS.type_name, [(1, first), (2, second)])])
        cols = bagio.read_run_bag(path)[topics.INS.name]
        assert cols["pitch_rad"].tolist() == [sample["pitch_rad"]] * 2
        assert cols["seq"].tolist() == [sample["seq"]] * 2 and cols["seq"].dtype == np.int64
        assert cols["valid"].dtype == bool and cols["valid"].tolist() == [True, True]
        assert cols["stamp_ns"].tolist() == [1_700_000_123_987_654_321] * 2
    with pytest.raises(bagio._NotFlat):
        bagio._fast_columns(store, topics.INS.type_name, [big])
    with pytest.raises(bagio._NotFlat):
        bagio._fast_columns(store, topics.INS.type_name, [little, big])


def test_a_truncated_message_is_undecodable(tmp_path):
    ins = _raw("InsMeasurement")
    path = _plain_bag(tmp_path / "bag", [(topics.INS.name, topics.INS.type_name,
                                          [(1, ins[:60]), (2, ins[:60])])])
    with pytest.raises(bagio.BagError) as info:
        bagio.read_run_bag(path)
    assert str(info.value).startswith(f"bag {path}: topic /vega/ins: undecodable "
                                      f"vega_msgs/msg/InsMeasurement message (")
    with pytest.raises(bagio._NotFlat):
        bagio._fast_columns(bagio.vega_typestore(), topics.INS.type_name, [ins[:84]])
    # one byte more than the layout (CDR padding at the end) still takes the fast path
    cols, _ = bagio._fast_columns(bagio.vega_typestore(), topics.INS.type_name,
                                  [ins + b"\x00"])
    assert cols["valid"].tolist() == [True]


def test_topics_without_messages_have_empty_columns_of_the_right_shapes(tmp_path):
    """What a check reads from a topic with no messages: every column, empty, with the
    message's shape (float64[2] -> (0, 2); sequences (0,) with (0,) counts)."""
    path = _plain_bag(tmp_path / "bag", [
        (topics.TRUTH.name, topics.TRUTH.type_name, []),
        (topics.ACTUATOR.name, topics.ACTUATOR.type_name, []),
        (topics.TVC_CMD.name, topics.TVC_CMD.type_name, [])])
    bag = bagio.read_run_bag(path)
    truth = bag[topics.TRUTH.name]
    assert truth["bending_q"].shape == (0, 2) and truth["bending_qdot"].shape == (0, 2)
    assert truth["stamp_ns"].dtype == np.int64 and truth["seq"].dtype == np.int64
    assert truth["mach"].dtype == np.float64 and truth["mach"].shape == (0,)
    act = bag[topics.ACTUATOR.name]
    for key in ("deflection_samples_rad", "rate_samples_radps", "accel_samples_radps2"):
        assert act[key].shape == (0,) and act[key].dtype == np.float64, key
        assert act.counts[key].shape == (0,) and act.counts[key].dtype == np.int64, key
    cmd = bag[topics.TVC_CMD.name]
    assert set(cmd.columns) == {"stamp_ns", "sample_stamp_ns", "seq", "deflection_cmd_rad",
                                "scheduling_velocity_mps", "status"}
    assert cmd["status"].dtype == np.int64 and cmd["sample_stamp_ns"].dtype == np.int64


def test_a_foreign_bag_names_what_it_holds_sorted(tmp_path):
    path = _plain_bag(tmp_path / "bag", [("/b", "std_msgs/msg/String", [(1, _string_msg("b"))]),
                                         ("/a", "std_msgs/msg/String", [(2, _string_msg("a"))])])
    with pytest.raises(bagio.BagError) as info:
        bagio.read_run_bag(path)
    assert str(info.value) == (f"bag {path}: foreign bag: none of the vega topics (/vega/truth, "
                               f"/vega/ins, /vega/tvc_cmd, /vega/actuator); it holds /a, /b")
