"""A moving sensor: the motion model against scipy, per-point poses, TUM files, the built-in flights, the IMU."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import trimesh
from scipy.interpolate import CubicSpline
from scipy.spatial.transform import Rotation

from livox_viz import LivoxVizError, load_preset
from livox_viz.casting.codec import max_decode_error
from livox_viz.casting.scan import LidarScanner
from livox_viz.core.poses import Pose
from livox_viz.core.rotations import quat_rotate, quat_to_matrix
from livox_viz.motion.flights import builtin_trajectory
from livox_viz.motion.imu import GRAVITY, ImuNoise, ImuStream, synthesize_imu
from livox_viz.motion.trajectory import Trajectory
from livox_viz.motion.tum import load_tum, save_tum

WALL_X = 40.0
SPEED = 5.0
YAW_RATE = 0.3


def flight(seconds: float = 1.2) -> Trajectory:
    """North at 5 m/s while yawing at 0.3 rad/s, 2 m up, sampled at 1 kHz."""
    t = np.arange(0.0, seconds, 0.001)
    position = np.column_stack([SPEED * t, np.zeros_like(t), np.full_like(t, -2.0)])
    quaternion = Rotation.from_rotvec(np.outer(YAW_RATE * t - 0.15, [0.0, 0.0, 1.0])).as_quat()
    return Trajectory("flight", t, position, quaternion)


def wall() -> trimesh.Trimesh:
    """A wall across the path, its face at x = 40 m (north)."""
    return trimesh.creation.box((1.0, 400.0, 400.0), trimesh.transformations.translation_matrix((WALL_X + 0.5, 0, 0)))


def test_every_point_lies_on_the_wall_with_its_own_pose() -> None:
    cfg = load_preset("livox_mid70")
    scanner = LidarScanner(cfg, wall(), trajectory=flight(), seed=0)
    frames = list(scanner.frames(1.0))
    step = max_decode_error(cfg.range_max)
    per_point = np.concatenate([f.xyz_world_decoded for f in frames])
    assert per_point.shape[0] > 50_000
    assert np.abs(per_point[:, 0] - WALL_X).max() <= math.sqrt(3) * step + 1e-9
    # The true hits too, and each frame starts and ends where the trajectory says.
    assert np.abs(np.concatenate([f.xyz_world for f in frames])[:, 0] - WALL_X).max() < 1e-3
    assert frames[3].sensor_pose.origin[0] == pytest.approx(SPEED * 0.3, abs=1e-9)
    assert frames[3].end_pose.origin[0] == pytest.approx(SPEED * 0.4, abs=1e-9)
    # One pose per frame would smear the wall by up to half a metre: this is per point.
    one_pose = np.concatenate([f.sensor_pose.origin + f.xyz_decoded @ f.sensor_pose.rotation.T for f in frames])
    assert np.abs(one_pose[:, 0] - WALL_X).max() > 0.3


def test_a_fixed_pose_trajectory_gives_the_fixed_scan() -> None:
    cfg = load_preset("livox_mid70")
    pose = Pose((0.0, 0.0, -2.0), 0.0, 0.0, 0.2)
    still = builtin_trajectory("hover", 0.0, pose, 0.5)
    moving = list(LidarScanner(cfg, wall(), trajectory=still, seed=1).frames(0.3))
    fixed = list(LidarScanner(cfg, wall(), pose, seed=1).frames(0.3))
    for a, b in zip(moving, fixed, strict=True):
        np.testing.assert_array_equal(a.xyz_int16, b.xyz_int16)
        np.testing.assert_allclose(a.xyz_world_decoded, b.xyz_world_decoded, atol=1e-9)


def test_the_model_is_scipys_natural_spline_normalised() -> None:
    """Position: scipy's natural CubicSpline; orientation: the same spline of the quaternions, normalised."""
    rng = np.random.default_rng(4)
    t = np.cumsum(rng.uniform(0.05, 0.3, 40))
    rotations = Rotation.from_rotvec(np.cumsum(rng.normal(scale=0.4, size=(40, 3)), axis=0))
    trajectory = Trajectory("random", t, rng.normal(size=(40, 3)), rotations.as_quat())
    query = np.sort(rng.uniform(t[0], t[-1], 5000))
    position, quaternion = trajectory.poses_at(query)
    signs = np.cumprod(np.r_[1.0, np.sign(np.einsum("ij,ij->i", rotations.as_quat()[1:], rotations.as_quat()[:-1]))])
    reference = CubicSpline(t, np.hstack([trajectory.position, rotations.as_quat() * signs[:, None]]),
                            bc_type="natural")
    np.testing.assert_allclose(position, reference(query)[:, :3], atol=1e-12)
    p = reference(query)[:, 3:]
    np.testing.assert_allclose(quat_to_matrix(quaternion), Rotation.from_quat(p).as_matrix(), atol=1e-12)
    np.testing.assert_allclose(trajectory.velocity_at(query), reference(query, 1)[:, :3], atol=1e-10)
    np.testing.assert_allclose(trajectory.acceleration_at(query), reference(query, 2)[:, :3], atol=1e-9)
    # Through every pose.
    np.testing.assert_allclose(quat_to_matrix(trajectory.poses_at(t)[1]), rotations.as_matrix(), atol=1e-12)
    # Body angular rate and acceleration against finite differences of the orientation (not of the rate).
    h = 1e-5
    inner = query[(query > t[0] + 2 * h) & (query < t[-1] - 2 * h)]
    rotation = [Rotation.from_quat(trajectory.orientation_at(inner + k * h)) for k in (-1, 0, 1)]
    rate = (rotation[0].inv() * rotation[2]).as_rotvec() / (2 * h)
    np.testing.assert_allclose(trajectory.angular_velocity_at(inner), rate, atol=1e-6)
    rate_before = (rotation[0].inv() * rotation[1]).as_rotvec() / h
    rate_after = (rotation[1].inv() * rotation[2]).as_rotvec() / h
    np.testing.assert_allclose(trajectory.angular_acceleration_at(inner), (rate_after - rate_before) / h, atol=2e-3)
    assert np.abs(trajectory.angular_acceleration_at(inner)).max() > 1.0  # non-trivial turns
    vectors = rng.normal(size=(5000, 3))
    np.testing.assert_allclose(quat_rotate(quaternion, vectors),
                               np.einsum("nij,nj->ni", quat_to_matrix(quaternion), vectors), atol=1e-12)
    for k in (0, 777, 4999):
        pose = trajectory.pose_at(float(query[k]))
        np.testing.assert_allclose(pose.rotation, quat_to_matrix(quaternion[k]), atol=1e-12)
        np.testing.assert_allclose(pose.origin, position[k], atol=1e-12)
    with pytest.raises(LivoxVizError, match="no extrapolation"):
        trajectory.poses_at(np.array([t[-1] + 0.5]))


