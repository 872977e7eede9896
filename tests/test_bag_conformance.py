"""What ROS 2 and GIS tools expect of our bags and files, read by third-party readers: the MCAP library and its
ROS 2 decoder (what Foxglove uses), the YAML metadata as rosbag2 Humble/Jazzy parse it, laspy and PROJ for LAS,
plyfile and pypcd4 for PLY and PCD (issue 15, section 4)."""

from __future__ import annotations

import json
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


def test_each_pointcloud2_is_dense_and_holds_only_finite_points(bag: Path) -> None:
    """sensor_msgs/PointCloud2's is_dense says "no invalid points": PCL's fromROSMsg and most filters skip the NaN
    check when it is true. Every /livox/points cloud says so, and its x, y, z, read through the message's own
    fields with the MCAP ROS 2 decoder, are finite float32 (a cloud marked not dense would cost a consumer a
    pass; one marked dense with NaN in it would break it)."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    clouds = 0
    with open(bag / metadata(bag)["relative_file_paths"][0], "rb") as handle:
        for _schema, _channel, _message, cloud in make_reader(handle, decoder_factories=[DecoderFactory()]) \
                .iter_decoded_messages(topics=["/livox/points"]):
            assert cloud.is_dense is True and cloud.height == 1 and cloud.width > 0
            offsets = {f.name: f.offset for f in cloud.fields if f.name in ("x", "y", "z")}
            assert all(f.datatype == 7 for f in cloud.fields if f.name in offsets)  # FLOAT32
            layout = np.dtype({"names": list(offsets), "formats": ["<f4"] * 3, "offsets": list(offsets.values()),
                               "itemsize": cloud.point_step})
            xyz = np.frombuffer(bytes(cloud.data), dtype=layout, count=cloud.width)
            assert all(np.isfinite(xyz[name]).all() for name in offsets)
            clouds += 1
    assert clouds == 6


# LAS --------------------------------------------------------------------------------------------------
@pytest.fixture(scope="module", params=["world", "sensor"])
def las_file(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> tuple[str, Path]:
    path = tmp_path_factory.mktemp("las") / f"{request.param}.las"
    assert main(["scan", "--seconds", "0.3", "--frame", request.param, "--out", str(path)]) == 0
    return request.param, path


def test_las_returns_and_wkt_bit_follow_the_spec(las_file: tuple[str, Path]) -> None:
    """LAS 1.4 R15: return_number and number_of_returns are at least 1; point formats 6-10 set the WKT bit of
    the global encoding (bit 4 of the uint16 at byte 6, read from the raw header) and give their CRS in WKT."""
    import laspy
    import pyproj

    _, path = las_file
    las = laspy.read(path)
    assert las.header.point_format.id == 6 and len(las.points) > 1000
    returns, of = np.asarray(las.return_number), np.asarray(las.number_of_returns)
    assert returns.min() >= 1 and (returns <= of).all()
    global_encoding = int.from_bytes(path.read_bytes()[6:8], "little")
    assert global_encoding & 0x10
    wkt = next(v for v in las.header.vlrs if v.user_id == "LASF_Projection" and v.record_id == 2112)
    crs = pyproj.CRS.from_wkt(wkt.string)
    assert not crs.is_geographic and [a.direction for a in crs.axis_info][2] == "up"


def test_las_is_z_up_and_says_so(las_file: tuple[str, Path]) -> None:
    """The urban scene's ground is below the sensor (1.5 m up): in a z-up LAS the lowest points have the lowest
    z, whether the world is ENU (sensor at z = +1.5 m) or the sensor FLU (ground at z < 0)."""
    import laspy

    frame, path = las_file
    las = laspy.read(path)
    record = json.loads(next(v for v in las.header.vlrs if v.user_id == "livox-viz").record_data)
    assert "z up" in record["description"] and ("ENU" if frame == "world" else "FLU") in record["description"]
    sensor_height = 1.5 + 0.3 if frame == "world" else 0.0  # the scene's vehicle 1.5 m up, the sensor 0.3 m above
    ground = np.asarray(las.z) < sensor_height - 1.0
    assert ground.mean() > 0.2  # most of what a forward sensor sees below it is the ground
    assert np.median(np.asarray(las.z)[ground]) == pytest.approx(sensor_height - 1.8, abs=0.3)


# One rule, stated in every file ----------------------------------------------------------------------
@pytest.mark.parametrize("suffix", [".ply", ".pcd", ".las", ".csv", ".npz"])
def test_every_file_states_which_points_it_holds(tmp_path: Path, suffix: str) -> None:
    import laspy
    from plyfile import PlyData

    from livox_viz.files.export import NPZ_RULE, POINTS_RULE

    out = tmp_path / f"cloud{suffix}"
    assert main(["scan", "--seconds", "0.1", "--frame", "world", "--out", str(out)]) == 0
    if suffix == ".ply":
        stated = " ".join(PlyData.read(str(out)).comments)
    elif suffix == ".las":
        stated = next(v for v in laspy.read(out).header.vlrs if v.user_id == "livox-viz").record_data.decode()
    elif suffix == ".npz":
        stated = str(np.load(out)["frame_of_reference"])
        assert NPZ_RULE in json.loads(stated)["points"]
    elif suffix == ".csv":  # a CSV holds only its columns: what they are is in its sidecar
        stated = json.loads(out.with_name(out.name + ".json").read_text())["points"]
    else:
        stated = out.read_bytes()[:400].decode("ascii", "replace")
    assert POINTS_RULE in stated or suffix == ".npz"
