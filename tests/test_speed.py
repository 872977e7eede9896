"""The fast paths of issue 19 compute what the plain ones do: BLAS pinning, the Risley block product, times on
demand, Embree casting in parts and in parallel, frames cast side by side.

Speed itself is measured by the benchmarks, never here.
"""

from __future__ import annotations

import threading
from dataclasses import replace

import numpy as np
import pytest
import trimesh
from threadpoolctl import threadpool_limits

from livox_viz import SensorConfig, load_preset
from livox_viz.casting.directions import directions_from_xy
from livox_viz.casting.scan import LidarScanner
from livox_viz.core.blas import blas_threads, one_blas_thread
from livox_viz.patterns.factory import make_pattern
from livox_viz.patterns.risley import RisleyPattern, block_shape, risley_xy
from livox_viz.patterns.stream import PatternChunk
from livox_viz.scene.raycast import PART_RAYS, EmbreeCaster
from livox_viz.scene.scenes import open_scene


# BLAS threads -----------------------------------------------------------------------------
def test_one_blas_thread_pins_nests_and_gives_the_users_count_back() -> None:
    with threadpool_limits(limits=2, user_api="blas"):
        assert set(blas_threads()) == {2}
        with one_blas_thread():
            assert set(blas_threads()) == {1}
            with one_blas_thread():
                assert set(blas_threads()) == {1}
            assert set(blas_threads()) == {1}  # the outer holder still holds
        assert set(blas_threads()) == {2}


def test_a_blas_controller_without_threadpoolctl_s_shared_state_is_never_set_directly() -> None:
    """threadpoolctl's private ``_SHARED_STATE`` may go (another version, another library's controller): then the
    pin goes through threadpoolctl's public calls, never OpenBLAS's C functions directly."""
    from livox_viz.core.blas import _may_set_directly

    class Controller:  # no _SHARED_STATE
        pass

    assert _may_set_directly(Controller()) is False


def test_scipys_own_blas_is_pinned_once_it_is_loaded() -> None:
    """scipy.linalg brings its own OpenBLAS, loaded after numpy's: a pin taken after its import holds it too (the
    fits' small Cholesky factors ran on two spinning threads, 10 x slower on the loaded machine). In a fresh
    process, so that numpy's library is looked up first, as a command that pins a stream before it fits does."""
    import json
    import subprocess
    import sys

    probe = (
        "from threadpoolctl import threadpool_info, threadpool_limits\n"
        "from livox_viz.core.blas import one_blas_thread\n"
        "with threadpool_limits(limits=2, user_api='blas'):\n"
        "    with one_blas_thread():\n"
        "        pass\n"
        "    import scipy.linalg\n"
        "    threadpool_limits(limits=2, user_api='blas')\n"
        "    with one_blas_thread():\n"
        "        inside = sorted((i['filepath'], i['num_threads']) for i in threadpool_info()"
        " if i['user_api'] == 'blas')\n"
        "    after = sorted(i['num_threads'] for i in threadpool_info() if i['user_api'] == 'blas')\n"
        "import json\n"
        "print(json.dumps([len(inside), sorted({n for _, n in inside}), sorted(set(after))]))\n"
    )
    result = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    libraries, inside, after = json.loads(result.stdout)
    assert libraries >= 2 and inside == [1] and after == [2], result.stdout  # numpy's and scipy's, both pinned


def test_one_blas_thread_from_many_threads_gives_the_count_back() -> None:
    """Holders in several threads at once share one pin; the user's count is back when the last one leaves.

    (OpenBLAS honours a count set from the main thread; other threads' holds are counted the same way.)
    """

    def work() -> None:
        for _ in range(200):
            with one_blas_thread():
                pass

    with threadpool_limits(limits=2, user_api="blas"):
        with one_blas_thread():  # the main thread holds while the others come and go
            threads = [threading.Thread(target=work) for _ in range(4)]
            for thread in threads:
                thread.start()
            for thread in threads:
                thread.join()
            assert set(blas_threads()) == {1}
        assert set(blas_threads()) == {2}
        threads = [threading.Thread(target=work) for _ in range(4)]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
        assert set(blas_threads()) == {2}


# The Risley block product ---------------------------------------------------------------------
@pytest.mark.parametrize(("points_per_frame", "lasers", "shape"), [
    (10_000, 1, (40, 250)),     # the Mid-70's frame: one block, rows of 250
    (100, 1, (81, 100)),        # small frames: a block is 81 of them
    (10_000, 6, (31, 258)),     # 10 000 is no multiple of 6: blocks of about 8192 samples
    (7919, 1, (32, 256)),       # a prime: no row divides it
])
def test_block_shapes(points_per_frame: int, lasers: int, shape: tuple[int, int]) -> None:
    rows, row = block_shape(points_per_frame, lasers)
    assert (rows, row) == shape and row % lasers == 0