def test_per_ray_poses_are_the_model_with_the_mount() -> None:
    """The compiled per-ray kernel against scipy: origin o + R m, direction R R_m d, sorted or not."""
    from livox_viz.motion.track import SensorTrack

    rng = np.random.default_rng(8)
    t = np.arange(0.0, 9.0, 1.5)
    rotations = Rotation.from_euler("ZYX", np.column_stack([np.radians(80) * np.arange(t.size),
                                                            0.2 * np.sin(t), 0.1 * np.cos(t)]))
    trajectory = Trajectory("turns", t, rng.normal(scale=5.0, size=(t.size, 3)), rotations.as_quat())
    mount = Pose((0.3, -0.2, -0.4), 0.2, -0.3, 0.5)
    track = SensorTrack(trajectory, mount)
    query = np.sort(rng.uniform(t[0], t[-1], 20000))
    directions = rng.normal(size=(query.size, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    origin, world = track.rays(query, directions)
    signs = np.cumprod(np.r_[1.0, np.sign(np.einsum("ij,ij->i", rotations.as_quat()[1:], rotations.as_quat()[:-1]))])
    reference = CubicSpline(t, np.hstack([trajectory.position, rotations.as_quat() * signs[:, None]]),
                            bc_type="natural")(query)
    body = Rotation.from_quat(reference[:, 3:])
    mount_rotation = Rotation.from_euler("ZYX", [0.5, -0.3, 0.2])
    np.testing.assert_allclose(origin, reference[:, :3] + body.apply([0.3, -0.2, -0.4]), atol=1e-12)
    np.testing.assert_allclose(world, (body * mount_rotation).apply(directions), atol=1e-12)
    shuffled = rng.permutation(query.size)
    again = track.rays(query[shuffled], directions[shuffled])
    np.testing.assert_allclose(again[0], origin[shuffled], atol=1e-12)
    np.testing.assert_allclose(again[1], world[shuffled], atol=1e-12)
    position, quaternion = track.poses_at(query[:100])
    np.testing.assert_allclose(position, origin[:100], atol=1e-12)
    np.testing.assert_allclose(Rotation.from_quat(quaternion).as_matrix(), (body * mount_rotation)[:100].as_matrix(),
                               atol=1e-12)


def test_tum_round_trip_and_errors(tmp_path: Path) -> None:
    trajectory = builtin_trajectory("figure8", 4.0, Pose((1.0, 2.0, -3.0), 0.0, 0.0, 0.5), 2.0)
    path = tmp_path / "flight.txt"
    save_tum(trajectory, path)
    loaded = load_tum(path)
    np.testing.assert_allclose(loaded.position, trajectory.position, atol=1e-8)
    np.testing.assert_allclose(loaded.quaternion, trajectory.quaternion, atol=1e-8)
    for text, message in [("0 0 0 0 0 0 0 1\n", "at least 2"), ("# c\n0 0 0 0 0 0 0 1\n1 0 0\n", "line 3 has 3"),
                          ("0 0 0 0 0 0 0 1\n0 1 0 0 0 0 0 1\n", "time goes back"),
                          ("0 0 0 0 0 0 0 1\n1 0 0 0 0 0 0 0\n", "unit quaternion"),
                          ("0 0 0 0 0 0 0 1\n1 x 0 0 0 0 0 1\n", "line 2: 'x' is not a number"),
                          ("0 0 0 0 0 0 0 1\n1 0 0 0 0 0 1 0\n", "turns 180 degrees between poses 1 and 2"),
                          ("0 0 0 0 0 0 0 1\n1 0 0 0 0 0 0 1\n" + "x" * 1200 + "\n", "line 3 is longer than 1000")]:
        path.write_text(text)
        with pytest.raises(LivoxVizError, match=message):
            load_tum(path)


@pytest.mark.parametrize("column", ["t", "position", "quaternion"])
@pytest.mark.parametrize("bad", [math.nan, math.inf])
def test_a_trajectory_with_one_non_finite_value_anywhere_is_refused(column: str, bad: float) -> None:
    """One NaN or infinity in the times, the positions or the quaternions alone is refused by name, the other two
    being finite: none of the later checks would see it (NaN compares false, so neither the time order nor the
    quaternion length test catches it) and the spline would carry it into every pose."""
    values = {"t": np.array([0.0, 1.0, 2.0]), "position": np.zeros((3, 3)),
              "quaternion": np.tile([0.0, 0.0, 0.0, 1.0], (3, 1))}
    values[column].flat[4 if column != "t" else 1] = bad
    with pytest.raises(LivoxVizError, match="NaN or infinite values; allowed: finite numbers"):
        Trajectory("bad", values["t"], values["position"], values["quaternion"])


def sharp_turns(seconds: float = 12.0, spacing: float = 2.0) -> Trajectory:
    """A hand-written TUM flight: poses ``spacing`` s apart round a 10 m square, a 90-degree turn at each, rolling
    and pitching a little (sparse and sharp: the case that showed the rays and /odom apart)."""
    t = np.arange(0.0, seconds + spacing / 2, spacing)
    corners = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]])
    position = np.column_stack([corners[np.arange(t.size) % 4], -3.0 - 0.5 * np.sin(t)])
    angles = np.column_stack([np.radians(90.0) * np.arange(t.size), 0.15 * np.sin(1.3 * t), 0.1 * np.cos(0.7 * t)])
    return Trajectory("sharp turns", t, position, Rotation.from_euler("ZYX", angles).as_quat())


