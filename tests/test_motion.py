"""A moving sensor: trajectories, per-point poses, the IMU."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation, Slerp

from livox_viz import LivoxVizError, load_preset
from livox_viz.casting.codec import max_decode_error
from livox_viz.casting.scan import LidarScanner
from livox_viz.core.poses import Pose
from livox_viz.core.rotations import quat_rotate, quat_to_matrix
from livox_viz.motion.flights import builtin_trajectory
from livox_viz.motion.imu import GRAVITY, ImuNoise, TrajectoryMotion, synthesize_imu
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


def test_interpolation_is_linear_and_slerp() -> None:
    rng = np.random.default_rng(4)
    t = np.cumsum(rng.uniform(0.05, 0.3, 40))
    rotations = Rotation.random(40, random_state=5)
    trajectory = Trajectory("random", t, rng.normal(size=(40, 3)), rotations.as_quat())
    query = np.sort(rng.uniform(t[0], t[-1], 5000))
    position, quaternion = trajectory.poses_at(query)
    np.testing.assert_allclose(quat_to_matrix(quaternion), Slerp(t, rotations)(query).as_matrix(), atol=1e-12)
    expected = np.column_stack([np.interp(query, t, trajectory.position[:, k]) for k in range(3)])
    np.testing.assert_allclose(position, expected, atol=1e-12)
    vectors = rng.normal(size=(5000, 3))
    np.testing.assert_allclose(quat_rotate(quaternion, vectors),
                               np.einsum("nij,nj->ni", quat_to_matrix(quaternion), vectors), atol=1e-12)
    for k in (0, 777, 4999):
        pose = trajectory.pose_at(float(query[k]))
        np.testing.assert_allclose(pose.rotation, quat_to_matrix(quaternion[k]), atol=1e-12)
        np.testing.assert_allclose(pose.origin, position[k], atol=1e-12)
    with pytest.raises(LivoxVizError, match="no extrapolation"):
        trajectory.poses_at(np.array([t[-1] + 0.5]))


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
                          ("0 0 0 0 0 0 0 1\n1 x 0 0 0 0 0 1\n", "line 2 is not numeric")]:
        path.write_text(text)
        with pytest.raises(LivoxVizError, match=message):
            load_tum(path)


def test_the_imu_integrates_back_to_the_trajectory() -> None:
    trajectory = builtin_trajectory("figure8", 5.0, Pose((0.0, 0.0, -10.0), 0.05, -0.03, 0.4), 10.0)
    rate = 400.0
    imu = synthesize_imu(trajectory, rate)
    assert imu.t.size == 4001
    motion = TrajectoryMotion(trajectory)
    dt = 1.0 / rate
    # Gyro to attitude: compose each step's rotation (midpoint of the two rates).
    attitude = motion.rotation(imu.t[:1])
    gravity = np.array([0.0, 0.0, GRAVITY])
    velocity = motion.velocity(imu.t[:1])[0]
    worst_angle = worst_speed = 0.0
    for k in range(imu.t.size - 1):
        step = Rotation.from_rotvec(0.5 * (imu.angular_velocity[k] + imu.angular_velocity[k + 1]) * dt)
        before = attitude
        attitude = attitude * step
        # Specific force plus gravity to velocity (trapezoid, each sample turned into the world).
        a0 = before.apply(imu.specific_force[k])[0] + gravity
        a1 = attitude.apply(imu.specific_force[k + 1])[0] + gravity
        velocity = velocity + 0.5 * (a0 + a1) * dt
        if k % 40 == 39:
            truth = motion.rotation(imu.t[k + 1 : k + 2])
            worst_angle = max(worst_angle, float((truth.inv() * attitude).magnitude()[0]))
            worst_speed = max(worst_speed, float(np.linalg.norm(velocity - motion.velocity(imu.t[k + 1 : k + 2])[0])))
    # Stated tolerance over 10 s of a figure-8 at 5 m/s: 1 mrad of attitude, 2 cm/s of velocity.
    assert worst_angle < 1e-3 and worst_speed < 0.02
    assert worst_speed > 0 and worst_angle > 0


def test_imu_at_rest_reads_gravity_and_noise_is_seeded() -> None:
    level = builtin_trajectory("hover", 0.0, Pose((0.0, 0.0, -1.0)), 2.0)
    imu = synthesize_imu(level, 200.0)
    np.testing.assert_allclose(imu.specific_force, np.tile([0.0, 0.0, -GRAVITY], (imu.t.size, 1)), atol=1e-9)
    np.testing.assert_allclose(imu.angular_velocity, 0.0, atol=1e-12)
    noise = ImuNoise(1.7e-4, 2e-5, 2e-3, 3e-3)
    a, b = synthesize_imu(level, 200.0, noise, seed=3), synthesize_imu(level, 200.0, noise, seed=3)
    np.testing.assert_array_equal(a.angular_velocity, b.angular_velocity)
    # White noise of density 1.7e-4 rad/s/sqrt(Hz) at 200 Hz: 2.4e-3 rad/s per sample.
    assert np.std(np.diff(a.angular_velocity[:, 0])) / math.sqrt(2) == pytest.approx(1.7e-4 * math.sqrt(200), rel=0.1)
    with pytest.raises(LivoxVizError, match="allowed: 200 to 10000"):
        synthesize_imu(level, 50.0)


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
    # posAng (float32 on the wire) moves 1 m north per 0.1 s frame: the pose at each frame's first ray.
    np.testing.assert_allclose(poses[:, 1], np.arange(5) * 1.0, atol=1e-5)
    np.testing.assert_allclose(poses[:, 3], -2.3, atol=1e-5)  # the sensor 0.3 m above the body
