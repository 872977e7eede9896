"""One motion for the rays, the NPZ's frame poses, /odom, /tf and the IMU, on a sparse, sharp-turning TUM flight.

Poses 2 s apart, a 90-degree turn at each, rolling and pitching, the lidar mounted
off-centre and turned. Every check reads the bag with rosbags and compares with a
computation of its own (scipy splines and rotations, finite differences, the
waypoints as written), never one output of the model with another.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scipy.interpolate import CubicHermiteSpline, CubicSpline
from scipy.spatial.transform import Rotation, RotationSpline

from livox_viz import load_preset
from livox_viz.casting.codec import max_decode_error
from livox_viz.casting.scan import LidarScanner
from livox_viz.cli import main
from livox_viz.motion.tum import save_tum

from .test_motion import sharp_turns
from .test_rosbag import read_bag

pytest.importorskip("rosbags")

MOUNT_XYZ = [0.25, -0.15, -0.3]
MOUNT_RPY = [0.2, -0.25, 0.35]
SECONDS = 5.0
IMU_RATE = 1000.0
GRAVITY = 9.80665
#: NED <-> ENU and FRD <-> FLU, written out here rather than taken from the code under test.
NED_ENU = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
FRD_FLU = np.diag([1.0, -1.0, -1.0])


def mounted_config(folder: Path) -> Path:
    preset = json.loads((Path(__file__).resolve().parent.parent / "presets" / "livox_mid70.json").read_text())
    preset["SensorPosXYZ"], preset["SensorAngEular"] = MOUNT_XYZ, MOUNT_RPY
    path = folder / "mounted.json"
    path.write_text(json.dumps(preset))
    return path


def room(folder: Path) -> Path:
    """A closed 80 m box round the flight: every ray returns."""
    path = folder / "room.json"
    path.write_text(json.dumps({"objects": [{"type": "box", "center": [5, 5, -5], "size": [80, 80, 40]}],
                                "vehicle_pose": [0, 0, -3, 0, 0, 0]}))
    return path


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> dict:
    folder = tmp_path_factory.mktemp("one_motion")
    save_tum(sharp_turns(), folder / "turns.txt")
    assert main(["scan", "--config", str(mounted_config(folder)), "--scene", str(room(folder)), "--trajectory",
                 str(folder / "turns.txt"), "--seconds", str(SECONDS), "--out", str(folder / "cloud.npz"),
                 "--rosbag", str(folder / "bag"), "--imu-rate", str(IMU_RATE)]) == 0
    return {"npz": dict(np.load(folder / "cloud.npz")), "bag": read_bag(folder / "bag")}


def stamp(message) -> float:
    """Seconds from the scan start."""
    return (message.header.stamp.sec * 10**9 + message.header.stamp.nanosec - 1_700_000_000 * 10**9) / 1e9


def odometry(bag: dict) -> dict[str, np.ndarray]:
    odom = [m for _, m in bag["/odom"]]
    return {
        "t": np.array([stamp(m) for m in odom]),
        "position": np.array([[m.pose.pose.position.x, m.pose.pose.position.y, m.pose.pose.position.z] for m in odom]),
        "rotation": Rotation.from_quat([[m.pose.pose.orientation.x, m.pose.pose.orientation.y,
                                         m.pose.pose.orientation.z, m.pose.pose.orientation.w] for m in odom]),
        "linear": np.array([[m.twist.twist.linear.x, m.twist.twist.linear.y, m.twist.twist.linear.z] for m in odom]),
        "angular": np.array([[m.twist.twist.angular.x, m.twist.twist.angular.y, m.twist.twist.angular.z]
                             for m in odom]),
    }


def static_mount(bag: dict) -> tuple[np.ndarray, Rotation]:
    transform = bag["/tf_static"][0][1].transforms[0].transform
    rotation = transform.rotation
    return (np.array([transform.translation.x, transform.translation.y, transform.translation.z]),
            Rotation.from_quat([rotation.x, rotation.y, rotation.z, rotation.w]))


def test_bag_points_placed_with_the_bags_own_odom_land_on_the_true_hits(recorded: dict) -> None:
    bag, npz = recorded["bag"], recorded["npz"]
    custom = [m for _, m in bag["/livox/lidar"]]
    points = np.concatenate([[(p.x, p.y, p.z) for p in m.points] for m in custom])
    times = np.concatenate([(m.timebase + np.array([p.offset_time for p in m.points]) - 1_700_000_000 * 10**9) / 1e9
                            for m in custom])
    odom = odometry(bag)
    # A user's interpolation of /odom: Hermite with the twist's velocity (turned into the world), scipy's own
    # rotation spline through the orientations.
    velocity_world = odom["rotation"].apply(odom["linear"])
    position = CubicHermiteSpline(odom["t"], odom["position"], velocity_world)(times)
    body = RotationSpline(odom["t"], odom["rotation"])(times)
    mount_t, mount_r = static_mount(bag)
    placed = position + body.apply(mount_t + mount_r.apply(points))
    truth = npz["xyz_world"] @ NED_ENU.T
    miss = np.linalg.norm(placed - truth, axis=1)
    assert points.shape[0] == truth.shape[0] > 400_000
    assert miss.max() <= np.sqrt(3) * max_decode_error(600.0) + 2e-4
    assert np.median(miss) < max_decode_error(600.0)


def test_frame_pose_is_the_bags_pose_at_the_same_stamps(recorded: dict) -> None:
    bag, npz = recorded["bag"], recorded["npz"]
    odom = odometry(bag)
    mount_t, mount_r = static_mount(bag)
    frame_pose = npz["frame_pose"]
    assert frame_pose.shape[0] == round(SECONDS * 10)
    for row in frame_pose:
        for time, pose in ((row[0] * 0.1, row[1:7]), ((row[0] + 1) * 0.1, row[7:13])):
            k = int(np.flatnonzero(np.abs(odom["t"] - time) < 1e-9)[0])
            sensor_enu = odom["position"][k] + odom["rotation"][k].apply(mount_t)
            sensor_rotation = (odom["rotation"][k] * mount_r).as_matrix()
            np.testing.assert_allclose(NED_ENU @ sensor_enu, pose[:3], atol=1e-9)
            ned_frd = NED_ENU @ sensor_rotation @ FRD_FLU
            np.testing.assert_allclose(Rotation.from_euler("ZYX", pose[5:2:-1]).as_matrix(), ned_frd, atol=1e-9)


def test_odometry_twist_is_in_the_body_frame(recorded: dict) -> None:
    """Against finite differences of the bag's own poses, turned into the body frame (REP 105: twist in the
    child frame)."""
    odom = odometry(recorded["bag"])
    dt = 1.0 / IMU_RATE
    rotation = odom["rotation"]
    inner = slice(1, -1)
    world_velocity = (odom["position"][2:] - odom["position"][:-2]) / (2 * dt)
    np.testing.assert_allclose(odom["linear"][inner], rotation[inner].inv().apply(world_velocity), atol=1e-3)
    rate = (rotation[:-2].inv() * rotation[2:]).as_rotvec() / (2 * dt)
    np.testing.assert_allclose(odom["angular"][inner], rate, atol=1e-3)
    # The rotations are far from trivial: the world and body frames differ by metres per second here.
    assert np.abs(world_velocity - odom["linear"][inner]).max() > 2.0
    assert np.abs(rate).max() > 0.5


def test_the_bags_imu_integrates_back_to_the_bags_poses(recorded: dict) -> None:
    bag = recorded["bag"]
    imu = [m for _, m in bag["/livox/imu"]]
    assert {m.header.frame_id for m in imu} == {"base_link"}
    t = np.array([stamp(m) for m in imu])
    omega = np.array([[m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z] for m in imu])
    force = np.array([[m.linear_acceleration.x, m.linear_acceleration.y, m.linear_acceleration.z] for m in imu])
    odom = odometry(bag)
    np.testing.assert_allclose(t, odom["t"], atol=1e-9)
    gravity = np.array([0.0, 0.0, -GRAVITY])  # ENU
    dt = 1.0 / IMU_RATE
    attitude = odom["rotation"][0]
    position = odom["position"][0].copy()
    velocity = attitude.apply(odom["linear"][0])
    worst_angle = worst_position = 0.0
    for k in range(t.size - 1):
        before = attitude
        attitude = attitude * Rotation.from_rotvec(0.5 * (omega[k] + omega[k + 1]) * dt)
        a0, a1 = before.apply(force[k]) + gravity, attitude.apply(force[k + 1]) + gravity
        position = position + velocity * dt + (2 * a0 + a1) / 6 * dt**2
        velocity = velocity + 0.5 * (a0 + a1) * dt
        if (k + 1) % 250 == 0:
            worst_angle = max(worst_angle, float((odom["rotation"][k + 1].inv() * attitude).magnitude()))
            worst_position = max(worst_position, float(np.linalg.norm(position - odom["position"][k + 1])))
    assert worst_angle < 1e-4 and worst_position < 5e-3


def test_each_ray_starts_from_the_sensors_track_at_its_own_time() -> None:
    """Each point's origin, recovered from its true hit and its sensor-frame point, is the sensor's position at the
    ray's own time: scipy's natural spline through the waypoints with the mount applied (a ray one sample late is
    50 um off at 5 m/s)."""
    cfg = load_preset("livox_mid70")
    import dataclasses

    cfg = dataclasses.replace(cfg, sensor_pos_xyz=tuple(MOUNT_XYZ), sensor_ang_euler=tuple(MOUNT_RPY))
    import trimesh

    scene = trimesh.creation.box((80.0, 80.0, 40.0), trimesh.transformations.translation_matrix((5.0, 5.0, -5.0)))
    flight = sharp_turns()
    frames = list(LidarScanner(cfg, scene, trajectory=flight, seed=0).frames(1.5))
    t = np.concatenate([f.t for f in frames])
    xyz_world = np.concatenate([f.xyz_world for f in frames])
    xyz_sensor = np.concatenate([f.xyz_sensor for f in frames])
    quaternions = flight.quaternion  # the waypoints as written (signs already continuous)
    spline = CubicSpline(flight.t, np.hstack([flight.position, quaternions]), bc_type="natural")(t)
    body = Rotation.from_quat(spline[:, 3:])
    mount = Rotation.from_euler("ZYX", MOUNT_RPY[::-1])
    origin = spline[:, :3] + body.apply(MOUNT_XYZ)
    recovered = xyz_world - (body * mount).apply(xyz_sensor)
    assert t.size > 100_000
    assert np.abs(recovered - origin).max() < 1e-6
    # The same check with the wall's tolerance of before would let a ray one sample late through: the sensor moves
    # this much per sample here.
    speed = np.linalg.norm(flight.velocity_at(t), axis=1)
    assert np.median(speed) / cfg.point_rate > 2e-5


def test_imu_frame_lidar_is_the_lidars_own_motion_in_livox_frame(tmp_path: Path) -> None:
    """--imu-frame lidar: the IMU at the lidar's origin and axes (the Livox driver's convention), checked against
    finite differences of the lidar's pose from the bag's /odom and /tf_static."""
    save_tum(sharp_turns(), tmp_path / "turns.txt")
    assert main(["scan", "--config", str(mounted_config(tmp_path)), "--scene", str(room(tmp_path)), "--trajectory",
                 str(tmp_path / "turns.txt"), "--seconds", "3", "--rosbag", str(tmp_path / "bag"), "--imu-rate",
                 str(IMU_RATE), "--imu-frame", "lidar"]) == 0
    bag = read_bag(tmp_path / "bag")
    imu = [m for _, m in bag["/livox/imu"]]
    assert {m.header.frame_id for m in imu} == {"livox_frame"}
    omega = np.array([[m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z] for m in imu])
    force = np.array([[m.linear_acceleration.x, m.linear_acceleration.y, m.linear_acceleration.z] for m in imu])
    odom = odometry(bag)
    mount_t, mount_r = static_mount(bag)
    lidar = odom["rotation"] * mount_r
    origin = odom["position"] + odom["rotation"].apply(mount_t)
    dt = 1.0 / IMU_RATE
    acceleration = (origin[2:] - 2 * origin[1:-1] + origin[:-2]) / dt**2
    inner = slice(1, -1)
    np.testing.assert_allclose(force[inner], lidar[inner].inv().apply(acceleration - [0.0, 0.0, -GRAVITY]),
                               atol=5e-3)
    np.testing.assert_allclose(omega[inner], (lidar[:-2].inv() * lidar[2:]).as_rotvec() / (2 * dt), atol=1e-3)
    # Not the body's readings merely turned: the lever arm shows.
    body_force = odom["rotation"][inner].inv().apply(
        (odom["position"][2:] - 2 * odom["position"][1:-1] + odom["position"][:-2]) / dt**2 - [0.0, 0.0, -GRAVITY])
    assert np.abs(force[inner] - mount_r.inv().apply(body_force)).max() > 0.05


def test_a_moving_scanners_pose_before_the_first_ray_is_the_flights_start() -> None:
    """sensor_pose of a scanner on a flight is where the scan starts (the flight's first pose with the mount),
    the same as its track at t = 0, not anywhere else along the flight."""
    import trimesh

    from livox_viz.config.mount import sensor_world_pose
    from livox_viz.core.poses import Pose
    from livox_viz.motion.flights import builtin_trajectory

    cfg = load_preset("livox_mid70")
    flight = builtin_trajectory("circle", 6.0, Pose((3.0, -2.0, -5.0), 0.0, 0.0, 0.4), 4.0)
    scanner = LidarScanner(cfg, trimesh.creation.box((1, 1, 1)), trajectory=flight)
    expected = sensor_world_pose(cfg, flight.pose_at(flight.span[0]))
    np.testing.assert_allclose(scanner.sensor_pose.origin, expected.origin, atol=1e-12)
    np.testing.assert_allclose(scanner.sensor_pose.rotation, expected.rotation, atol=1e-12)
    np.testing.assert_allclose(scanner.mounted.sensor_pose_at(0.0).origin, expected.origin, atol=1e-9)
    assert np.linalg.norm(flight.pose_at(flight.span[1]).origin - expected.origin) > 1.0