def test_the_imu_integrates_back_to_the_waypoints() -> None:
    """Gyro and accelerometer integrated from the first pose reach every later waypoint the user wrote."""
    trajectory = sharp_turns()
    rate = 1000.0
    imu = synthesize_imu(trajectory, rate)
    assert imu.t.size == 12001
    dt = 1.0 / rate
    attitude = Rotation.from_quat(trajectory.quaternion[0])
    gravity = np.array([0.0, 0.0, GRAVITY])
    position = trajectory.position[0].copy()
    velocity = trajectory.velocity_at(0.0)[0]  # the one state the poses do not give
    worst_angle = worst_position = 0.0
    steps_per_pose = round(2.0 * rate)
    for k in range(imu.t.size - 1):
        before = attitude
        attitude = attitude * Rotation.from_rotvec(0.5 * (imu.angular_velocity[k] + imu.angular_velocity[k + 1]) * dt)
        a0 = before.apply(imu.specific_force[k]) + gravity
        a1 = attitude.apply(imu.specific_force[k + 1]) + gravity
        position = position + velocity * dt + (2 * a0 + a1) / 6 * dt**2
        velocity = velocity + 0.5 * (a0 + a1) * dt
        if (k + 1) % steps_per_pose == 0:
            pose = (k + 1) // steps_per_pose
            truth = Rotation.from_quat(trajectory.quaternion[pose])
            worst_angle = max(worst_angle, float((truth.inv() * attitude).magnitude()))
            worst_position = max(worst_position, float(np.linalg.norm(position - trajectory.position[pose])))
    # Stated tolerance over 12 s of 90-degree turns, integrated at 1 kHz: 0.1 mrad and 1 cm.
    assert worst_angle < 1e-4 and worst_position < 0.01
    # No step anywhere (the windows and waypoints of before): sample to sample, 1 ms apart.
    assert np.abs(np.diff(imu.specific_force, axis=0)).max() < 0.05
    assert np.abs(np.diff(imu.angular_velocity, axis=0)).max() < 0.01
    assert np.abs(imu.angular_velocity).max() > 0.5  # it does turn