def risley_with(frame_w: int, frame_h: int, lasers: int) -> SensorConfig:
    base = load_preset("livox_mid70_risley")
    params = base.risley
    coefficients = np.stack([params.base_coefficients[0] * (1 + 0.01 * k) + 0.05j * k for k in range(lasers)])
    risley = replace(params, base_coefficients=coefficients, deflection_deg=None)
    return replace(base, data_width=frame_w, data_height=frame_h, risley=risley)


@pytest.mark.parametrize(("frame_w", "frame_h", "lasers"), [(250, 40, 1), (10, 10, 1), (250, 40, 6), (4973, 1, 1)])
def test_risley_blocks_are_the_series_and_the_same_however_cut(frame_w: int, frame_h: int, lasers: int) -> None:
    cfg = risley_with(frame_w, frame_h, lasers)
    stream = RisleyPattern(cfg)
    whole = stream.points(0, 50_000).xy_deg
    k = np.arange(50_000)
    # Against the series summed term by term at each time (an independent evaluation).
    np.testing.assert_allclose(whole, risley_xy(cfg.risley, k / cfg.point_rate, k % lasers), atol=1e-9)
    for cuts in ([cfg.points_per_frame] * 3, [1, 3, 8191, 8193, 17_000], [12_345]):
        cut_stream = RisleyPattern(cfg)
        parts = np.concatenate([cut_stream.take(n).xy_deg for n in cuts])
        np.testing.assert_array_equal(parts, whole[: sum(cuts)])
    later = RisleyPattern(cfg).points(33_333, 777).xy_deg  # straight into the middle of a block
    np.testing.assert_array_equal(later, whole[33_333:34_110])


def test_times_are_made_on_first_use_as_k_over_rate(mid70: SensorConfig) -> None:
    for config in (mid70, load_preset("livox_mid70_risley")):
        stream = make_pattern(config)
        stream.skip(123_457)
        chunk = stream.take(5000)
        assert "_t_given" not in chunk.__dict__ or chunk.__dict__["_t_given"] is None
        np.testing.assert_array_equal(chunk.t, np.arange(123_457, 128_457) / config.point_rate)
        assert chunk.t is chunk.t  # made once
    given = np.linspace(0.0, 1.0, 4)
    chunk = PatternChunk(mid70, 10, np.zeros((4, 2)), given)
    assert chunk.t is given


# Embree in parts --------------------------------------------------------------------------------
def ceiling() -> trimesh.Trimesh:
    """A 200 m square ceiling 10 m up (NED: z = -10): rays below the horizon or past its edge miss."""
    return trimesh.Trimesh([[-100, -100, -10], [100, -100, -10], [100, 100, -10], [-100, 100, -10]],
                           [[0, 1, 2], [0, 2, 3]], process=False)


def analytic_ceiling(origins: np.ndarray, directions: np.ndarray, max_distance: float) -> np.ndarray:
    """Distance along each ray to the ceiling z = -10 inside |x|, |y| < 100, inf otherwise."""
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (-10.0 - origins[:, 2]) / directions[:, 2]
    point = origins + t[:, None] * directions
    inside = (t > 0) & (np.abs(point[:, 0]) < 100) & (np.abs(point[:, 1]) < 100) & (t <= max_distance)
    return np.where(inside, t, np.inf)


@pytest.mark.parametrize("threads", [1, 2, 3])
def test_distances_from_origins_per_ray_with_scattered_misses(threads: int) -> None:
    rng = np.random.default_rng(4)
    count = 3 * PART_RAYS + 1234  # several parts
    directions = rng.normal(size=(count, 3))
    directions /= np.linalg.norm(directions, axis=1)[:, None]
    origins = rng.uniform(-50, 50, size=(count, 3)) * (1, 1, 0.1)
    caster = EmbreeCaster(ceiling(), threads=threads)
    expected = analytic_ceiling(origins, directions, 60.0)
    assert 0.2 < np.isinf(expected).mean() < 0.8  # misses all through the rays, upward ones hitting
    got = caster.distances(origins, directions, 60.0)
    hit = np.isfinite(expected)
    np.testing.assert_array_equal(np.isfinite(got), hit)
    np.testing.assert_allclose(got[hit], expected[hit], rtol=0, atol=2e-5)
    # One origin for all; float32 directions go to Embree as they are and give the same answer.
    single = caster.distances(origins[7], directions, 60.0)
    np.testing.assert_allclose(single, analytic_ceiling(np.broadcast_to(origins[7], origins.shape), directions, 60.0),
                               rtol=0, atol=2e-5)
    np.testing.assert_array_equal(caster.distances(origins[7], directions.astype(np.float32), 60.0),
                                  caster.distances(origins[7], directions.astype(np.float32).astype(np.float64), 60.0))
    assert np.isinf(caster.distances(origins, directions, 0.0)).all()


