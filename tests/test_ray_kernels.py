"""The scan's compiled per-ray steps against the numpy steps they replace, and the recycled blocks they fill."""

from __future__ import annotations

import gc

import numpy as np
import pytest

from livox_viz.casting.codec import encode_int16
from livox_viz.casting.ray_kernels import ideal_points, sensor_rays
from livox_viz.core.buffers import RecycledBlocks, carve, carved_size
from livox_viz.core.rotations import euler_matrix, rotate_rows
from livox_viz.patterns.planes import directions_from_xy
from tests.forking import child_exit_code


def _pattern_samples(count: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    xy = rng.uniform(-89.0, 89.0, (count, 2))
    # boresight, far off it; then along +-y and +-z (boresight plane), to be clipped on every axis both ways
    xy[:9] = [[0.0, 0.0], [1e-300, 0.0], [0.0, -1e-12], [179.9, 0.0], [-120.0, 150.0],
              [90.0, 0.0], [-90.0, 0.0], [0.0, 90.0], [0.0, -89.0]]
    return xy


@pytest.mark.parametrize("plane", ["boresight", "panorama"])
def test_sensor_rays_are_the_numpy_rays_bit_for_bit(plane: str) -> None:
    xy = _pattern_samples(5000, 1)
    rotation = euler_matrix(*np.radians([17.0, -31.0, 73.0]))  # no axis is left alone: R and R.T differ
    sensor, world = sensor_rays(xy, plane, rotation)
    expected = directions_from_xy(xy, plane)
    np.testing.assert_array_equal(sensor, expected)
    np.testing.assert_array_equal(world, rotate_rows(expected, rotation))
    # Independent of both: the rays are unit vectors, and turned by R (not its transpose).
    np.testing.assert_allclose(np.linalg.norm(sensor, axis=1), 1.0, atol=1e-15)
    np.testing.assert_allclose(world, expected @ rotation.T, atol=1e-15)
    alone, none = sensor_rays(xy, plane)
    assert none is None
    np.testing.assert_array_equal(alone, expected)
    _, world32 = sensor_rays(xy, plane, rotation, world_dtype=np.float32)
    assert world32.dtype == np.float32
    np.testing.assert_array_equal(world32, world.astype(np.float32))


def test_sensor_rays_in_scratch_are_the_same_and_reused_by_the_next_call() -> None:
    xy = _pattern_samples(3000, 2)
    rotation = euler_matrix(*np.radians([5.0, 10.0, -40.0]))
    fresh = sensor_rays(xy, "boresight", rotation)
    first = sensor_rays(xy, "boresight", rotation, scratch=True)
    np.testing.assert_array_equal(first[0], fresh[0])
    np.testing.assert_array_equal(first[1], fresh[1])
    second = sensor_rays(xy[:1000] * 0.5, "boresight", rotation, scratch=True)
    assert np.shares_memory(first[0], second[0])  # the caller was told: the next call overwrites them
    np.testing.assert_array_equal(second[0], directions_from_xy(xy[:1000] * 0.5))


def test_sensor_rays_refuse_an_unknown_plane() -> None:
    with pytest.raises(ValueError, match="boresight"):
        sensor_rays(np.zeros((2, 2)), "cylinder")


def _numpy_ideal_points(distance, sensor, world, origins, xy, t, first, range_max):
    """The steps ideal_points replaced, in numpy: hits, points, int16, the (0, 0, 0) points dropped."""
    hit = np.flatnonzero(np.isfinite(distance))
    range_m = distance[hit]
    xyz_sensor = sensor[hit] * range_m[:, None]
    start = origins[0] if origins.shape[0] == 1 else origins[hit]
    xyz_world = world[hit] * range_m[:, None] + start
    xyz_int16 = encode_int16(xyz_sensor, range_max)
    keep = np.any(xyz_int16 != 0, axis=1)
    return {"stream_index": first + hit[keep], "t": t[hit][keep], "xy_deg": xy[hit][keep], "range_m": range_m[keep],
            "xyz_sensor": xyz_sensor[keep], "xyz_world": xyz_world[keep], "xyz_int16": xyz_int16[keep]}


@pytest.mark.parametrize("per_ray_origins", [False, True])
def test_ideal_points_are_the_numpy_steps(per_ray_origins: bool) -> None:
    rng = np.random.default_rng(3)
    count, first, rate, range_max = 4000, 123_456, 100_000.0, 40.0
    xy = _pattern_samples(count, 4)
    rotation = euler_matrix(*np.radians([-60.0, 20.0, 110.0]))
    sensor, world = sensor_rays(xy, "boresight", rotation)
    distance = rng.uniform(0.0, 39.0, count)
    distance[rng.random(count) < 0.3] = np.inf
    distance[:9] = [np.nan, 1e-4, 0.0] + [range_max * 2] * 6  # no hit; two points at (0,0,0) in int16; clipped
    origins = rng.normal(size=(count if per_ray_origins else 1, 3)) * 100.0
    t = (first + np.arange(count)) / rate
    expected = _numpy_ideal_points(distance, sensor, world, origins, xy, t, first, range_max)
    assert 0 < expected["range_m"].size < count - 1000
    assert 1e-4 not in expected["range_m"] and 0.0 not in expected["range_m"]
    clipped = np.abs(expected["xyz_int16"][:6]) == 32767
    assert clipped[:, 1:].any(axis=0).all() and {-32767, 32767} <= set(expected["xyz_int16"][:6].ravel().tolist())
    for given_world, given_t in ((world, t), (None, None), (world, None)):
        found = ideal_points(distance, sensor, given_world, origins, xy, given_t, first, rate, range_max, rotation)
        assert set(found) == set(expected)
        for name, values in expected.items():
            np.testing.assert_array_equal(found[name], values, err_msg=name)
            assert found[name].dtype == values.dtype, name


def test_ideal_points_of_no_hit_are_empty() -> None:
    sensor, world = sensor_rays(np.zeros((3, 2)), "boresight", np.eye(3))
    found = ideal_points(np.full(3, np.inf), sensor, world, np.zeros((1, 3)), np.zeros((3, 2)), None, 0, 10.0, 5.0)
    assert all(values.shape[0] == 0 for values in found.values())
    assert found["xyz_int16"].shape == (0, 3)


def test_a_recycled_block_is_never_handed_out_while_an_array_of_it_is_held() -> None:
    blocks = RecycledBlocks(keep=4)
    layout = [("a", (100,), np.int64), ("b", (100, 3), np.int16), ("c", (7,), np.float64)]
    size = carved_size(layout)
    assert size == 800 + 600 + 56
    held = carve(blocks.get(size), layout)
    held["a"][:] = 7
    held["b"][:] = -3
    views = held["a"][10:20]  # a view of a view still holds the block
    del held
    gc.collect()
    other = carve(blocks.get(size), layout)
    other["a"][:] = 1
    assert (views == 7).all()
    assert not np.shares_memory(views, other["a"])
    # Once nothing holds it, the block is handed out again: the same memory, no fresh pages.
    address = views.__array_interface__["data"][0] - 10 * 8
    del views
    gc.collect()
    again = carve(blocks.get(size), layout)
    assert again["a"].__array_interface__["data"][0] == address
    # Each array starts on an 8-byte boundary, whatever the one before it holds.
    assert all(values.__array_interface__["data"][0] % 8 == 0 for values in again.values())
    # A request far smaller than a free block takes a block of its own (a small frame pins no large block).
    small = blocks.get(size // 4)
    assert not np.shares_memory(small, again["a"]) and small.base.shape[0] == size // 4


def test_the_boresight_series_are_libm_rays_within_two_ulp() -> None:
    xy = _pattern_samples(20000, 5)
    xy[9:] *= 57.0 / 89.0  # most inside the series' reach (1 rad), the first few and some others beyond it
    x, y = np.radians(xy).T
    alpha = np.hypot(x, y)
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = np.where(alpha > 0, np.sin(alpha) / alpha, 1.0)
    libm = np.column_stack([np.cos(alpha), ratio * x, -ratio * y])
    found = directions_from_xy(xy)
    inside = alpha <= 1.0
    assert 1000 < np.count_nonzero(~inside) < 8000
    ulps = np.abs(found - libm)[inside] / np.spacing(np.maximum(np.abs(libm[inside]), 1e-300))
    assert ulps.max() <= 2.0
    np.testing.assert_allclose(found, libm, rtol=0, atol=1e-15)  # beyond it too (libm's sin and cos)


def test_a_forked_child_gets_blocks_even_when_the_parent_was_taking_one() -> None:
    import os

    blocks = RecycledBlocks()
    blocks._lock.acquire()  # another thread of the parent inside get() at the fork
    try:
        pid = os.fork()
        if pid == 0:
            os._exit(0 if blocks.get(64).shape == (64,) else 1)
        assert child_exit_code(pid, 30.0, "it waits for the parent's lock") == 0
    finally:
        blocks._lock.release()
