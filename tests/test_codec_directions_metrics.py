"""int16 codec, ray directions and pattern measures against independent computations."""

from __future__ import annotations

import math

import numpy as np
import pytest

from livox_viz import ScanPattern, SensorConfig
from livox_viz.casting.codec import decode_int16, encode_int16, max_decode_error
from livox_viz.casting.directions import directions_from_xy, xy_from_directions
from livox_viz.patterns.metrics import CoverageGrid, coverage, coverage_curve, pattern_coverage, radial_density


@pytest.mark.parametrize("range_max", [600.0, 1.0, 123.4])
def test_codec_error_bound(range_max: float) -> None:
    rng = np.random.default_rng(0)
    xyz = rng.uniform(-range_max, range_max, size=(200_000, 3))
    back = decode_int16(encode_int16(xyz, range_max), range_max)
    error = np.abs(back - xyz).max()
    assert error <= max_decode_error(range_max) * (1 + 1e-9)
    assert error > 0.9 * max_decode_error(range_max)  # the bound is tight, not loose
    assert max_decode_error(600.0) == pytest.approx(0.009155, abs=1e-6)


def test_codec_matches_the_formula_and_clips() -> None:
    values = np.array([[0.0, 600.0, -600.0], [1.0, 1e6, -1e6], [300.0, -0.0091, 0.0092]])
    encoded = encode_int16(values, 600.0)
    assert encoded.dtype == np.int16
    assert encoded.tolist() == [[0, 32767, -32767], [55, 32767, -32767], [16384, 0, 1]]
    assert decode_int16(np.array([32767, -32767, 1], dtype=np.int16), 600.0).tolist() == [
        600.0, -600.0, 600.0 / 32767]


def test_directions_are_unit_and_follow_frd() -> None:
    xy = np.array([[0.0, 0.0], [10.0, 0.0], [0.0, 10.0], [-30.0, 40.0]])
    d = directions_from_xy(xy)
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, atol=1e-12)
    np.testing.assert_allclose(d[0], [1, 0, 0])
    s, c = math.sin(math.radians(10)), math.cos(math.radians(10))
    np.testing.assert_allclose(d[1], [c, s, 0], atol=1e-12)  # pattern right = sensor +y (right)
    np.testing.assert_allclose(d[2], [c, 0, -s], atol=1e-12)  # pattern up = sensor -z (up in FRD)
    # Angle off the boresight is hypot(x, y).
    assert math.degrees(math.acos(d[3, 0])) == pytest.approx(50.0)
    np.testing.assert_allclose(xy_from_directions(d), xy, atol=1e-9)


def test_coverage_hand_computed_case() -> None:
    # Radius 1, cells of 0.5: centres at +-0.25 and +-0.75; the 4 corner cells lie outside.
    grid = CoverageGrid(1.0, 0.5)
    assert grid.cell_count == 12
    points = np.array([[0.1, 0.1], [0.2, 0.3], [-0.6, 0.1], [0.1, -0.9], [0.8, 0.8], [5, 5]])
    assert coverage(points, 1.0, 0.5) == pytest.approx(3 / 12)
    np.testing.assert_allclose(coverage_curve(points, [0, 1, 2, 3, 6], 1.0, 0.5), [0, 1 / 12, 1 / 12, 2 / 12, 3 / 12])


def test_a_coverage_grid_cannot_be_changed_after_it_is_made() -> None:
    """A CoverageGrid is immutable: the metrics keep one grid per (fov, cell) in an lru_cache and hand the same
    object to every caller, and its inside mask is cached from the cell size it was made with. A caller that set
    cell_deg would get a mask for another cell size and spoil the grid for every other caller; so setting a field
    raises (the dataclass is frozen) and the hand-computed 12 cells of radius 1 at 0.5 deg stay 12."""
    import dataclasses

    grid = CoverageGrid(1.0, 0.5)
    assert grid.cell_count == 12
    with pytest.raises(dataclasses.FrozenInstanceError):
        grid.cell_deg = 0.25  # type: ignore[misc]
    assert grid.cell_deg == 0.5 and grid.cell_count == 12


def test_full_grid_is_full_coverage() -> None:
    grid = CoverageGrid(2.0, 0.1)
    half = grid.cells_per_side
    centres = (np.arange(-half, half) + 0.5) * 0.1
    xs, ys = np.meshgrid(centres, centres)
    points = np.column_stack([xs.ravel(), ys.ravel()])
    assert coverage(points, 2.0, 0.1) == pytest.approx(1.0)
    assert grid.cell_count == pytest.approx(math.pi * 20**2, rel=0.02)


def test_pattern_coverage_agrees_with_one_pass_curve(mid70: SensorConfig) -> None:
    points = ScanPattern(mid70, seed=0).take(100_000).xy_deg
    seconds = [0.1, 0.25, 1.0]
    curve = coverage_curve(points, [10_000, 25_000, 100_000], mid70.half_fov_deg)
    np.testing.assert_allclose(pattern_coverage(mid70, seconds, seed=0), curve)
    # Grows with time, one flower covers about a tenth of the FOV.
    assert np.all(np.diff(curve) > 0)
    assert 0.08 < curve[0] < 0.13


def test_radial_density_of_uniform_disk_is_flat() -> None:
    rng = np.random.default_rng(1)
    radius = 20.0
    # Uniform in solid angle on the cone: cos(alpha) uniform.
    alpha = np.degrees(np.arccos(rng.uniform(math.cos(math.radians(radius)), 1.0, 400_000)))
    beta = rng.uniform(0, 2 * math.pi, alpha.size)
    xy = np.column_stack([alpha * np.cos(beta), alpha * np.sin(beta)])
    edges, density = radial_density(xy, radius, bins=10)
    assert edges[-1] == radius
    expected = alpha.size / (2 * math.pi * (1 - math.cos(math.radians(radius))))
    np.testing.assert_allclose(density, expected, rtol=0.05)


def test_received_points_give_the_stream_s_own_curves_in_any_order_at_their_times_resolution() -> None:
    """A live stream's curves (the window's charts in the live view): points in any order give the curves of the
    stream in firing order; stamped a frame at a time (RflySim's wire), no integration time shorter than a frame
    is drawn, and the rest count each frame's points at its stamp."""
    from livox_viz import ScanPattern, load_preset
    from livox_viz.patterns.metrics import received_curves, stream_curves

    config = load_preset("livox_mid70")
    count = 100_000
    xy = ScanPattern(config, seed=0).take(count).xy_deg
    t = np.arange(count) / config.point_rate
    firing_order = stream_curves(xy, config.point_rate, config.field_of_view)
    shuffled = np.random.default_rng(4).permutation(count)
    received = received_curves(xy[shuffled], t[shuffled] + 7.0, config.point_rate, config.field_of_view)
    np.testing.assert_array_equal(received.seconds, firing_order.seconds)
    np.testing.assert_allclose(received.coverage, firing_order.coverage)
    np.testing.assert_allclose(received.density, firing_order.density)
    stamped = np.floor(t * 10.0) / 10.0  # each 0.1 s frame at its start
    framed = received_curves(xy, stamped, config.point_rate, config.field_of_view)
    assert framed.seconds.tolist() == [0.1, 0.2, 0.3, 0.5, 0.75]
    np.testing.assert_allclose(framed.coverage[[0, 1, 2]], firing_order.coverage[[1, 2, 3]], atol=0.002)
    empty = received_curves(np.zeros((0, 2)), np.zeros(0), config.point_rate, config.field_of_view)
    assert empty.seconds.size == empty.coverage.size == empty.density.size == 0