def test_distances_called_from_several_threads_at_once() -> None:
    rng = np.random.default_rng(5)
    caster = EmbreeCaster(ceiling(), threads=2)
    calls = []
    for _ in range(6):
        directions = rng.normal(size=(20_000, 3)) * (1, 1, 3) - (0, 0, 2)
        directions /= np.linalg.norm(directions, axis=1)[:, None]
        calls.append((rng.uniform(-20, 20, size=(20_000, 3)), directions))
    alone = [caster.distances(o, d, 200.0) for o, d in calls]
    together: list[np.ndarray | None] = [None] * len(calls)

    def run(k: int) -> None:
        for _ in range(5):
            together[k] = caster.distances(*calls[k], 200.0)

    threads = [threading.Thread(target=run, args=(k,)) for k in range(len(calls))]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    for one, other in zip(alone, together, strict=True):
        np.testing.assert_array_equal(one, other)


# Frames cast side by side ---------------------------------------------------------------------------
@pytest.fixture(scope="module")
def urban():
    return open_scene("urban")


def frame_key(frame) -> tuple:
    return (frame.index, frame.ray_count, frame.stream_index.tobytes(), frame.range_m.tobytes(),
            frame.xyz_int16.tobytes(), frame.t.tobytes())


@pytest.mark.parametrize("model", ["ideal", "datasheet"])
def test_frames_cast_as_one_run_are_the_frames_cast_one_by_one_on_a_flight(urban, model: str) -> None:
    from livox_viz import load_preset
    from livox_viz.casting.scan import MountedCaster
    from livox_viz.motion.flights import builtin_trajectory
    from livox_viz.scene.raycast import casting_in_this_thread

    cfg = load_preset("livox_mid70_risley").with_returns_model(model)
    flight = builtin_trajectory("circle", 8.0, urban.vehicle_pose, 2.0)
    mounted = MountedCaster(cfg, EmbreeCaster(urban.mesh), trajectory=flight, seed=2)
    pattern = make_pattern(cfg, seed=2)
    pattern.skip(12_345)  # the batch starts inside a frame, as a resumed scan's does
    chunks = [pattern.take(cfg.points_per_frame - 12_345 % cfg.points_per_frame)]
    chunks += [pattern.take(cfg.points_per_frame) for _ in range(3)] + [pattern.take(777)]
    with casting_in_this_thread():
        batch = mounted.cast_frames(chunks)
        single = [mounted.cast(chunk) for chunk in chunks]
    assert len(batch) == len(chunks) and sum(len(frame) for frame in batch) > 20_000
    for one_run, alone in zip(batch, single, strict=True):
        for name in ("index", "ray_count", "timestamp", "end_time", "range_max"):
            assert getattr(one_run, name) == getattr(alone, name), name
        for name in ("sensor_pose", "end_pose"):
            np.testing.assert_array_equal(getattr(one_run, name).origin, getattr(alone, name).origin)
            np.testing.assert_array_equal(getattr(one_run, name).rotation, getattr(alone, name).rotation)
        for name in ("stream_index", "t", "xy_deg", "xyz_int16", "reflectivity", "tag", "return_number",
                     "number_of_returns"):
            np.testing.assert_array_equal(getattr(one_run, name), getattr(alone, name), err_msg=name)
        for name in ("range_m", "xyz_sensor", "xyz_world"):
            np.testing.assert_allclose(getattr(one_run, name), getattr(alone, name), rtol=0, atol=1e-9,
                                       err_msg=name)


def test_frames_side_by_side_are_the_frames_one_by_one(mid70: SensorConfig, urban) -> None:
    caster = EmbreeCaster(urban.mesh)
    piped = list(LidarScanner(mid70, caster, urban.vehicle_pose, seed=3).frames(0.73))
    one_by_one = LidarScanner(mid70, caster, urban.vehicle_pose, seed=3)
    expected = [one_by_one.next_frame() for _ in range(7)]
    expected.append(one_by_one.cast(one_by_one.pattern.take(3000)))  # the partial last frame
    assert [frame_key(f) for f in piped] == [frame_key(f) for f in expected]


def test_stopping_early_puts_the_stream_back(mid70: SensorConfig, urban) -> None:
    caster = EmbreeCaster(urban.mesh)
    scanner = LidarScanner(mid70, caster, urban.vehicle_pose, seed=3)
    frames = scanner.frames(2.0)
    first = [next(frames) for _ in range(3)]
    assert scanner.time == pytest.approx(0.3)  # the caller's place, though frames ahead are in flight
    assert scanner.pattern.position > 3 * mid70.points_per_frame
    frames.close()
    assert scanner.pattern.position == 3 * mid70.points_per_frame and scanner.time == pytest.approx(0.3)
    fresh = LidarScanner(mid70, caster, urban.vehicle_pose, seed=3)
    expected = [fresh.next_frame() for _ in range(5)]
    assert [frame_key(f) for f in first] == [frame_key(f) for f in expected[:3]]
    assert [frame_key(f) for f in scanner.frames(0.5)] == [frame_key(f) for f in expected[3:]]


