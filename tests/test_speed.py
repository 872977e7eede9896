"""The fast paths of issue 19 compute what the plain ones do: BLAS pinning, the Risley block product, times on
demand.

Speed itself is measured by the benchmarks, never here.
"""

from __future__ import annotations

import threading
from dataclasses import replace

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

from livox_viz import SensorConfig, load_preset
from livox_viz.core.blas import blas_threads, one_blas_thread
from livox_viz.patterns.factory import make_pattern
from livox_viz.patterns.risley import RisleyPattern, block_shape, risley_xy
from livox_viz.patterns.stream import PatternChunk


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