def test_builtin_flights_start_and_end_at_rest_with_a_smooth_ramp() -> None:
    start = Pose((1.0, 2.0, -5.0), 0.05, -0.04, 0.7)
    seconds = 8.0
    for name in ("line", "circle", "figure8"):
        flight = builtin_trajectory(name, 6.0, start, seconds)
        # From the 100 Hz samples themselves (not the spline): speed by finite differences.
        speed = np.linalg.norm(np.diff(flight.position, axis=0), axis=1) / np.diff(flight.t)
        assert speed[0] < 1e-3 and speed[-1] < 1e-3, name
        assert speed.max() == pytest.approx(6.0, rel=0.02), name
        accel = np.diff(speed) / np.diff(flight.t)[1:]
        assert np.abs(np.diff(accel)).max() < 0.2, name  # no step in the acceleration
        # The IMU at both ends reads a vehicle at rest: gravity in the tilted body, no rotation.
        imu = synthesize_imu(flight, 200.0, start=0.0, stop=seconds)
        at_rest = Rotation.from_euler("ZYX", [0.0, start.pitch, start.roll]).inv().apply([0.0, 0.0, -GRAVITY])
        for row in (0, -1):
            np.testing.assert_allclose(imu.angular_velocity[row], 0.0, atol=1e-3)
            if name != "circle" or row == 0:  # the circle ends turned, gravity still down in the world
                np.testing.assert_allclose(np.linalg.norm(imu.specific_force[row]), GRAVITY, atol=1e-3)
        np.testing.assert_allclose(imu.specific_force[0], at_rest, atol=1e-3)
    hover = builtin_trajectory("hover", 5.0, start, 2.0)
    assert not hover.moves and builtin_trajectory("line", 5.0, start, 2.0).moves