@pytest.mark.parametrize("where", ["first batch", "later batch"])
def test_a_failing_cast_reaches_the_caller_and_the_stream_is_put_back(mid70: SensorConfig, urban, where: str) -> None:
    """A failing run is cast again frame by frame from its own rays (also in a batch that does not start the
    stream): the frames before the failing one are handed out, equal to the frames cast one by one, then the error
    reaches the caller and the stream is put back after the last frame handed out."""
    from livox_viz.casting import scan

    real = EmbreeCaster(urban.mesh)
    per_frame = mid70.points_per_frame
    failing = 4 if where == "first batch" else -(-scan.TASK_RAYS // per_frame) + 2
    scanner = LidarScanner(mid70, real, urban.vehicle_pose, seed=1)
    # Ray 123 of the failing frame, as the scanner will cast it (frames are cast side by side, in no fixed order;
    # a frame's first ray is the pattern's centre, the same in every frame).
    xy = make_pattern(mid70, seed=1).points(failing * per_frame + 123, 1).xy_deg
    target = directions_from_xy(xy)[0] @ scanner.sensor_pose.rotation.T

    class FailsOnOneFrame:
        # Whatever run holds that ray fails: a worker's batch of frames cast as one run, then that frame alone.
        def distances(self, origins, directions, max_distance=np.inf):
            if np.any(np.all(np.abs(directions - target) <= 1e-12, axis=1)):
                raise RuntimeError("the cast of the failing frame fails")
            return real.distances(origins, directions, max_distance)

    scanner = LidarScanner(mid70, FailsOnOneFrame(), urban.vehicle_pose, seed=1)
    handed = []
    with pytest.raises(RuntimeError, match="failing frame"):
        for frame in scanner.frames(3.0):
            handed.append(frame)
    assert [frame.index for frame in handed] == list(range(failing))
    assert scanner.pattern.position == failing * per_frame
    one_by_one = LidarScanner(mid70, real, urban.vehicle_pose, seed=1)
    for frame in handed:
        expected = one_by_one.next_frame()
        assert (frame.index, frame.ray_count) == (expected.index, expected.ray_count)
        np.testing.assert_array_equal(frame.stream_index, expected.stream_index)
        np.testing.assert_array_equal(frame.xyz_int16, expected.xyz_int16)


def test_small_frames_go_a_few_to_a_worker_and_stay_in_order(urban) -> None:
    from tests.conftest import small_config

    cfg = small_config()  # 160 points a frame, 10 frames a second: 26 frames to a worker
    caster = EmbreeCaster(urban.mesh)
    piped = LidarScanner(cfg, caster, urban.vehicle_pose, seed=2)
    frames = piped.frames(5.0)
    first = [next(frames) for _ in range(30)]  # stops inside the second worker's batch
    frames.close()
    assert piped.pattern.position == 30 * cfg.points_per_frame
    one_by_one = LidarScanner(cfg, caster, urban.vehicle_pose, seed=2)
    expected = [one_by_one.next_frame() for _ in range(40)]
    assert [frame_key(f) for f in first] == [frame_key(f) for f in expected[:30]]
    assert [frame_key(f) for f in piped.frames(4.0)] == [frame_key(f) for f in expected[30:40]]


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_a_caster_asked_from_an_origin_moved_along_one_axis_casts_from_it(axis: int) -> None:
    """The caster keeps its float32 origins between calls from one origin: moving it along any single axis must
    be seen (a key made of the wrong components casts later calls from the first origin). Inside a 100 m box,
    the distance along d from o is min over the axes of (50 - o_i) / d_i, here in closed form."""
    import trimesh

    from livox_viz.scene.raycast import EmbreeCaster

    caster = EmbreeCaster(trimesh.creation.box((100.0, 100.0, 100.0)))
    other = (axis + 1) % 3
    direction = np.zeros(3)
    direction[axis], direction[other] = 0.6, 0.8
    directions = np.tile(direction, (5000, 1))
    moved = np.zeros(3)
    moved[axis] = 20.0
    # Alternate the two origins: whichever worker thread casts a part, some call finds the other origin kept.
    for origin in (np.zeros(3), moved) * 4:
        expected = min((50.0 - origin[axis]) / 0.6, (50.0 - origin[other]) / 0.8)
        np.testing.assert_allclose(caster.distances(origin, directions), expected, rtol=1e-5)
