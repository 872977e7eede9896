"""The live wire under hostile but realistic use: endless publishing, signals during a recording, garbage poses,
restarted senders, two senders at once (issue 15)."""

from __future__ import annotations

import math
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import laspy
import numpy as np
import pytest

from livox_viz.cli import main
from livox_viz.config.presets import load_preset
from livox_viz.core.rotations import flu_from_frd
from livox_viz.wire.rflysim import (
    Reassembler,
    SharedMemoryLink,
    pack_payload,
    shm_path,
    shm_size,
    split_datagrams,
)
from livox_viz.wire.transport import ShmReceiver, UdpReceiver, UdpSender

from .conftest import free_udp_port, wait_until_bound
from .readers import read_pcd


def random_points(count: int, seed: int) -> np.ndarray:
    return np.random.default_rng(seed).integers(-32767, 32768, size=(count, 3)).astype(np.int16)


class Listening:
    """``livox-viz listen ARGV`` in a thread, keeping its exit status."""

    def __init__(self, argv: list[str]) -> None:
        self.status: int | None = None
        self.thread = threading.Thread(target=self._run, args=(argv,))
        self.thread.start()
        wait_until_bound(int(argv[argv.index("--port") + 1]), self.thread.is_alive)

    def _run(self, argv: list[str]) -> None:
        self.status = main(["listen", *argv])

    def join(self) -> int | None:
        self.thread.join(30)
        assert not self.thread.is_alive()
        return self.status


def _stderr_lines(process: subprocess.Popen) -> tuple[list[str], threading.Thread]:
    """Collect a child's stderr in the background (so its pipe never fills); join the thread for the rest."""
    lines: list[str] = []

    def pump() -> None:
        for line in process.stderr:
            lines.append(line)

    thread = threading.Thread(target=pump, daemon=True)
    thread.start()
    return lines, thread


def _end(process: subprocess.Popen) -> None:
    """Kill a child still running (a failed test) and close its pipes."""
    if process.poll() is None:
        process.kill()
    process.wait()
    for pipe in (process.stdout, process.stderr):
        if pipe is not None:
            pipe.close()


def _wait_for(condition, seconds: float = 60.0) -> None:
    deadline = time.monotonic() + seconds
    while not condition():
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.05)