def test_imu_at_rest_reads_gravity_and_noise_is_seeded_and_bounded() -> None:
    level = builtin_trajectory("hover", 0.0, Pose((0.0, 0.0, -1.0)), 2.0)
    imu = synthesize_imu(level, 200.0)
    np.testing.assert_allclose(imu.specific_force, np.tile([0.0, 0.0, -GRAVITY], (imu.t.size, 1)), atol=1e-9)
    np.testing.assert_allclose(imu.angular_velocity, 0.0, atol=1e-12)
    noise = ImuNoise(1.7e-4, 2e-5, 2e-3, 3e-3)
    a, b = synthesize_imu(level, 200.0, noise, seed=3), synthesize_imu(level, 200.0, noise, seed=3)
    np.testing.assert_array_equal(a.angular_velocity, b.angular_velocity)
    # White noise of density 1.7e-4 rad/s/sqrt(Hz) at 200 Hz: 2.4e-3 rad/s per sample.
    assert np.std(np.diff(a.angular_velocity[:, 0])) / math.sqrt(2) == pytest.approx(1.7e-4 * math.sqrt(200), rel=0.1)
    # A stream a stretch at a time: the same times, the bias carried on (a continuous walk).
    stream = ImuStream(level, 200.0, ImuNoise(0.0, 0.0, 0.0, 0.5), seed=1)
    parts = [stream.until(0.1 * k) for k in range(1, 11)] + [stream.until(1.0, inclusive=True)]
    times = np.concatenate([p.t for p in parts])
    np.testing.assert_allclose(times, np.arange(201) / 200.0, atol=1e-12)
    force = np.concatenate([p.specific_force for p in parts])
    assert np.abs(np.diff(force, axis=0)).max() < 6 * 0.5 * math.sqrt(1 / 200)  # steps of the walk only
    with pytest.raises(LivoxVizError, match="allowed: 200 to 10000"):
        synthesize_imu(level, 50.0)
    for values in ([1e308, 0, 0, 0], [0, 0, 0, 11.0], [0, math.inf, 0, 0], [0, 0, -1e-3, 0]):
        with pytest.raises(LivoxVizError, match="allowed: 0 to"):
            ImuNoise(*values)


def test_the_imu_in_the_lidar_frame_is_the_lidars_own_motion() -> None:
    """With the mount: the rate and specific force of the lidar's origin, from finite differences of its track."""
    from livox_viz.motion.imu import imu_readings
    from livox_viz.motion.track import SensorTrack

    trajectory = sharp_turns()
    mount = Pose((0.4, -0.3, -0.5), 0.3, -0.2, 0.6)
    track = SensorTrack(trajectory, mount)
    t = np.linspace(1.0, 11.0, 400)
    omega, force = imu_readings(trajectory, t, mount)
    h = 1e-4
    origin = [track.poses_at(t + k * h)[0] for k in (-1, 0, 1)]
    rotation = [Rotation.from_quat(track.poses_at(t + k * h)[1]) for k in (-1, 0, 1)]
    acceleration = (origin[0] - 2 * origin[1] + origin[2]) / h**2
    expected_force = rotation[1].inv().apply(acceleration - [0.0, 0.0, GRAVITY])
    np.testing.assert_allclose(force, expected_force, atol=2e-4)
    np.testing.assert_allclose(omega, (rotation[0].inv() * rotation[2]).as_rotvec() / (2 * h), atol=1e-6)
    body_force = imu_readings(trajectory, t)[1]
    assert np.abs(force - body_force @ mount.rotation).max() > 0.05  # the lever arm matters here


def test_publish_sends_each_frames_own_pose(tmp_path: Path) -> None:
    from livox_viz.cli import main

    from .conftest import free_udp_port, start_listening

    port = free_udp_port()
    received = tmp_path / "received.npz"
    listener = start_listening(["--host", "127.0.0.1", "--port", str(port), "--frames", "5", "--timeout", "20",
                                "--record", str(received)])
    assert main(["publish", "--to", f"127.0.0.1:{port}", "--seconds", "0.5", "--unpaced", "--trajectory", "line",
                 "--trajectory-speed", "10", "--pose=0,0,-2,0,0,0"]) == 0
    listener.join(30)
    poses = np.load(received)["frame_pose"]
    # posAng (float32 on the wire): the sensor's pose at each frame's first ray, on the line flight from rest
    # (the sensor 0.3 m above the body).
    flight = builtin_trajectory("line", 10.0, Pose((0.0, 0.0, -2.0)), 0.5)
    expected = np.array([flight.pose_at(0.1 * k).origin for k in range(5)]) + np.array([0.0, 0.0, -0.3])
    np.testing.assert_allclose(poses[:, 1:4], expected, atol=1e-5)
    assert np.all(np.diff(poses[:, 1]) > 0.05)  # each frame its own pose


@pytest.mark.parametrize("sign", [-1.0, 1.0])
def test_a_pose_looking_straight_up_or_down_survives_rounding(sign: float) -> None:
    """A quaternion for pitch +-90 deg whose sine rounds past +-1 (2 sqrt(0.5)^2 = 1.0000000000000002): the
    pose is made, with that pitch, instead of a math domain error."""
    from livox_viz.core.poses import pose_from_quaternion

    half = math.sqrt(0.5)
    pose = pose_from_quaternion(np.zeros(3), np.array([0.0, sign * half, 0.0, half]))
    assert pose.pitch == pytest.approx(sign * math.pi / 2)
    np.testing.assert_allclose(pose.rotation @ [1.0, 0.0, 0.0], [0.0, 0.0, -sign], atol=1e-7)


