"""ROS 2 bags: read back with rosbags, the same frames and points as the NPZ, in ROS frames, de-skewable."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation, Slerp

from livox_viz.casting.codec import max_decode_error
from livox_viz.cli import main
from livox_viz.core.rotations import enu_flu_from_ned_frd, enu_from_ned, flu_from_frd
from livox_viz.files.rosbag import CUSTOM_MSG, CUSTOM_POINT_MSG, custom_msg_cdr
from livox_viz.motion.tum import save_tum

from .test_motion import WALL_X, flight

rosbags = pytest.importorskip("rosbags")


def typestore():
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    types = get_types_from_msg(CUSTOM_POINT_MSG, "livox_ros_driver2/msg/CustomPoint")
    types.update(get_types_from_msg(CUSTOM_MSG, "livox_ros_driver2/msg/CustomMsg"))
    store.register(types)
    return store


def test_custom_msg_bytes_are_rosbags_own() -> None:
    store = typestore()
    types = store.types
    rng = np.random.default_rng(0)
    for count in (0, 1, 7):
        xyz = rng.normal(size=(count, 3)).astype(np.float32)
        offset = rng.integers(0, 10**8, count)
        line = rng.integers(0, 6, count).astype(np.uint8)
        reflectivity = rng.integers(0, 256, count).astype(np.uint8)
        tag = rng.integers(0, 64, count).astype(np.uint8)
        stamp = 1_700_000_000_123_456_789
        message = types["livox_ros_driver2/msg/CustomMsg"](
            header=types["std_msgs/msg/Header"](stamp=types["builtin_interfaces/msg/Time"](
                sec=stamp // 10**9, nanosec=stamp % 10**9), frame_id="livox_frame"),
            timebase=stamp, point_num=count, lidar_id=0, rsvd=np.zeros(3, np.uint8),
            points=[types["livox_ros_driver2/msg/CustomPoint"](
                offset_time=int(offset[i]), x=float(xyz[i, 0]), y=float(xyz[i, 1]), z=float(xyz[i, 2]),
                reflectivity=int(reflectivity[i]), tag=int(tag[i]), line=int(line[i])) for i in range(count)])
        expected = bytes(store.serialize_cdr(message, "livox_ros_driver2/msg/CustomMsg"))
        assert custom_msg_cdr(stamp, "livox_frame", xyz, offset, line, reflectivity, tag) == expected


def test_ned_frd_to_enu_flu_at_the_boundary() -> None:
    # North is ENU y, east ENU x, down -z; forward stays x, right becomes -y, down -z.
    np.testing.assert_array_equal(enu_from_ned([[1.0, 2.0, 3.0]]), [[2.0, 1.0, -3.0]])
    np.testing.assert_array_equal(flu_from_frd([[1.0, 2.0, 3.0]]), [[1.0, -2.0, -3.0]])
    # A vehicle yawed 90 degrees (NED: facing east) faces ENU x: its FLU forward maps to (1, 0, 0).
    yawed = Rotation.from_euler("z", 90, degrees=True).as_matrix()
    np.testing.assert_allclose(enu_flu_from_ned_frd(yawed) @ [1, 0, 0], [1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(enu_flu_from_ned_frd(np.eye(3)) @ [1, 0, 0], [0, 1, 0], atol=1e-12)  # north
    assert np.linalg.det(enu_flu_from_ned_frd(yawed)) == pytest.approx(1.0)


def read_bag(path: Path) -> dict[str, list]:
    from rosbags.rosbag2 import Reader

    store = typestore()
    messages: dict[str, list] = {}
    with Reader(path) as reader:
        for connection, timestamp, data in reader.messages():
            messages.setdefault(connection.topic, []).append(
                (timestamp, store.deserialize_cdr(data, connection.msgtype)))
    return messages


def test_the_bag_holds_the_npz_frames_in_ros_frames_and_deskews_onto_the_wall(tmp_path: Path) -> None:
    scene = tmp_path / "wall.json"
    scene.write_text(json.dumps({"objects": [{"type": "box", "center": [WALL_X + 0.5, 0, 0], "size": [1, 400, 400]}],
                                 "vehicle_pose": [0, 0, -2, 0, 0, 0]}))
    save_tum(flight(), tmp_path / "flight.txt")
    npz, bag = tmp_path / "cloud.npz", tmp_path / "bag"
    assert main(["scan", "--scene", str(scene), "--trajectory", str(tmp_path / "flight.txt"), "--seconds", "0.5",
                 "--out", str(npz), "--rosbag", str(bag)]) == 0
    assert (bag / "metadata.yaml").is_file() and "mcap" in (bag / "metadata.yaml").read_text()
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []
    data = np.load(npz)
    messages = read_bag(bag)
    assert {"/livox/lidar", "/livox/points", "/livox/imu", "/odom", "/tf", "/tf_static"} <= set(messages)
    custom = [m for _, m in messages["/livox/lidar"]]
    assert len(custom) == len(data["frame_pose"]) == 5
    points = np.concatenate([[(p.x, p.y, p.z) for p in m.points] for m in custom])
    np.testing.assert_allclose(points, flu_from_frd(data["xyz_sensor"]), atol=1e-5)  # float32 of the same points
    times = np.concatenate([m.timebase + np.array([p.offset_time for p in m.points]) for m in custom])
    np.testing.assert_allclose((times - 1_700_000_000 * 10**9) / 1e9, data["t"], atol=1e-9)
    cloud = messages["/livox/points"][2][1]
    assert cloud.point_step == 26 and [f.name for f in cloud.fields][-1] == "timestamp"
    layout = np.dtype({"names": ["x", "y", "z"], "formats": ["<f4"] * 3, "offsets": [0, 4, 8], "itemsize": 26})
    decoded = np.frombuffer(cloud.data.tobytes(), dtype=layout)
    frame = data["frame"] == 2
    np.testing.assert_allclose(np.column_stack([decoded["x"], decoded["y"], decoded["z"]]),
                               flu_from_frd(data["xyz_sensor"][frame]), atol=1e-5)
    assert len(messages["/livox/imu"]) == 101  # 200 Hz from 0 to 0.5 s
    # De-skew with the bag's own ground truth: every point onto the wall (ENU y = north = 40 m).
    odom = [m for _, m in messages["/odom"]]
    odom_t = np.array([m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for m in odom], dtype=np.int64)
    position = np.array([[m.pose.pose.position.x, m.pose.pose.position.y, m.pose.pose.position.z] for m in odom])
    orientation = Rotation.from_quat([[m.pose.pose.orientation.x, m.pose.pose.orientation.y,
                                       m.pose.pose.orientation.z, m.pose.pose.orientation.w] for m in odom])
    mount = messages["/tf_static"][0][1].transforms[0].transform
    mount_t = np.array([mount.translation.x, mount.translation.y, mount.translation.z])
    mount_r = Rotation.from_quat([mount.rotation.x, mount.rotation.y, mount.rotation.z, mount.rotation.w])
    base = odom_t[0]
    query = (times - base) / 1e9
    body_r = Slerp((odom_t - base) / 1e9, orientation)(query)
    body_p = np.column_stack([np.interp(query, (odom_t - base) / 1e9, position[:, k]) for k in range(3)])
    world = body_p + body_r.apply(mount_t + mount_r.apply(points))
    assert np.abs(world[:, 1] - WALL_X).max() <= np.sqrt(3) * max_decode_error(600.0) + 1e-4


def test_an_existing_bag_folder_is_never_replaced(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bag = tmp_path / "bag"
    bag.mkdir()
    (bag / "mine.txt").write_text("keep")
    assert main(["scan", "--seconds", "0.1", "--rosbag", str(bag)]) == 2
    assert "exists" in capsys.readouterr().err and (bag / "mine.txt").read_text() == "keep"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bag"]


def test_packed_imu_and_odometry_read_back_as_written(tmp_path: Path) -> None:
    from livox_viz.core.poses import Pose
    from livox_viz.files.rosbag import RosbagWriter
    from livox_viz.motion.flights import builtin_trajectory
    from livox_viz.motion.imu import synthesize_imu

    flight_ = builtin_trajectory("figure8", 6.0, Pose((1.0, 2.0, -5.0), 0.1, 0.0, 0.3), 2.0)
    imu = synthesize_imu(flight_, 200.0, start=0.0, stop=1.0)
    with RosbagWriter(tmp_path / "bag", Pose((0.1, 0.0, -0.2), 0.0, 0.2, 0.0)) as writer:
        writer.write_imu(imu)
        writer.write_motion(flight_, imu.t)
    messages = read_bag(tmp_path / "bag")
    got = np.array([[m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z,
                     m.linear_acceleration.x, m.linear_acceleration.y, m.linear_acceleration.z]
                    for _, m in messages["/livox/imu"]])
    expected = np.hstack([flu_from_frd(imu.angular_velocity), flu_from_frd(imu.specific_force)])
    np.testing.assert_array_equal(got, expected)
    stamps = np.array([m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for _, m in messages["/livox/imu"]])
    np.testing.assert_array_equal(stamps, 1_700_000_000 * 10**9 + np.round(imu.t * 1e9).astype(np.int64))
    imu_messages = [m for _, m in messages["/livox/imu"]]
    assert all(m.header.frame_id == "base_link" and m.orientation_covariance[0] == -1 for m in imu_messages)
    odom = [m for _, m in messages["/odom"]]
    np.testing.assert_allclose([[m.pose.pose.position.x, m.pose.pose.position.y, m.pose.pose.position.z]
                                for m in odom], enu_from_ned(flight_.position_at(imu.t)), atol=1e-12)
    assert odom[5].child_frame_id == "base_link" and odom[5].header.frame_id == "odom"
    transform = messages["/tf"][7][1].transforms[0]
    assert transform.child_frame_id == "base_link" and transform.transform.rotation.w == pytest.approx(
        odom[7].pose.pose.orientation.w)


def test_imu_covariances_state_the_noise_the_samples_have(tmp_path: Path) -> None:
    """With --imu-noise, each IMU message's covariance diagonals are the white noise's variance per sample
    (density^2 x rate), which the samples of a hovering sensor show; a perfect IMU's stay all zero ("unknown")."""
    gyroscope_density, accelerometer_density, rate = 0.01, 0.1, 200.0
    assert main(["scan", "--seconds", "2", "--scene", "open_field", "--imu-rate", str(rate), "--imu-noise",
                 f"{gyroscope_density},0,{accelerometer_density},0", "--rosbag", str(tmp_path / "noisy")]) == 0
    assert main(["scan", "--seconds", "0.3", "--scene", "open_field", "--rosbag", str(tmp_path / "perfect")]) == 0
    imu = [m for _, m in read_bag(tmp_path / "noisy")["/livox/imu"]]
    rates = np.array([[m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z] for m in imu])
    forces = np.array([[m.linear_acceleration.x, m.linear_acceleration.y, m.linear_acceleration.z] for m in imu])
    gyroscope_variance = gyroscope_density**2 * rate  # 0.02 (rad/s)^2
    accelerometer_variance = accelerometer_density**2 * rate  # 2 (m/s^2)^2
    for m in imu:
        np.testing.assert_allclose(np.reshape(m.angular_velocity_covariance, (3, 3)),
                                   np.eye(3) * gyroscope_variance, rtol=1e-12)
        np.testing.assert_allclose(np.reshape(m.linear_acceleration_covariance, (3, 3)),
                                   np.eye(3) * accelerometer_variance, rtol=1e-12)
        assert m.orientation_covariance[0] == -1
    # A hovering sensor turns not at all and feels gravity alone: what varies is the noise (1200 values each).
    assert len(imu) >= 400
    assert np.var(rates) == pytest.approx(gyroscope_variance, rel=0.15)
    assert np.var(forces - forces.mean(axis=0)) == pytest.approx(accelerometer_variance, rel=0.15)
    for _, m in read_bag(tmp_path / "perfect")["/livox/imu"]:
        assert not np.any(m.angular_velocity_covariance) and not np.any(m.linear_acceleration_covariance)