# 1. publish --seconds forever ------------------------------------------------------------------
@pytest.mark.parametrize(("pacing", "signum"), [(["--speed", "4"], signal.SIGINT), (["--unpaced"], signal.SIGTERM)])
def test_publish_forever_over_udp_runs_until_stopped(tmp_path: Path, pacing: list[str], signum: int) -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sink:
        sink.bind(("127.0.0.1", 0))
        sink.settimeout(30)
        port = sink.getsockname()[1]
        process = subprocess.Popen([sys.executable, "-m", "livox_viz", "publish", "--to", f"127.0.0.1:{port}",
                                    "--seconds", "forever", "--scene", "open_field", *pacing],
                                   cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            reassembler = Reassembler()
            frames = 0
            while frames < 12:  # past a second of scan time: it does not stop at a first chunk
                done = reassembler.feed(sink.recv(65536))
                frames += done is not None
            assert process.poll() is None
            process.send_signal(signum)
            out, err = process.communicate(timeout=30)
        finally:
            _end(process)
    assert process.returncode == 128 + signum, err
    assert "Traceback" not in err
    sent = int(out.split("sent ")[1].split()[0])
    assert sent >= 12 and f"stopped by {'Ctrl-C' if signum == signal.SIGINT else 'SIGTERM'}" in err


def test_endless_frames_are_whole_across_chunks() -> None:
    from livox_viz.casting.scan import LidarScanner
    from livox_viz.cli.wire_commands import endless_frames
    from livox_viz.scene.raycast import EmbreeCaster
    from livox_viz.scene.scenes import open_scene

    from .conftest import small_config

    config = small_config()
    scene = open_scene("open_field")
    scanner = LidarScanner(config, EmbreeCaster(scene.mesh), scene.vehicle_pose)
    frames = [frame for _, frame in zip(range(7), endless_frames(scanner, chunk_frames=2), strict=False)]
    assert [frame.index for frame in frames] == list(range(7))
    np.testing.assert_allclose([frame.timestamp for frame in frames], np.arange(7) / config.data_check_freq)
    np.testing.assert_allclose([frame.end_time - frame.timestamp for frame in frames], 1 / config.data_check_freq)


def test_publish_forever_into_shared_memory_until_hang_up(tmp_path: Path) -> None:
    config = load_preset("livox_mid70")  # SendProtocol[0] = 0: shared memory
    process = subprocess.Popen([sys.executable, "-m", "livox_viz", "publish", "--seconds", "forever",
                                "--shm-dir", str(tmp_path), "--scene", "open_field", "--speed", "4"],
                               cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    block = shm_path(config.seq_id, tmp_path)
    try:
        _wait_for(lambda: (block.exists() and block.stat().st_size == shm_size(config)) or process.poll() is not None)
        assert process.poll() is None, process.communicate()
        reader = SharedMemoryLink(block, shm_size(config))
        times = []
        deadline = time.monotonic() + 60
        while len(times) < 8 and time.monotonic() < deadline:
            frame = reader.read()
            if frame is not None:
                times.append(frame.timestamp)
            time.sleep(0.01)
        reader.close()
        process.send_signal(signal.SIGHUP)
        out, err = process.communicate(timeout=30)
    finally:
        _end(process)
    assert len(times) == 8 and times == sorted(times) and times[-1] >= 0.7
    assert process.returncode == 128 + signal.SIGHUP, err
    assert "Traceback" not in err and "sent " in out and "send errors" not in out  # none happened


# 2. A recording survives SIGTERM and SIGHUP -----------------------------------------------------
def _send_frames(port: int, frames: list[tuple[float, np.ndarray, np.ndarray]]) -> None:
    sender = UdpSender("127.0.0.1", port)
    try:
        for timestamp, pose, points in frames:
            sender.send(timestamp, pose, points)
            time.sleep(0.02)
    finally:
        sender.close()


def _three_frames() -> list[tuple[float, np.ndarray, np.ndarray]]:
    return [(0.1 * k, np.array([k, 2.0, -3.0, 0.1, -0.2, 0.3 * k]), random_points(500 + k, k)) for k in range(3)]


@pytest.mark.parametrize(("signum", "suffix"), [(signal.SIGTERM, ".npz"), (signal.SIGHUP, ".las"),
                                                (signal.SIGTERM, ".pcd"), (signal.SIGINT, ".npz")])
def test_a_recording_is_kept_on_terminate_and_hang_up(tmp_path: Path, signum: int, suffix: str) -> None:
    port = free_udp_port()
    out = tmp_path / f"rec{suffix}"
    process = subprocess.Popen([sys.executable, "-m", "livox_viz", "listen", "--host", "127.0.0.1", "--port",
                                str(port), "--record", str(out)], cwd=tmp_path, stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True)
    try:
        assert "listening on" in process.stderr.readline()
        lines, pump = _stderr_lines(process)
        frames = _three_frames()
        _send_frames(port, frames)
        _wait_for(lambda: any(line.startswith("3 frames") for line in lines), 20)
        process.send_signal(signum)
        process.wait(timeout=30)
        pump.join(10)
        stdout = process.stdout.read()
    finally:
        _end(process)
    err = "".join(lines)
    # Ctrl-C is listen's documented way to stop (exit 0); SIGTERM and SIGHUP give the shell's 128 + signal.
    assert process.returncode == (0 if signum == signal.SIGINT else 128 + signum), err
    name = "Ctrl-C" if signum == signal.SIGINT else signal.Signals(signum).name
    assert f"stopped by {name}" in err and f"{out} was kept" in err
    assert "removed" not in err and "Traceback" not in err
    assert "received 3 frames" in stdout
    assert sorted(p.name for p in tmp_path.iterdir()) == [out.name]  # no temporaries left
    config = load_preset("livox_mid70")
    step = config.range_max / 32767
    expected = np.concatenate([points for _, _, points in frames]) * step
    if suffix == ".npz":
        data = np.load(out)
        np.testing.assert_array_equal(data["xyz_int16"], np.concatenate([p for _, _, p in frames]))
        np.testing.assert_array_equal(data["frame_pose"][:, 0], [0, 1, 2])
    elif suffix == ".las":
        las = laspy.read(out)
        got = np.column_stack([las.x, las.y, las.z])
        np.testing.assert_allclose(got, flu_from_frd(expected), atol=1e-4)  # a LAS is z-up: sensor FLU
    else:
        fields = read_pcd(out)
        np.testing.assert_allclose(np.column_stack([fields["x"], fields["y"], fields["z"]]), expected, atol=1e-4)


def test_a_recording_under_nohup_outlives_the_hang_up(tmp_path: Path) -> None:
    nohup = shutil.which("nohup")
    assert nohup, "coreutils' nohup is missing"
    port = free_udp_port()
    out = tmp_path / "rec.npz"
    process = subprocess.Popen([nohup, sys.executable, "-m", "livox_viz", "listen", "--host", "127.0.0.1", "--port",
                                str(port), "--record", str(out)], cwd=tmp_path, stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True)
    try:
        lines, pump = _stderr_lines(process)
        _wait_for(lambda: any("listening on" in line for line in lines), 60)
        frames = _three_frames()
        _send_frames(port, frames[:2])
        process.send_signal(signal.SIGHUP)  # the terminal went away: nohup said to ignore it
        time.sleep(0.5)
        assert process.poll() is None
        _send_frames(port, frames[2:])
        _wait_for(lambda: any(line.startswith("3 frames") for line in lines), 20)
        process.send_signal(signal.SIGTERM)
        process.wait(timeout=30)
        pump.join(10)
    finally:
        _end(process)
    assert process.returncode == 128 + signal.SIGTERM, "".join(lines)
    np.testing.assert_array_equal(np.load(out)["frame_pose"][:, 0], [0, 1, 2])


@pytest.mark.parametrize("suffix", [".npz", ".pcd"])
def test_a_full_disk_ends_the_recording_with_the_frames_received_before(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], suffix: str) -> None:
    """The disk fills after two frames: listening stops with status 1, says so, and the recording holds the two
    frames (and only their rows in the NPZ's receiving table) instead of being lost."""
    from livox_viz.files import export

    asked: list[int] = []

    def free(folder: str) -> int:
        asked.append(1)
        return 1 << 40 if len(asked) <= 2 else 0

    monkeypatch.setattr(export, "free_bytes", free)
    port = free_udp_port()
    out = tmp_path / f"rec{suffix}"
    listener = Listening(["--host", "127.0.0.1", "--port", str(port), "--frames", "10", "--timeout", "20",
                          "--record", str(out)])
    frames = _three_frames()
    _send_frames(port, frames)
    assert listener.join() == 1  # at the third frame, not after ten or the timeout
    err = capsys.readouterr().err
    assert f"{out}: the disk is full (0.0 MiB free" in err and "the 2 frames received before are kept" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == [out.name]
    step = load_preset("livox_mid70").range_max / 32767
    if suffix == ".npz":
        data = np.load(out)
        np.testing.assert_array_equal(data["xyz_int16"], np.concatenate([p for _, _, p in frames[:2]]))
        np.testing.assert_array_equal(data["received_frames"][:, 0], [0, 1])
        np.testing.assert_array_equal(data["frame_pose"][:, 0], [0, 1])
    else:
        fields = read_pcd(out)
        np.testing.assert_allclose(np.column_stack([fields["x"], fields["y"], fields["z"]]),
                                   np.concatenate([p for _, _, p in frames[:2]]) * step, atol=1e-4)


# 3. A datagram whose posAng is NaN or inf --------------------------------------------------------
def test_a_frame_with_a_nan_or_infinite_pose_is_dropped_and_counted(tmp_path: Path,
                                                                    capsys: pytest.CaptureFixture[str]) -> None:
    port = free_udp_port()
    out = tmp_path / "x.npz"
    listener = Listening(["--host", "127.0.0.1", "--port", str(port), "--frames", "3", "--timeout", "10",
                          "--record", str(out)])
    good = _three_frames()
    bad_nan = (0.05, np.array([0.0, math.nan, 0.0, 0.0, 0.0, 0.0]), random_points(100, 7))
    bad_inf = (0.15, np.array([0.0, 0.0, 0.0, 0.0, math.inf, 0.0]), random_points(100, 8))
    _send_frames(port, [good[0], bad_nan, good[1], bad_inf, good[2]])
    assert listener.join() == 0
    captured = capsys.readouterr()
    assert "received 3 frames" in captured.out and "2 dropped (posAng not finite 2)" in captured.out
    assert "posAng not finite" in captured.err  # the live line says why
    data = np.load(out)
    np.testing.assert_array_equal(data["xyz_int16"], np.concatenate([p for _, _, p in good]))
    np.testing.assert_allclose(data["frame_pose"][:, 1:7], np.array([pose for _, pose, _ in good]), atol=1e-6)


def test_shared_memory_with_a_nan_pose_or_time_is_dropped_and_counted(tmp_path: Path) -> None:
    config = load_preset("livox_mid70")
    writer = SharedMemoryLink(shm_path(config.seq_id, tmp_path), shm_size(config), create=True)
    receiver = ShmReceiver(config, str(tmp_path))
    try:
        assert writer.write(math.nan, np.zeros(6), random_points(10, 1))
        assert receiver.poll() == []
        assert writer.write(0.1, np.array([0, 0, 0, math.nan, 0, 0]), random_points(10, 2))
        assert receiver.poll() == []
        assert writer.write(0.2, np.arange(6.0), random_points(10, 3))
        assert [f.timestamp for f in receiver.poll()] == [0.2]
        assert receiver.assembler.drops == {"timestamp not finite": 1, "posAng not finite": 1}
    finally:
        receiver.close()
        writer.close()


# 4. A sender that restarts -------------------------------------------------------------------------
def _publish(port: int, seconds: str = "0.3") -> None:
    assert main(["publish", "--to", f"127.0.0.1:{port}", "--seconds", seconds, "--speed", "5",
                 "--scene", "open_field"]) == 0


def test_a_sender_restart_gets_new_frame_numbers_and_is_marked(tmp_path: Path,
                                                               capsys: pytest.CaptureFixture[str]) -> None:
    port = free_udp_port()
    out = tmp_path / "rec.npz"
    listener = Listening(["--host", "127.0.0.1", "--port", str(port), "--frames", "6", "--timeout", "20",
                          "--record", str(out)])
    _publish(port)
    time.sleep(0.3)
    _publish(port)  # the publisher restarts: frames 0..2 and t from 0 again
    assert listener.join() == 0
    assert "2 sender sessions (new senders 1, restarts 0)" in capsys.readouterr().out
    data = np.load(out)
    per_frame = data["received_frames"]
    # One row per received frame: index, session, sender frame, sender time, recording time.
    np.testing.assert_array_equal(per_frame[:, 0], np.arange(6))
    np.testing.assert_array_equal(per_frame[:, 1], [0, 0, 0, 1, 1, 1])
    np.testing.assert_array_equal(per_frame[:, 2], [0, 1, 2, 0, 1, 2])
    np.testing.assert_allclose(per_frame[:, 3], [0.0, 0.1, 0.2, 0.0, 0.1, 0.2])
    assert np.all(np.diff(per_frame[:, 4]) > 0)  # the recording's time never goes back
    # Within a session the recording's time steps like the sender's; the restart costs at least a frame.
    np.testing.assert_allclose(np.diff(per_frame[:3, 4]), 0.1)
    np.testing.assert_allclose(np.diff(per_frame[3:, 4]), 0.1)
    assert per_frame[3, 4] - per_frame[2, 4] >= 0.1
    np.testing.assert_array_equal(data["frame_pose"][:, 0], np.arange(6))  # unique frame_pose indices
    # A restarted publisher sends from a new port: a new session, named by its address.
    sources = list(data["session_source"])
    assert len(sources) == len(set(sources)) == 2 and all(s.startswith("127.0.0.1:") for s in sources)
    # Per point: the unique index, the sender's own number and time, the recording's time.
    frame, sender_frame = data["frame"], data["sender_frame"]
    assert np.all(np.diff(frame) >= 0) and set(frame) == set(range(6))
    starts = np.searchsorted(frame, np.arange(6))
    np.testing.assert_array_equal(sender_frame[starts], [0, 1, 2, 0, 1, 2])
    np.testing.assert_array_equal(data["sender_time"][starts], per_frame[:, 3])
    np.testing.assert_array_equal(data["t"][starts], per_frame[:, 4])
    np.testing.assert_array_equal(data["session"][starts], [0, 0, 0, 1, 1, 1])


@pytest.mark.parametrize("suffix", [".las", ".csv", ".pcd", ".ply"])
def test_restart_columns_in_every_format(tmp_path: Path, suffix: str, capsys: pytest.CaptureFixture[str]) -> None:
    port = free_udp_port()
    out = tmp_path / f"rec{suffix}"
    listener = Listening(["--host", "127.0.0.1", "--port", str(port), "--frames", "4", "--timeout", "20",
                          "--record", str(out)])
    frames = _three_frames()
    # One sender (one address) whose clock starts again at 0: RflySim restarting its simulation.
    _send_frames(port, [frames[0], frames[1], frames[0], frames[2]])
    assert listener.join() == 0
    assert "2 sender sessions (new senders 0, restarts 1)" in capsys.readouterr().out
    sizes = [len(points) for _, _, points in (frames[0], frames[1], frames[0], frames[2])]
    want = {
        "frame": np.repeat([0, 1, 2, 3], sizes),
        "sender_frame": np.repeat([0, 1, 0, 2], sizes),
        "sender_time": np.repeat([0.0, 0.1, 0.0, 0.2], sizes),
        "session": np.repeat([0, 0, 1, 1], sizes),
    }
    if suffix == ".las":
        las = laspy.read(out)
        got = {name: np.asarray(las[name]) for name in want}
        got["sender_time"] = np.asarray(las["sender_time"])
        times = np.asarray(las.gps_time)
    elif suffix == ".csv":
        table = np.genfromtxt(out, delimiter=",", names=True)
        got = {name: table[name] for name in want}
        times = table["time"]
    elif suffix == ".pcd":
        got = read_pcd(out)
        times = got["time"]
    else:
        got = _read_binary_ply(out)
        times = got["time"]
    for name, expected in want.items():
        np.testing.assert_allclose(got[name], expected, atol=1e-6, err_msg=name)
    assert np.all(np.diff(times) >= 0) and times[-1] > times[sizes[0] + sizes[1]]


def _read_binary_ply(path: Path) -> dict[str, np.ndarray]:
    """A binary little-endian PLY vertex list, read from its header's declared properties."""
    types = {"float": "<f4", "double": "<f8", "uint": "<u4", "int": "<i4", "uchar": "u1"}
    raw = path.read_bytes()
    header, body = raw.split(b"end_header\n", 1)
    lines = header.decode().splitlines()
    count = int(next(line for line in lines if line.startswith("element vertex")).split()[2])
    dtype = np.dtype([(line.split()[2], types[line.split()[1]]) for line in lines if line.startswith("property")])
    records = np.frombuffer(body, dtype=dtype, count=count)
    return {name: records[name] for name in dtype.names}


# 5. Two senders with the same timestamps ---------------------------------------------------------
def test_two_sources_with_the_same_timestamp_are_reassembled_apart() -> None:
    first, second = random_points(25_000, 1), random_points(24_000, 2)
    pose_a, pose_b = np.arange(6.0), -np.arange(6.0)
    a = split_datagrams(pack_payload(pose_a, first), 0.5)
    b = split_datagrams(pack_payload(pose_b, second), 0.5)
    assert len(a) == len(b) == 3
    reassembler = Reassembler()
    done = []
    for one, other in zip(a, b, strict=True):
        for source, datagram in ((("10.0.0.1", 5000), one), (("10.0.0.2", 5000), other)):
            result = reassembler.feed(datagram, source)
            if result is not None:
                done.append(result)
    assert [payload for _, payload in done] == [pack_payload(pose_a, first), pack_payload(pose_b, second)]
    assert reassembler.restarts == 0 and not reassembler.drops


def test_two_udp_senders_at_once_arrive_as_their_own_frames() -> None:
    receiver = UdpReceiver("127.0.0.1", 0)
    points = {0: random_points(30_000, 3), 1: random_points(20_000, 4)}
    poses = {0: np.array([1.0, 2, 3, 0, 0, 0]), 1: np.array([-5.0, 0, 1, 0, 0, 1])}
    senders = [socket.socket(socket.AF_INET, socket.SOCK_DGRAM) for _ in range(2)]
    try:
        chunks = {k: split_datagrams(pack_payload(poses[k], points[k]), 1.0) for k in (0, 1)}
        for one, other in zip(chunks[0], chunks[1], strict=False):
            senders[0].sendto(one, ("127.0.0.1", receiver.port))
            senders[1].sendto(other, ("127.0.0.1", receiver.port))
        for rest in chunks[0][len(chunks[1]):]:
            senders[0].sendto(rest, ("127.0.0.1", receiver.port))
        time.sleep(0.2)
        frames = receiver.poll()
        sources = {f"127.0.0.1:{s.getsockname()[1]}": k for k, s in enumerate(senders)}
    finally:
        for sender in senders:
            sender.close()
        receiver.close()
    assert len(frames) == 2
    for frame in frames:
        k = sources[frame.source]
        np.testing.assert_array_equal(frame.xyz_int16, points[k])
        np.testing.assert_allclose(frame.pos_ang, poses[k])
    assert {frame.source for frame in frames} == set(sources)


def test_interleaved_senders_are_not_restarts(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Two senders whose clocks differ are two sessions, not a restart every other frame."""
    port = free_udp_port()
    out = tmp_path / "two.npz"
    listener = Listening(["--host", "127.0.0.1", "--port", str(port), "--frames", "6", "--timeout", "20",
                          "--record", str(out)])
    senders = [UdpSender("127.0.0.1", port) for _ in range(2)]
    try:
        for k in range(3):
            senders[0].send(10.0 + 0.1 * k, np.zeros(6), random_points(50, k))
            senders[1].send(0.1 * k, np.ones(6), random_points(60, k))
            time.sleep(0.02)
    finally:
        for sender in senders:
            sender.close()
    assert listener.join() == 0
    captured = capsys.readouterr()
    assert "2 sender sessions (new senders 1, restarts 0)" in captured.out
    assert "senders 2" in captured.err and "sender restarts" not in captured.err
    per_frame = np.load(out)["received_frames"]
    np.testing.assert_array_equal(per_frame[:, 1], [0, 1, 0, 1, 0, 1])
    np.testing.assert_allclose(per_frame[:, 3], [10.0, 0.0, 10.1, 0.1, 10.2, 0.2])



def test_frames_sent_to_the_broadcast_address_arrive() -> None:
    """``publish --to 255.255.255.255:PORT`` feeds every listener of the LAN; the send was refused before."""
    receiver = UdpReceiver("0.0.0.0", 0)
    sender = UdpSender("255.255.255.255", receiver.port)
    points = random_points(40, 3)
    try:
        assert sender.send(0.5, np.zeros(6), points) >= 1 and sender.errors == 0, sender.last_error
        deadline = time.monotonic() + 10.0
        frame = next(iter(receiver.frames(lambda: time.monotonic() > deadline)), None)
    finally:
        sender.close()
        receiver.close()
    assert frame is not None
    np.testing.assert_array_equal(frame.xyz_int16, points)