def test_the_built_in_circle_and_figure8_have_the_sizes_the_readme_gives() -> None:
    """README: `circle` (15 m) and `figure8` (32 m): the circle's points lie 15 m from one centre, the figure-8
    spans 32 m along its axis and 11.3 m across."""
    from livox_viz.core.poses import Pose
    from livox_viz.motion.flights import builtin_trajectory

    circle = builtin_trajectory("circle", 6.0, Pose((4.0, -3.0, -10.0), 0.0, 0.0, 0.5), 40.0).position_at(
        np.linspace(0.0, 40.0, 4001))[:, :2]
    # The centre from three points far apart on it (circumcentre), then every point's distance to it.
    a, b, c = circle[0], circle[len(circle) // 3], circle[2 * len(circle) // 3]
    d = 2 * (a[0] * (b[1] - c[1]) + b[0] * (c[1] - a[1]) + c[0] * (a[1] - b[1]))
    centre = np.array([
        (a @ a * (b[1] - c[1]) + b @ b * (c[1] - a[1]) + c @ c * (a[1] - b[1])) / d,
        (a @ a * (c[0] - b[0]) + b @ b * (a[0] - c[0]) + c @ c * (b[0] - a[0])) / d])
    np.testing.assert_allclose(np.linalg.norm(circle - centre, axis=1), 15.0, atol=1e-3)
    eight = builtin_trajectory("figure8", 6.0, Pose((0.0, 0.0, -10.0)), 60.0).position_at(np.linspace(0, 60, 6001))
    assert np.ptp(eight[:, 0]) == pytest.approx(32.0, abs=0.05)
    assert np.ptp(eight[:, 1]) == pytest.approx(32.0 / 2 / math.sqrt(2), abs=0.05)


@pytest.mark.parametrize("speed", [5.0, 2.0, 12.0])
def test_the_built_in_flights_turn_as_a_real_drone_does(speed: float) -> None:
    """At the default 5 m/s no built-in flight yaws faster than 1 rad/s (Gerono's 20 m figure-8 turned at
    2.4 rad/s: 13.7 degrees a frame, which no lidar odometry follows); the peak rates --help states are the
    flights' own, measured on the motion model (the spline's angular rate), and scale with the speed."""
    from livox_viz.motion.flights import peak_yaw_rate

    t = np.linspace(0.0, 60.0, 30001)
    for name in ("line", "circle", "figure8"):
        flight = builtin_trajectory(name, speed, Pose((0.0, 0.0, -10.0), 0.0, 0.0, 0.3), 60.0)
        peak = float(np.abs(flight.angular_velocity_at(t)).max())
        assert peak == pytest.approx(peak_yaw_rate(name, speed), rel=1e-3, abs=1e-6), name
        if speed <= 5.0:
            assert peak <= 1.0, name


@pytest.mark.parametrize("scene_name", ["urban", "open_field", "dense_terrain"])
def test_the_built_in_flights_stay_clear_of_the_built_in_scenes(scene_name: str) -> None:
    """Every built-in flight from a built-in scene's start pose keeps 10 cm off every surface and never flies under
    a roof (inside a building): the right-turning circle once crossed the urban house (5 % return-0 points), and
    the figure-8 grazed the crate by 7 cm."""
    from livox_viz.scene.raycast import TrimeshCaster
    from livox_viz.scene.scenes import open_scene

    scene = open_scene(scene_name)
    caster = TrimeshCaster(scene.mesh)
    for name in ("line", "circle", "figure8"):
        flight = builtin_trajectory(name, 5.0, scene.vehicle_pose, 60.0)
        path = np.asarray(flight.position)[::25]
        clearance = trimesh.proximity.closest_point(scene.mesh, path)[1]
        assert clearance.min() > 0.1, (name, path[np.argmin(clearance)])
        overhead = caster.distances(path, np.tile([0.0, 0.0, -1.0], (len(path), 1)), 1000.0)  # NED up
        assert not np.isfinite(overhead).any(), (name, path[np.isfinite(overhead)][:3])
