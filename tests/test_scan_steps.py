"""The scan's steps around the cast, where a mutation trial found them untested; each test is held to a computation
of its own.

The recycled blocks' slack and the 8-byte layout of :func:`carve`, given times on a fixed sensor's ideal path (cast
alone and joined with a chunk without them), the float64 world points of the ideal path (from the float64 rays,
exact caster or not), the datasheet model cast in parts, and libm's rays beyond the series' reach.
"""

from __future__ import annotations

import gc
from dataclasses import replace

import numpy as np
import pytest
import trimesh

from livox_viz import SensorConfig
from livox_viz.casting import scan
from livox_viz.casting.ray_kernels import sensor_rays
from livox_viz.casting.scan import MountedCaster
from livox_viz.core.buffers import RecycledBlocks, carve, carved_size
from livox_viz.core.poses import Pose
from livox_viz.core.rotations import euler_matrix
from livox_viz.patterns.factory import make_pattern
from livox_viz.patterns.planes import directions_from_xy
from livox_viz.patterns.stream import PatternChunk
from livox_viz.scene.raycast import EmbreeCaster
from livox_viz.scene.scenes import open_scene


def _address(values: np.ndarray) -> int:
    return values.__array_interface__["data"][0]


# Recycled blocks ----------------------------------------------------------------------------------
def test_carve_starts_every_array_on_an_8_byte_boundary_after_odd_sized_ones() -> None:
    # 6, 40, 3 and 8 bytes: each rounded up to a multiple of 8 -> 8 + 40 + 8 + 8.
    layout = [("a", (3,), np.int16), ("b", (5,), np.float64), ("c", (3,), np.int8), ("d", (2,), np.int32)]
    assert carved_size(layout) == 64
    block = np.zeros(64, dtype=np.uint8)
    arrays = carve(block, layout)
    assert [_address(arrays[name]) - _address(block) for name in "abcd"] == [0, 8, 48, 56]
    assert {name: values.shape for name, values in arrays.items()} == {"a": (3,), "b": (5,), "c": (3,), "d": (2,)}
    arrays["a"][:] = -1
    arrays["b"][:] = 2.5
    arrays["c"][:] = 7
    arrays["d"][:] = 123_456
    # No array overlaps another: each keeps what was written to it.
    assert arrays["a"].tolist() == [-1] * 3 and arrays["b"].tolist() == [2.5] * 5
    assert arrays["c"].tolist() == [7] * 3 and arrays["d"].tolist() == [123_456] * 2


def test_a_free_block_is_reused_only_within_the_slack() -> None:
    blocks = RecycledBlocks(keep=4, slack=1.25)
    large = blocks.get(1000)
    address = _address(large)
    del large
    gc.collect()
    # Free, but more than 1.25 times the request: the small request gets a block of its own.
    small = blocks.get(100)
    assert small.base.shape[0] == 100 and _address(small) != address
    del small
    too_small = blocks.get(799)  # 799 * 1.25 < 1000
    assert too_small.base.shape[0] == 799 and _address(too_small) != address
    del too_small
    gc.collect()
    within = blocks.get(800)  # 800 * 1.25 == 1000: the free block, its head
    assert within.shape == (800,) and within.base.shape[0] == 1000 and _address(within) == address


# The boresight rays beyond the series' reach ------------------------------------------------------
@pytest.mark.parametrize("compiled", [False, True])
def test_rays_beyond_one_radian_are_libms_bit_for_bit(compiled: bool) -> None:
    """Beyond 1 rad off the boresight the series are not used: each ray is libm's ``cos(a)``, ``sin(a)/a``."""
    rng = np.random.default_rng(8)
    off = rng.uniform(np.radians(57.5), np.radians(80.0), 5000)
    turn = rng.uniform(-np.pi, np.pi, 5000)
    xy = np.degrees(np.column_stack([off * np.cos(turn), off * np.sin(turn)]))
    x, y = (xy * (np.pi / 180.0)).T
    alpha = np.sqrt(x * x + y * y)
    assert alpha.min() > 1.0
    ratio = np.sin(alpha) / alpha
    expected = np.column_stack([np.cos(alpha), ratio * x, -(ratio * y)])
    found = sensor_rays(xy, "boresight")[0] if compiled else directions_from_xy(xy)
    np.testing.assert_array_equal(found, expected)


