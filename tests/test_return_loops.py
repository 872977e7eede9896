"""The datasheet model's compiled loops and bounds, each against a case worked out by hand or an identity.

Written from a mutation trial of the loops: every test here failed one or more mutants that the scene-level tests
of ``test_returns.py`` let through (a (0, 0, 0) test missing an axis, return numbers counted after the drop, the
return-0 bits on a later return, the strongest-returns selection, the outputs' size check, false alarms of
undetected hits, the ziggurat's constants, a bounding cylinder drawn too tight, the probes' limit, a ball's
sphere read in place of a cylinder).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh

from livox_viz.casting import return_kernels
from livox_viz.casting.beam import SUBRAY_WEIGHTS
from livox_viz.casting.returns import reflectivity_byte
from livox_viz.core import streamrandom
from livox_viz.scene.materials import set_face_materials
from livox_viz.scene.raycast import EmbreeCaster, casting_in_this_thread

from .test_returns import at_origin, scan, wall


def emit(whole: list, power: list, distance: list, first: list, count: list, e_power: list, e_range: list,
         directions: list, *, keep: int = 3, blind: float = 0.0, return0: float = 1.5, false_rate: float = 0.0,
         rows: int | None = None, start: int = 0, range_max: float = 260.0,
         sigma: float = 1e-9) -> tuple[int, dict[str, np.ndarray]]:
    """The compiled emit loop on hand-made pulses: receiver noise off (a huge SNR), range noise ``sigma`` (by default
    a nanometre).

    Pulse ``i`` is whole (its central hit at ``distance[i]``) or, when ``count[i]`` > 0, sampled with the echoes
    ``first[i] ..`` of ``e_power`` and ``e_range``; the loop takes the sampled pulses' echoes in slots of the
    largest count, as the model lays them out."""
    n = len(whole)
    echoes = len(e_power)
    rows = n + echoes if rows is None else rows
    out = {"beam": np.zeros(rows, np.int64), "index": np.zeros(rows, np.int64), "t": np.zeros(rows),
           "xy": np.zeros((rows, 2)), "range": np.zeros(rows), "sensor": np.zeros((rows, 3)),
           "int16": np.zeros((rows, 3), np.int16), "world": np.zeros((rows, 3)),
           "reflectivity": np.zeros(rows, np.uint8), "tag": np.zeros(rows, np.uint8),
           "number": np.zeros(rows, np.uint8), "returns": np.zeros(rows, np.uint8)}
    keys = np.array([streamrandom.stream_key(1, purpose) for purpose in (1, 2, 3, 4, 5)], dtype=np.uint64)
    count = np.asarray(count, np.int64)
    sampled = np.flatnonzero(count > 0)
    slots = int(count.max(initial=1))
    slot_power, slot_range = np.zeros(sampled.size * slots), np.zeros(sampled.size * slots)
    for s, pulse in enumerate(sampled):
        taken = slice(first[pulse], first[pulse] + count[pulse])
        slot_power[s * slots : s * slots + count[pulse]] = np.asarray(e_power, float)[taken]
        slot_range[s * slots : s * slots + count[pulse]] = np.asarray(e_range, float)[taken]
    triangle = np.where(np.asarray(whole, bool), 0, -1).astype(np.int64)
    directions = np.ascontiguousarray(directions, dtype=np.float64)
    kept = return_kernels.kernel("emit")(
        triangle, np.asarray(power, float), np.asarray(distance, float), np.ones(n), sampled, count[sampled], slots,
        slot_power, slot_range, np.zeros(slot_power.size, np.uint8), np.ones(slot_power.size), start, keys, 1e9,
        np.array([[0.0, sigma], [1000.0, sigma]]), blind, range_max, keep, false_rate, return0, 100.0, directions,
        directions, np.zeros((1, 3)), 0.0, np.zeros((n, 2)), np.empty(0), 1e5, 32767 / range_max,
        np.empty(slot_power.size), np.empty(slot_power.size), np.empty(slot_power.size, bool), *out.values())
    return kept, {name: values[: max(kept, 0)] for name, values in out.items()}


def test_a_pulse_keeps_its_return_numbers_when_its_first_echo_encodes_as_nothing() -> None:
    """A first echo a millimetre away encodes as (0, 0, 0) and is left out; the second is still return 2 of 2."""
    kept, points = emit([False], [0], [0], [0], [2], [1e6, 1e6], [0.001, 5.0], [[1.0, 0.0, 0.0]], keep=2)
    assert kept == 1 and points["number"].tolist() == [2] and points["returns"].tolist() == [2]


def test_only_the_first_return_nearer_than_return0_takes_return_bits_0() -> None:
    kept, points = emit([False], [0], [0], [0], [2], [1e6, 1e6], [0.5, 1.0], [[1.0, 0.0, 0.0]], keep=2)
    assert kept == 2 and (points["tag"] >> 4).tolist() == [0, 2]


def test_past_its_returns_a_pulse_keeps_the_nearest_and_then_the_strongest() -> None:
    """Four echoes seen (powers 50, 10, 40, 30 at 5-8 m), three kept: the nearest, then 40 and 30, in range order."""
    kept, points = emit([False], [0], [0], [0], [4], [50, 10, 40, 30], [5, 6, 7, 8], [[1.0, 0.0, 0.0]], keep=3)
    assert kept == 3 and points["range"].round(6).tolist() == [5, 7, 8]
    assert points["number"].tolist() == [1, 2, 3] and points["returns"].tolist() == [3, 3, 3]


def test_a_point_along_one_axis_is_not_taken_for_nothing() -> None:
    """Straight down the z axis at 5 m: x and y encode as 0, z does not; the point stays."""
    kept, points = emit([True], [1e6], [5.0], [0], [0], [], [], [[0.0, 0.0, 1.0]])
    assert kept == 1 and points["int16"][0].tolist() == [0, 0, round(5.0 / 260.0 * 32767)]


def test_a_hit_at_the_blind_zone_is_whole_and_one_nearer_is_not() -> None:
    """A central hit exactly at the blind zone's edge is a whole pulse (its point kept where the range noise,
    a nanometre, falls beyond the edge, and its int16 point decodes beyond it too); one a micrometre nearer gives
    nothing. At 2.004 m the int16 level (260 m / 32767) rounds up, to 2.0075 m; at 2.000 m it rounds down, to
    1.99952 m, so a hit at a blind zone of 2 m decodes inside it and gives nothing either."""
    noise = streamrandom.stream_normal(1, 1, np.arange(64), 2)[:, 1]  # each pulse's range-noise draw
    start = int(np.flatnonzero(noise > 0.5)[0])
    level = 260.0 / 32767
    assert np.rint(2.004 / level) * level > 2.004 and np.rint(2.0 / level) * level < 2.0
    kept, points = emit([True], [1e6], [2.004], [0], [0], [], [], [[1.0, 0.0, 0.0]], blind=2.004, start=start)
    assert kept == 1 and points["range"][0] == pytest.approx(2.004, abs=1e-8)
    assert points["index"].tolist() == [start] and points["int16"][0].tolist() == [253, 0, 0]
    assert emit([True], [1e6], [2.004 - 1e-6], [0], [0], [], [], [[1.0, 0.0, 0.0]], blind=2.004, start=start)[0] == 0
    assert emit([True], [1e6], [2.0], [0], [0], [], [], [[1.0, 0.0, 0.0]], blind=2.0, start=start)[0] == 0
    assert emit([True], [1e6], [2.0], [0], [0], [], [], [[1.0, 0.0, 0.0]], blind=1.999, start=start)[0] == 1


def test_the_loop_says_when_its_outputs_are_one_row_short() -> None:
    """Pulses with nothing in front, at stream indices 70 000-72 999: a point for each whose false-alarm draw falls
    under the rate, drawn here independently. With a row fewer than those the loop answers -1 (the caller sizes
    again), with as many it writes them all, at their stream indices."""
    start, n = 70_000, 3000
    draws = streamrandom.stream_uniform(1, 4, start + np.arange(n), 1)[:, 0]
    alarms = start + np.flatnonzero(draws < 0.01)
    assert 15 < alarms.size < 50
    nothing = [np.zeros(n, bool), np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n), [], [],
               np.tile([1.0, 0.0, 0.0], (n, 1))]
    assert emit(*nothing, false_rate=0.01, rows=alarms.size - 1, start=start, blind=0.1)[0] == -1
    kept, points = emit(*nothing, false_rate=0.01, rows=alarms.size, start=start, blind=0.1)
    assert kept == alarms.size and points["index"].tolist() == alarms.tolist()
    assert np.all((points["tag"] & 0x0F) == 0x05)


def test_a_hit_too_dark_to_detect_reports_false_alarms_at_the_rate() -> None:
    """Every pulse meets a wall of reflectance 1e-6 and none is seen: their false alarms come at the sheet's
    rate, as a pulse meeting nothing does."""
    cfg = at_origin("livox_mid40_risley", false_alarm_rate=0.01)
    frames, _ = scan(cfg, wall(30.0, 1e-6), 0.5, seed=2)
    expected = sum(f.ray_count for f in frames) * 0.01
    assert abs(sum(len(f) for f in frames) - expected) < 4 * math.sqrt(expected)


def test_the_ziggurats_layers_each_hold_the_same_area() -> None:
    """The tables' defining identities (Marsaglia and Tsang): the base strip x_0 f(R) = V is the rectangle under
    R plus the tail beyond it, R f(R) + sqrt(pi / 2) erfc(R / sqrt(2)); every layer above holds V; the top one
    ends at the peak, f = 1."""
    x, f = streamrandom.ZIGGURAT_X, streamrandom.ZIGGURAT_F
    area, edge = streamrandom.ZIGGURAT_V, streamrandom.ZIGGURAT_R
    assert x[0] * f[1] == pytest.approx(area, rel=1e-12)
    tail = math.sqrt(math.pi / 2.0) * math.erfc(edge / math.sqrt(2.0))
    assert edge * math.exp(-edge * edge / 2.0) + tail == pytest.approx(area, rel=1e-9)
    for i in range(1, streamrandom.ZIGGURAT_LAYERS):
        above = 1.0 if i == streamrandom.ZIGGURAT_LAYERS - 1 else f[i + 1]
        assert x[i] * (above - f[i]) == pytest.approx(area, rel=1e-8), i


def test_a_poles_bounding_cylinder_holds_every_vertex_and_hugs_it() -> None:
    from livox_viz.casting.beam import _convex_hulls, _part_kinds

    rng = np.random.default_rng(0)
    for _ in range(5):
        pole = trimesh.creation.cylinder(0.08, 3.0, sections=40)
        pole.apply_transform(trimesh.transformations.random_rotation_matrix(rng.random(3)))
        pole.apply_translation(rng.uniform(-50, 50, 3))
        triangles = np.asarray(pole.triangles)
        parts = np.zeros(len(triangles), np.int64)
        shapes, _, _ = _convex_hulls(triangles, parts, _part_kinds(triangles, parts))
        point, axis, radius = shapes[0, 4:7], shapes[0, 7:10], shapes[0, 10]
        offsets = pole.vertices - point
        across = np.linalg.norm(offsets - np.outer(offsets @ axis, axis), axis=1)
        assert across.max() <= radius + 1e-9 and radius < 0.081


def test_rays_said_to_miss_an_octahedron_miss_it_in_embree() -> None:
    """A convex object of few faces (planes, and a finite bounding sphere, but no cylinder) over a ground plate:
    no ray :meth:`TileProxy.rays_may_meet` lets go is one Embree finds blocked."""
    from livox_viz.casting.beam import TileProxy

    corners = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float) * 0.5
    octahedron = trimesh.convex.convex_hull(corners).apply_translation((5.0, 0.3, -0.2))
    ground = trimesh.Trimesh([[-5.0, -30.0, 1.2], [9.0, -30.0, 1.2], [9.0, 30.0, 1.2], [-5.0, 30.0, 1.2]],
                             [[0, 1, 2], [0, 2, 3]])
    mesh = trimesh.util.concatenate([octahedron, ground])
    set_face_materials(mesh, np.full(len(mesh.faces), 0.5), np.ones(len(mesh.faces)),
                       np.repeat([0, 1], [len(octahedron.faces), len(ground.faces)]))
    proxy = TileProxy(mesh, math.tan(math.radians(0.14)))
    assert np.isfinite(proxy.part_sphere[0, 3]) and not np.isfinite(proxy.part_sphere[0, 10])
    origin = np.zeros((1, 3))
    aim = np.random.default_rng(3).uniform((4.4, -0.3, -0.8), (5.6, 0.9, 0.4), (5000, 3))
    rays = aim / np.linalg.norm(aim, axis=1, keepdims=True)
    limit = np.full(len(rays), 12.0)
    crossed = np.empty((len(rays), 8), np.int64)
    no_hit = np.full(len(rays), -1)
    proxy.near(np.ones(len(rays), dtype=bool), origin, rays, limit, no_hit, None, proxy.place(origin, 600.0),
               crossed)
    meet = proxy.rays_may_meet(np.arange(len(rays)), rays.astype(np.float32), limit, no_hit, origin, crossed)
    with casting_in_this_thread():
        blocked = EmbreeCaster(mesh).occluded(origin[0], rays.astype(np.float32), limit)
    assert blocked.sum() > 100 and not np.any(blocked & ~meet)
    assert np.count_nonzero(~meet & ~blocked) > 100  # and it does let rays go


@pytest.mark.parametrize("depth", [0.04, 0.08])
def test_a_plate_just_in_front_of_a_wall_covers_the_footprints_that_reach_it(depth: float) -> None:
    """A plate (its own object) a few centimetres in front of a wall, its edge along the pattern's x = 0: the
    probes find covered every footprint that reaches past the edge onto the wall, within a quarter (a 4 cm plate
    is less than 3 range sigmas deep: a probe stopped short of the wall's plane by the sigma still meets it)."""
    from livox_viz.casting.scan import MountedCaster
    from livox_viz.patterns.factory import make_pattern

    cfg = at_origin("livox_mid70_risley")
    plate = trimesh.creation.box((0.002, 40, 80), trimesh.transformations.translation_matrix(
        (20.0 - depth + 0.001, 20.0, 0.0)))
    behind = wall(20.0, 0.5)
    mesh = trimesh.util.concatenate([plate, behind])
    set_face_materials(mesh, np.full(len(mesh.faces), 0.5), np.ones(len(mesh.faces)),
                       np.repeat([1, 0], [len(plate.faces), len(behind.faces)]))
    mounted = MountedCaster(cfg, EmbreeCaster(mesh), seed=1)
    chunk = make_pattern(cfg, seed=1).take(60_000)
    with casting_in_this_thread():
        mounted.cast(chunk)
    reaching = int(np.count_nonzero((chunk.xy_deg[:, 0] < 0) & (chunk.xy_deg[:, 0] > -0.015)))
    assert mounted.returns.last_counts["covered"] == pytest.approx(reaching, rel=0.25)


# From a second mutation trial: the byte, the later echoes' noise, the blind zone of footprint echoes, the spatial
# bits' order, and a footprint echo's reflectance unit ------------------------------------------------------------
@pytest.mark.parametrize(("value", "byte"), [(0.5037, 76), (0.5030, 75), (1.0, 150), (1.5, 150), (1.999, 150),
                                             (2.0, 151), (20.0, 190), (1000.0, 255), (5000.0, 255)])
def test_the_compiled_byte_is_the_documented_mapping(value: float, byte: int) -> None:
    """0-150 for 0-100 % Lambertian, rounded half up (0.5037 -> 75.56 -> 76), saturating up to twice a white
    target; 151 + 104 x log(v / 2) / log(500), rounded, from twice to 1000 times (20 -> 151 + 38.5). The emit loop's
    own byte and the Python one both."""
    return_kernels.kernel("emit")  # compiles the loops' helpers
    assert return_kernels._byte(value) == byte
    assert reflectivity_byte(np.array([value]))[0] == byte


def test_a_later_echo_takes_its_noise_from_the_later_echoes_stream() -> None:
    """A pulse's first echo draws pair 0 of its own stream (purpose 1), its second echo pair 0 of the later echoes'
    stream (purpose 2), at the pulse's stream index: range noise 1 m, so the draws show in the ranges."""
    kept, points = emit([False], [0], [0], [0], [2], [1e6, 1e6], [10.0, 20.0], [[1.0, 0.0, 0.0]], start=77,
                        sigma=1.0)
    first = streamrandom.stream_normal(1, 1, np.array([77]), 2)[0]
    later = streamrandom.stream_normal(1, 2, np.array([77]), 2)[0]
    assert kept == 2
    np.testing.assert_allclose(points["range"], [10.0 + first[1], 20.0 + later[1]], rtol=0, atol=1e-12)


def test_a_footprint_echo_measured_inside_the_blind_zone_gives_no_point() -> None:
    """A sampled pulse's echo at the 1 m blind zone with 5 cm range noise: over 40 stream indices about half land
    inside; none of them gives a point, measured or decoded."""
    kept_any = 0
    for start in range(40):
        kept, points = emit([False], [0], [0], [0], [1], [1e6], [1.0], [[1.0, 0.0, 0.0]], blind=1.0, start=start,
                            sigma=0.05)
        kept_any += kept
        assert np.all(points["range"] >= 1.0)
        assert np.all(np.linalg.norm(points["int16"] * (260.0 / 32767), axis=1) >= 1.0)
    assert 8 < kept_any < 32


def footprint(ranges: list[float], triangles: list[int], planes: list[list[float]],
              calibration: tuple[float, float, float] = (0.1, 90.0, 0.0), blind: float = 0.05,
              separate: bool = False) -> tuple[int, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The compiled footprint loop on one pulse whose 19 sub-rays (all along x, from the origin) met ``triangles``
    at ``ranges``: its echoes' count, power, range, spatial bits and reflectance per unit of power."""
    count = SUBRAY_WEIGHTS.size
    rays = np.zeros((1, count, 3))
    rays[..., 0] = 1.0
    written, slot = np.zeros(1, np.int64), np.zeros(count, np.int64)
    power, range_m, unit = np.zeros(count), np.zeros(count), np.zeros(count)
    spatial = np.zeros(count, np.uint8)
    return_kernels.kernel("footprint_echoes")(
        np.array([0], np.int64), np.array([ranges], float), np.array([triangles], np.int64), rays, SUBRAY_WEIGHTS,
        np.asarray(planes, float), np.ones(len(planes)), np.zeros((1, 3)), blind, separate, 0.6,
        np.array([[20.0, 0.02]]), 0.05, np.asarray(calibration, float), written, slot, power, range_m, spatial, unit)
    return int(written[0]), power, range_m, spatial, unit


def test_sub_rays_at_the_blind_zone_echo_as_a_whole_pulse_there_does() -> None:
    written, _, range_m, _, _ = footprint([0.5] * 19, [0] * 19, [[1.0, 0.0, 0.0, 0.5]], blind=0.5)
    assert written == 1 and range_m[0] == pytest.approx(0.5)


def test_the_spatial_bits_say_how_far_between_the_surfaces_the_point_sits() -> None:
    """A single-return footprint on two planes 1 m apart: the centre and inner ring on 11 m and the outer ring on
    10 m blend at 10.63 m, 0.37 of the way (bits 01, high confidence of noise); one outer sub-ray on 10 m blends at
    10.97 m, 0.03 of the way (bits 11, low)."""
    planes = [[1.0, 0.0, 0.0, 11.0], [1.0, 0.0, 0.0, 10.0]]
    written, _, range_m, spatial, _ = footprint([11.0] * 7 + [10.0] * 12, [0] * 7 + [1] * 12, planes)
    assert written == 1 and 0.3 < 11.0 - range_m[0] < 0.45 and spatial[0] == 0x01
    written, _, range_m, spatial, _ = footprint([11.0] * 18 + [10.0], [0] * 18 + [1], planes)
    assert written == 1 and 11.0 - range_m[0] < 0.1 and spatial[0] == 0x03


def test_a_footprint_echos_unit_inverts_its_power_with_the_range_loss() -> None:
    """A white wall at 11 m, normal incidence, a loss of 0.004 / m: power x unit is the reflectance, 1."""
    written, power, _, _, unit = footprint([11.0] * 19, [0] * 19, [[1.0, 0.0, 0.0, 11.0]], (0.1, 90.0, 0.004))
    assert written == 1 and power[0] * unit[0] == pytest.approx(1.0, rel=1e-9)
