"""EmbreeCaster's split of a call over threads and its compiled steps around Embree: every ray cast once, the
parts shrinking towards the end, and the distances bit for bit those of Embree run bare on the same float32 rays."""

from __future__ import annotations

import itertools
import threading
import time

import numpy as np
import pytest
import trimesh

from livox_viz.scene.raycast import _KERNELS, LEAST_RAYS, PART_RAYS, EmbreeCaster, casting_in_this_thread


def recorded_parts(caster: EmbreeCaster, count: int, pause: float = 0.0) -> list[tuple[int, int, int]]:
    """The parts ``caster._run_split`` hands out for ``count`` rays: (start, stop, thread), in the order taken."""
    taken: list[tuple[int, int, int]] = []
    lock = threading.Lock()

    def run(bounds: tuple[int, int]) -> None:
        with lock:
            taken.append((bounds[0], bounds[1], threading.get_ident()))
        time.sleep(pause)

    caster._run_split(run, count)
    return taken


def assert_covers_once(parts: list[tuple[int, int, int]], count: int) -> None:
    bounds = sorted((start, stop) for start, stop, _ in parts)
    assert bounds[0][0] == 0 and bounds[-1][1] == count
    assert all(a[1] == b[0] for a, b in itertools.pairwise(bounds)), "a gap or an overlap"
    assert all(stop > start for start, stop in bounds)


@pytest.fixture(scope="module")
def box() -> trimesh.Trimesh:
    return trimesh.creation.box((2, 2, 2))


@pytest.mark.parametrize("count", [1, LEAST_RAYS, 2 * LEAST_RAYS, 10_000, 3 * PART_RAYS + 1234, 1_000_000])
def test_every_ray_is_in_one_part_and_no_part_is_past_the_largest(box: trimesh.Trimesh, count: int) -> None:
    parts = recorded_parts(EmbreeCaster(box, threads=2), count)
    assert_covers_once(parts, count)
    assert max(stop - start for start, stop, _ in parts) <= PART_RAYS
    if count < 2 * LEAST_RAYS:
        assert len(parts) == 1  # too few rays to hand any to a worker


