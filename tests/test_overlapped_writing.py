"""Writing beside scanning: each output on a thread of its own writes the bytes the scan's own thread wrote,
every frame in order, with what waits bounded; a failed writer stops the scan with its error."""

from __future__ import annotations

import threading
import time
from pathlib import Path

import pytest

from livox_viz import load_preset
from livox_viz.casting.scan import LidarScanner
from livox_viz.cli import main, scan_commands
from livox_viz.files import export
from livox_viz.files.overlap import OverlappedWriting, WriterThread
from livox_viz.scene.scenes import open_scene


@pytest.fixture(scope="module")
def frames() -> list:
    scene = open_scene("urban")
    return list(LidarScanner(load_preset("livox_mid70"), scene.mesh, scene.vehicle_pose, seed=5).frames(0.3))


class SerialWriting:
    """What ``scan`` did before its writers had threads: each frame written in the scan's own thread."""

    def __init__(self, sinks) -> None:
        self.sinks = list(sinks)

    def write(self, frame) -> None:
        for sink in self.sinks:
            sink.write(frame)

    def __enter__(self) -> SerialWriting:
        return self

    def __exit__(self, *exc) -> None:
        pass


def _files(folder: Path) -> dict[str, bytes]:
    return {str(path.relative_to(folder)): path.read_bytes() for path in sorted(folder.rglob("*")) if path.is_file()}


@pytest.mark.parametrize("argv", [["--out", "cloud.npz"], ["--out", "cloud.ply"], ["--out", "cloud.pcd", "--ascii"],
                                  ["--out", "cloud.las", "--frame", "world"], ["--out", "cloud.csv"],
                                  ["--rosbag", "bag", "--trajectory", "line"]])
def test_scan_writes_the_same_bytes_on_writer_threads_as_in_its_own_thread(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, argv: list[str]) -> None:
    made = {}
    for how in ("serial", "overlapped"):
        folder = tmp_path / how
        folder.mkdir()
        monkeypatch.chdir(folder)
        with monkeypatch.context() as patch:
            if how == "serial":
                patch.setattr(scan_commands, "OverlappedWriting", SerialWriting)
            assert main(["scan", "--preset", "livox_mid70_risley", "--seconds", "0.4", "--seed", "2", *argv]) == 0
        made[how] = _files(folder)
    assert made["serial"] and sum(len(data) for data in made["serial"].values()) > 100_000
    assert made["overlapped"] == made["serial"]


class SlowSink:
    """A writer slower than the scan: each frame takes a little while, and what it got is kept."""

    def __init__(self, fail_at: int | None = None) -> None:
        self.got: list[int] = []
        self.fail_at = fail_at
        self.most_waiting = 0

    def write(self, frame) -> None:
        time.sleep(0.002)
        if self.fail_at is not None and len(self.got) == self.fail_at:
            raise export.WritingStopped("the disk is full")
        self.got.append(frame.index)


def test_a_writer_thread_writes_every_frame_in_order_and_bounds_what_waits(frames: list) -> None:
    sink = SlowSink()
    thread = WriterThread(sink, waiting_points=len(frames[0]) + 1)
    for frame in frames * 5:
        thread.write(frame)
        with thread._changed:  # never more than the bound (or one frame) waits
            assert thread._points <= max(thread.waiting_points, len(frame))
    thread.finish()
    assert sink.got == [frame.index for frame in frames * 5]


def test_empty_frames_wait_for_a_slow_writer_in_a_bounded_number() -> None:
    """Frames of no point were never held back (the bound counted points): a 1 x 1 x 1000 Hz scan queued them
    without end behind its writer (issue 47)."""
    empty = [type("Frame", (), {"index": k, "__len__": lambda self: 0})() for k in range(200)]
    sink = SlowSink()
    thread = WriterThread(sink, waiting_frames=8)
    for frame in empty:
        thread.write(frame)
        with thread._changed:
            assert len(thread._frames) <= 8
    thread.finish()
    assert sink.got == list(range(200))


def test_a_failed_writer_stops_the_scan_with_its_error_and_the_others_finish(frames: list) -> None:
    good, bad = SlowSink(), SlowSink(fail_at=2)
    with pytest.raises(export.WritingStopped, match="disk is full"):
        with OverlappedWriting([good, bad]) as writing:
            for frame in frames * 4:
                writing.write(frame)
    assert bad.got == [frames[0].index, frames[1].index]
    assert not any(thread._thread.is_alive() for thread in writing.threads)


def test_leaving_by_an_error_drops_what_was_not_written(frames: list) -> None:
    sink = SlowSink()
    gate = threading.Event()
    original = sink.write
    sink.write = lambda frame: (gate.wait(5), original(frame))
    with pytest.raises(KeyboardInterrupt), OverlappedWriting([sink]) as writing:
        for frame in frames:
            writing.write(frame)
        gate.set()
        raise KeyboardInterrupt
    assert sink.got == [frames[0].index] or sink.got == []  # at most the frame in hand
