"""The Risley stream's frame-by-frame path (issue 19): block phasors made in batches, frame buffers with their
views made once, chunks made without the dataclass's ``__init__``. Each must give what the plain path gives.

Speed itself is measured by ``benchmarks/bench_risley.py``, never here.
"""

from __future__ import annotations

import numpy as np
import pytest

from livox_viz import load_preset
from livox_viz.patterns.risley import _BATCH, RisleyPattern, risley_xy
from livox_viz.patterns.stream import PatternChunk


@pytest.fixture(scope="module")
def mid70_risley():
    """The preset whose frame (250 x 40) is one block of the stream."""
    config = load_preset("livox_mid70_risley")
    assert RisleyPattern(config)._block == config.points_per_frame
    return config


def test_frames_read_in_order_are_the_series_across_several_batches(mid70_risley) -> None:
    """Frames read one after another (block phasors made in batches) are the series summed term by term."""
    frames = 2 * _BATCH + 3  # past two batch boundaries
    stream = RisleyPattern(mid70_risley)
    per_frame = mid70_risley.points_per_frame
    stream.skip(5 * per_frame)  # not starting at zero
    xy = np.concatenate([stream.next_frame().xy_deg for _ in range(frames)])
    k = 5 * per_frame + np.arange(frames * per_frame)
    np.testing.assert_allclose(xy, risley_xy(mid70_risley.risley, k / mid70_risley.point_rate), atol=1e-9)


def test_a_frame_is_the_same_bit_for_bit_however_the_frames_are_visited(mid70_risley) -> None:
    """In order (batched), backwards and by jumps (each frame's phasors made alone): the same numbers."""
    per_frame = mid70_risley.points_per_frame
    frames = _BATCH + 5
    in_order = RisleyPattern(mid70_risley)
    forward = [in_order.next_frame().xy_deg for _ in range(frames)]
    backward = RisleyPattern(mid70_risley)
    for index in reversed(range(frames)):
        np.testing.assert_array_equal(backward.points(index * per_frame, per_frame).xy_deg, forward[index])
    jumping = RisleyPattern(mid70_risley)
    for index in (7, 3, _BATCH + 4, 0, _BATCH, 8, 9, 1):
        np.testing.assert_array_equal(jumping.points(index * per_frame, per_frame).xy_deg, forward[index])
    # A part of a frame comes from the whole block, made once and kept: the same numbers again.
    np.testing.assert_array_equal(jumping.points(9 * per_frame + 17, 500).xy_deg, forward[9][17:517])


def test_a_kept_frame_or_a_view_of_it_is_never_overwritten(mid70_risley) -> None:
    """A frame's buffer is handed out again only when neither its chunk nor a view of its points is held."""
    stream = RisleyPattern(mid70_risley)
    first = stream.next_frame()
    first_copy = first.xy_deg.copy()
    column = stream.next_frame().xy_deg[:, 0]  # only a view of the second frame's points is kept
    column_copy = column.copy()
    later = [stream.next_frame().xy_deg.copy() for _ in range(12)]  # the chunks themselves dropped
    np.testing.assert_array_equal(first.xy_deg, first_copy)
    np.testing.assert_array_equal(column, column_copy)
    assert not np.array_equal(later[0], later[1])  # frames differ, so an overwrite would show
    # Dropped chunks' buffers are reused: the stream holds a few frames, not one per frame made.
    assert len(stream._frames._free) <= stream._frames._KEEP


def test_a_dropped_frame_buffer_is_reused(mid70_risley) -> None:
    stream = RisleyPattern(mid70_risley)
    address = stream.next_frame().xy_deg.ctypes.data
    assert stream.next_frame().xy_deg.ctypes.data == address


def test_a_chunk_from_the_stream_is_the_chunk_init_makes(mid70_risley) -> None:
    """:meth:`PatternChunk.from_stream` fills the fields ``__init__`` fills: the same fields, times and labels."""
    xy = np.arange(20.0).reshape(10, 2)
    rotations = np.zeros(0)
    fast = PatternChunk.from_stream(mid70_risley, 12_345, xy, rotations)
    plain = PatternChunk(mid70_risley, 12_345, xy, None, rotations)
    assert fast.__dict__.keys() == plain.__dict__.keys()
    assert all(fast.__dict__[name] is value for name, value in plain.__dict__.items())
    np.testing.assert_array_equal(fast.t, np.arange(12_345, 12_355) / mid70_risley.point_rate)
    for name, labels in plain.labels().items():
        np.testing.assert_array_equal(fast.labels()[name], labels)
    with pytest.raises(AttributeError):
        fast.start = 0  # still frozen