def test_parts_shrink_towards_the_end_so_the_threads_finish_together(box: trimesh.Trimesh) -> None:
    count = 1_000_000
    parts = recorded_parts(EmbreeCaster(box, threads=2), count, pause=0.001)
    sizes = [stop - start for start, stop, _ in sorted(parts)]
    assert sizes[0] == PART_RAYS  # large while much is left
    # The last parts are each at most a quarter of what was left when taken (down to the least part): the one
    # the slower thread finishes last is small. Parts of one size would leave it a whole part behind.
    left = count
    for size in sizes:
        assert size <= max(PART_RAYS if left > 4 * PART_RAYS else left // 4, LEAST_RAYS) + LEAST_RAYS // 2
        left -= size
    assert sizes[-1] <= LEAST_RAYS + LEAST_RAYS // 2
    assert len({thread for _, _, thread in parts}) == 2  # the caller and the worker both took parts


def test_one_thread_or_casting_inline_takes_every_part_on_the_caller(box: trimesh.Trimesh) -> None:
    count = 3 * PART_RAYS + 5
    here = threading.get_ident()
    alone = recorded_parts(EmbreeCaster(box, threads=1), count)
    assert_covers_once(alone, count)
    assert [stop - start for start, stop, _ in alone] == [PART_RAYS] * 3 + [5]
    assert {thread for _, _, thread in alone} == {here}
    with casting_in_this_thread():
        inline = recorded_parts(EmbreeCaster(box, threads=2), count)
    assert {thread for _, _, thread in inline} == {here}


def test_a_failing_part_stops_the_other_threads_taking_parts(box: trimesh.Trimesh) -> None:
    caster = EmbreeCaster(box, threads=2)
    ran: list[int] = []
    lock = threading.Lock()

    def run(bounds: tuple[int, int]) -> None:
        with lock:
            ran.append(bounds[0])
            second = len(ran) == 2
        if second:
            raise ValueError("part failed")
        time.sleep(0.002)

    with pytest.raises(ValueError, match="part failed"):
        caster._run_split(run, 1_000_000)
    assert len(ran) <= 4  # not the 20-odd parts of the whole call


def test_the_compiled_steps_are_numpys_casts_and_the_miss_rule() -> None:
    rng = np.random.default_rng(7)
    n = 1000
    origins = rng.uniform(-5e4, 5e4, size=(n, 3))
    centre = np.array([1234.5678, -987.654321, 42.4242])
    directions = rng.normal(size=(n, 3))
    origins_out = np.empty((n, 3), np.float32)
    directions_out = np.empty((n, 3), np.float32)
    limits = np.empty(n, np.float32)
    _KERNELS["rays"](origins.reshape(-1), centre, directions.reshape(-1), origins_out.reshape(-1),
                       directions_out.reshape(-1), limits, np.float32(123.25))
    np.testing.assert_array_equal(origins_out, (origins - centre).astype(np.float32))
    np.testing.assert_array_equal(directions_out, directions.astype(np.float32))
    np.testing.assert_array_equal(limits, np.full(n, np.float32(123.25)))

    limit = np.float32(60.0)
    far = np.array([0.0, 1.5, np.nextafter(limit, np.float32(0)), limit, np.nan, 59.75], np.float32)
    out = np.full(far.size, -1.0)
    _KERNELS["misses"](far, limit, out)
    np.testing.assert_array_equal(out, [0.0, 1.5, float(np.nextafter(limit, np.float32(0))), np.inf, np.nan, 59.75])


@pytest.mark.parametrize("threads", [1, 2])
def test_distances_are_bare_embrees_on_the_same_float32_rays(threads: int) -> None:
    """Per-ray origins far from the scene's centre, scattered misses, a limit, directions float64, float32 and
    strided: each distance is Embree's own float32 answer for the float32 ray, widened, or inf for a miss."""
    rng = np.random.default_rng(11)
    count = 2 * PART_RAYS + 777
    mesh = trimesh.creation.icosphere(subdivisions=4, radius=30.0)
    mesh.apply_translation((5000.0, -3000.0, 40.0))
    caster = EmbreeCaster(mesh, threads=threads)
    origins = np.array([5000.0, -3000.0, 40.0]) + rng.uniform(-45.0, 45.0, size=(count, 3))
    directions = rng.normal(size=(count, 3))
    directions /= np.linalg.norm(directions, axis=1)[:, None]
    limit = 70.0

    o32 = (origins - caster.local_origin).astype(np.float32)
    d32 = directions.astype(np.float32)
    far = caster._scene.run(o32, d32, dists=np.full(count, np.float32(limit)), query="DISTANCE")
    expected = np.where(far < np.float32(limit), far.astype(np.float64), np.inf)
    assert 0.2 < np.isinf(expected).mean() < 0.8  # misses all through the rays

    np.testing.assert_array_equal(caster.distances(origins, directions, limit), expected)
    np.testing.assert_array_equal(caster.distances(origins, d32, limit), expected)
    strided = np.asfortranarray(directions)
    np.testing.assert_array_equal(caster.distances(origins, strided, limit), expected)
    one = caster.distances(origins[3], directions, limit)
    far_one = caster._scene.run(np.broadcast_to(o32[3], o32.shape).copy(), d32,
                                dists=np.full(count, np.float32(limit)), query="DISTANCE")
    np.testing.assert_array_equal(one, np.where(far_one < np.float32(limit), far_one.astype(np.float64), np.inf))


@pytest.mark.parametrize("threads", [1, 2])
def test_occlusion_is_a_hit_nearer_than_each_rays_own_limit_as_trimesh_finds_it(threads: int) -> None:
    """Embree's occlusion query through the thread's scratch arrays, against trimesh's own intersector (its hit
    distances): rays from their own origins or one, float64 or float32 directions, a limit a ray or one for all,
    limits beyond float32 (they stay rays of any length), parts on both threads."""
    from livox_viz.scene.raycast import TrimeshCaster

    scene = trimesh.util.concatenate([trimesh.creation.icosphere(2, 3.0),
                                      trimesh.creation.box((2.0, 8.0, 8.0)).apply_translation((9.0, 0.0, 0.0))])
    rng = np.random.default_rng(5)
    n = 3 * LEAST_RAYS + 17
    origins = rng.uniform((-12.0, -2.0, -2.0), (-6.0, 2.0, 2.0), (n, 3))
    directions = rng.normal((1.0, 0.0, 0.0), 0.35, (n, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    reference = TrimeshCaster(scene)
    far = reference.hits(origins, directions)[0]
    one = origins[:1]
    far_from_one = reference.hits(one, directions)[0]
    hit = np.isfinite(far)
    assert 0.3 * n < hit.sum() < 0.9 * n
    # Limits a clear margin off each hit (Embree casts in float32; trimesh in float64).
    limits = np.where(hit, far * np.where(rng.random(n) < 0.5, 0.98, 1.02), rng.uniform(1.0, 50.0, n))
    limits[::7] = np.inf
    limits[3::7] = 1e300
    caster = EmbreeCaster(scene, threads=threads)
    for rays in (directions, directions.astype(np.float32)):
        np.testing.assert_array_equal(caster.occluded(origins, rays, limits), hit & (far < limits))
        np.testing.assert_array_equal(caster.occluded(origins, rays, np.inf), hit)
        np.testing.assert_array_equal(caster.occluded(one[0], rays, 1e300), np.isfinite(far_from_one))
        short = np.where(np.isfinite(far_from_one), far_from_one * 0.98, 5.0)
        np.testing.assert_array_equal(caster.occluded(one, rays, short), np.zeros(n, dtype=bool))
    with pytest.raises(ValueError):
        caster.occluded(origins, directions, limits[:-1])


@pytest.mark.parametrize("exact", [False, True])
@pytest.mark.parametrize("count", [1, 2, 3, 7])
def test_each_ray_is_measured_from_its_own_origin_whatever_their_number(box: trimesh.Trimesh, count: int,
                                                                        exact: bool) -> None:
    """Rays from ``count`` different origins along x into the box's face at x = -1: each distance is its own
    origin's gap to the face, by Embree's float32 and by the hit triangle's plane (``exact``), whose code has a
    case of its own for one shared origin."""
    caster = EmbreeCaster(box, exact=exact)
    start = -3.0 - np.arange(count)  # 2, 3, 4, ... metres before the face
    origins = np.column_stack([start, np.linspace(-0.5, 0.5, count), np.zeros(count)])
    directions = np.tile([1.0, 0.0, 0.0], (count, 1))
    distance, triangle = caster.hits(origins, directions, 100.0)
    expected = -1.0 - start
    # The plane's distance is float64 arithmetic; Embree's is float32 in the box's own frame, whose coordinates
    # here reach |x| = 2 + count: its t is good to a few float32 ulps of that (1.2e-7 relative each), so 4 ulps of
    # the largest coordinate. Measured from another ray's origin the error is >= 1 m.
    rtol, atol = (1e-12, 0.0) if exact else (0.0, 4 * float(np.spacing(np.float32(np.abs(start).max()))))
    np.testing.assert_allclose(distance, expected, rtol=rtol, atol=atol)
    assert np.all(triangle >= 0)
    np.testing.assert_allclose(caster.distances(origins, directions, 100.0), expected, rtol=rtol, atol=atol)
