"""What ROS 2 and GIS tools expect of our bags and files, read by third-party readers: the MCAP library and its
ROS 2 decoder (what Foxglove uses), the YAML metadata as rosbag2 Humble/Jazzy parse it, laspy and PROJ for LAS,
plyfile and pypcd4 for PLY and PCD (issue 15, section 4)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from livox_viz.cli import main

TOPICS = ("/livox/lidar", "/livox/points", "/livox/imu", "/odom", "/tf", "/tf_static")


@pytest.fixture(scope="module")
def bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("bag") / "flight"
    assert main(["scan", "--seconds", "0.6", "--trajectory", "circle", "--rosbag", str(path)]) == 0
    return path


def metadata(bag: Path) -> dict:
    from ruamel.yaml import YAML

    return YAML(typ="safe").load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]


def qos_as_ros_reads_it(text: str) -> list[dict]:
    """The offered QoS string parsed the way rosbag2 Humble does (every policy an int, durations sec/nsec)."""
    from ruamel.yaml import YAML

    profiles = YAML(typ="safe").load(text)
    for profile in profiles:
        for key in ("history", "depth", "reliability", "durability", "liveliness"):
            assert isinstance(profile[key], int), (key, profile)
        for key in ("deadline", "lifespan", "liveliness_lease_duration"):
            assert isinstance(profile[key]["sec"], int) and isinstance(profile[key]["nsec"], int)
        assert isinstance(profile["avoid_ros_namespace_conventions"], bool)
    return profiles


def test_offered_qos_is_what_ros2_bag_record_writes(bag: Path) -> None:
    """/tf_static reliable and transient local (so `ros2 bag play` latches it for RViz, ros2/rviz#916); the rest
    reliable and volatile, as the Livox driver and tf2 publish. In metadata.yaml (version 8, the QoS as a YAML
    string: what Humble reads) and in the MCAP channels (what the MCAP storage plugin reads)."""
    from mcap.reader import make_reader

    info = metadata(bag)
    assert info["version"] == 8 and info["storage_identifier"] == "mcap"
    recorded = {t["topic_metadata"]["name"]: t["topic_metadata"]["offered_qos_profiles"]
                for t in info["topics_with_message_count"]}
    assert set(recorded) == set(TOPICS)
    with open(bag / info["relative_file_paths"][0], "rb") as handle:
        channels = {c.topic: c.metadata["offered_qos_profiles"] for c in make_reader(handle).get_summary()
                    .channels.values()}
    for topic in TOPICS:
        assert isinstance(recorded[topic], str) and channels[topic] == recorded[topic]
        (profile,) = qos_as_ros_reads_it(recorded[topic])
        assert profile["reliability"] == 1  # RMW_QOS_POLICY_RELIABILITY_RELIABLE
        assert profile["durability"] == (1 if topic == "/tf_static" else 2)  # TRANSIENT_LOCAL / VOLATILE
        assert (profile["history"], profile["depth"], profile["liveliness"]) == (3, 0, 1)  # as recorded
        assert profile["deadline"] == {"sec": 9223372036, "nsec": 854775807}  # RMW_DURATION_INFINITE


def test_messages_are_in_log_time_order_and_decode(bag: Path) -> None:
    """File order is log-time order (no step back), every message decodes with the MCAP ROS 2 decoder, and each
    header stamp is its log time."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    info = metadata(bag)
    counts: dict[str, int] = {}
    log_times = []
    with open(bag / info["relative_file_paths"][0], "rb") as handle:
        for _schema, channel, message, decoded in make_reader(handle, decoder_factories=[DecoderFactory()]) \
                .iter_decoded_messages(log_time_order=False):
            log_times.append(message.log_time)
            assert message.publish_time == message.log_time
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
            stamp = decoded.transforms[0].header.stamp if channel.topic.startswith("/tf") else decoded.header.stamp
            assert stamp.sec * 10**9 + stamp.nanosec == message.log_time, channel.topic
            if channel.topic == "/livox/lidar":
                assert decoded.point_num == len(decoded.points) > 0 and decoded.timebase == message.log_time
    steps = np.diff(np.array(log_times, dtype=np.int64))
    assert (steps >= 0).all(), f"{(steps < 0).sum()} steps back in time"
    assert counts == {t["topic_metadata"]["name"]: t["message_count"] for t in info["topics_with_message_count"]}
    assert counts["/livox/lidar"] == counts["/livox/points"] == 6 and counts["/livox/imu"] >= 120