# Given times on a fixed sensor -------------------------------------------------------------------
def _inside_a_box(config: SensorConfig) -> MountedCaster:
    """A fixed sensor at the centre of a 60 m box: every ray hits a wall within 52 m."""
    config = replace(config, sensor_pos_xyz=(0.0, 0.0, 0.0), sensor_ang_euler=(0.0, 0.0, 0.0))
    return MountedCaster(config, EmbreeCaster(trimesh.creation.box((60.0, 60.0, 60.0))), Pose())


def test_given_times_are_the_points_times_on_a_fixed_sensor(mid70: SensorConfig) -> None:
    mounted = _inside_a_box(mid70)
    pattern = make_pattern(mounted.config, seed=5)
    pattern.skip(1000)
    first, second = pattern.take(3000), pattern.take(2000)
    given = 7.0 + np.arange(3000) * 3e-6  # not k / rate
    timed = PatternChunk(mounted.config, first.start, first.xy_deg, given)
    alone = mounted.cast(timed)
    assert len(alone) == 3000
    np.testing.assert_array_equal(alone.t, given[alone.stream_index - 1000])
    # Joined with a chunk that holds no times: the given ones, then the stream's own k / rate.
    joined = mounted.cast_frames([timed, second])
    assert [len(frame) for frame in joined] == [3000, 2000]
    np.testing.assert_array_equal(joined[0].t, given[joined[0].stream_index - 1000])
    np.testing.assert_array_equal(joined[1].stream_index, np.arange(4000, 6000))
    np.testing.assert_array_equal(joined[1].t, np.arange(4000, 6000) / mounted.config.point_rate)


# World points of the ideal path ------------------------------------------------------------------
@pytest.mark.parametrize("exact", [False, True])
def test_ideal_world_points_are_the_sensor_points_turned_and_moved(mid70: SensorConfig, exact: bool) -> None:
    """Embree casts float32 rays; the points are still made from the float64 ones (``xyz_world = R xyz_sensor +
    origin`` to float64 rounding), and an exact caster measures along the float64 rays (the points on the wall's
    plane to float64 rounding)."""
    config = replace(mid70, sensor_pos_xyz=(0.0, 0.0, 0.0), sensor_ang_euler=(0.0, 0.0, 0.0))
    pose = Pose((3.0, -2.0, -1.5), 0.05, -0.08, 0.3)
    wall = trimesh.creation.box((0.5, 2000.0, 2000.0), trimesh.transformations.translation_matrix((400.25, 0, 0)))
    mounted = MountedCaster(config, EmbreeCaster(wall, exact=exact), pose)
    frame = mounted.cast(make_pattern(config, seed=6).take(20_000))
    assert len(frame) > 19_000
    rotation = euler_matrix(0.05, -0.08, 0.3)
    np.testing.assert_allclose(frame.xyz_world, frame.xyz_sensor @ rotation.T + np.array([3.0, -2.0, -1.5]),
                               rtol=0, atol=1e-9)
    if exact:
        np.testing.assert_allclose(frame.xyz_world[:, 0], 400.0, rtol=0, atol=1e-9)


# The datasheet model cast in parts ---------------------------------------------------------------
def test_a_datasheet_frame_cast_in_parts_keeps_each_points_ray(monkeypatch: pytest.MonkeyPatch,
                                                                mid70: SensorConfig) -> None:
    """Each point of a frame cast in parts (the return model's path) is the point of its own ray: its stream
    index names the ray its pattern angles and time are those of."""
    config = mid70.with_returns_model("datasheet")
    urban = open_scene("urban")
    chunk = make_pattern(config, seed=4).take(10_000)
    monkeypatch.setattr(scan, "CAST_PART", 999)  # ten full parts and a short one
    frame = MountedCaster(config, EmbreeCaster(urban.mesh), urban.vehicle_pose, seed=4).cast(chunk)
    rows = frame.stream_index - chunk.start
    assert len(frame) > 5_000 and rows.min() >= 0 and rows.max() >= 9_000 and rows.max() < 10_000
    assert np.all(np.diff(frame.stream_index) >= 0)  # in stream order, a pulse's returns together
    np.testing.assert_array_equal(frame.xy_deg, chunk.xy_deg[rows])
    np.testing.assert_array_equal(frame.t, frame.stream_index / config.point_rate)
