"""RflySim's wire formats: payloads, datagrams, reassembly, request, shared memory, loopback UDP."""

from __future__ import annotations

import itertools
import math
import socket
import struct
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from livox_viz import LivoxVizError, SensorConfig
from livox_viz.cli import main
from livox_viz.wire.rflysim import (
    DATAGRAM_HEADER,
    FRAME_CHECKSUM,
    Reassembler,
    SharedMemoryLink,
    pack_payload,
    parse_host_port,
    send_protocol_destination,
    sensor_request,
    shm_size,
    split_datagrams,
    unpack_payload,
)

from .conftest import free_udp_port, start_listening


def random_points(count: int, seed: int = 0) -> np.ndarray:
    """Reproducible int16 points, the same whatever ran before (no shared generator)."""
    return np.random.default_rng(seed).integers(-32767, 32768, size=(count, 3)).astype(np.int16)


def spec_decoder(payload: bytes, range_max: float) -> np.ndarray:
    """Written from the spec alone: PointNum at byte 24, int16 points from byte 28."""
    (count,) = struct.unpack_from("<i", payload, 24)
    return np.frombuffer(payload, dtype="<i2", offset=28).reshape(count, 3) / 32767 * range_max


def test_payload_round_trip_and_spec_decoder() -> None:
    points = random_points(12_345)
    pose = np.array([1.5, -2.0, -30.25, 0.1, -0.2, 3.0])
    payload = pack_payload(pose, points)
    assert len(payload) == 28 + 12_345 * 6
    frame = unpack_payload(payload, timestamp=0.7)
    assert np.array_equal(frame.xyz_int16, points)
    np.testing.assert_allclose(frame.pos_ang, pose, rtol=1e-6)
    np.testing.assert_array_equal(frame.decoded(600.0), spec_decoder(payload, 600.0))


def test_lying_point_count_is_rejected() -> None:
    payload = bytearray(pack_payload(np.zeros(6), random_points(10)))
    struct.pack_into("<i", payload, 24, 11)
    with pytest.raises(LivoxVizError, match="PointNum 11 but the payload holds 10"):
        unpack_payload(bytes(payload), 0.0)


def test_datagrams_have_the_header_and_size() -> None:
    payload = pack_payload(np.zeros(6), random_points(25_000))  # 150 028 bytes -> 3 chunks
    datagrams = split_datagrams(payload, 1.25)
    assert len(datagrams) == 3
    for index, datagram in enumerate(datagrams):
        checksum, length, chunk, count, stamp = DATAGRAM_HEADER.unpack_from(datagram)
        assert (checksum, length, chunk, count, stamp) == (FRAME_CHECKSUM, len(datagram), index, 3, 1.25)
        assert len(datagram) - 24 <= 60000
    assert b"".join(d[24:] for d in datagrams) == payload


def test_a_payload_of_whole_chunks_is_cut_into_exactly_that_many() -> None:
    """Chunks of at most ``max_chunk`` bytes: 120 bytes in 60-byte chunks are 2 datagrams, not a third empty one."""
    datagrams = split_datagrams(b"x" * 120, 0.0, max_chunk=60)
    assert len(datagrams) == 2 and b"".join(d[24:] for d in datagrams) == b"x" * 120


@pytest.mark.parametrize("order", list(itertools.permutations(range(3))))
def test_three_chunks_in_any_order(order: tuple[int, ...]) -> None:
    payload = pack_payload(np.zeros(6), random_points(25_000))
    datagrams = split_datagrams(payload, 2.0)
    assembler = Reassembler()
    results = [assembler.feed(datagrams[i]) for i in order]
    assert results[:2] == [None, None] and results[2] == (2.0, payload)


def _feed_all(assembler: Reassembler, datagram: bytes, source: object = None) -> list[tuple[float, bytes]]:
    """Every frame one datagram makes ready."""
    ready = []
    done = assembler.feed(datagram, source)
    while done is not None:
        ready.append(done)
        done = assembler.next_ready()
    return ready


def test_incomplete_and_stale_frames_are_dropped() -> None:
    """A frame missing a chunk holds the sender's later frames back until ``reorder_frames`` of them are complete;
    then it is given up, they come out in order, and its late chunk is stale."""
    assembler = Reassembler(reorder_frames=2)
    payloads = [pack_payload(np.zeros(6), random_points(25_000, seed=k)) for k in range(4)]
    frames = [split_datagrams(payload, 1.0 + k) for k, payload in enumerate(payloads)]
    assert len(frames[0]) == 3
    assert _feed_all(assembler, frames[0][0]) == []
    held = [r for d in frames[1] + frames[2] for r in _feed_all(assembler, d)]
    assert held == [] and assembler.drops["incomplete frame"] == 0  # two complete frames wait for the first
    assert assembler.pending_bytes == sum(len(d) - 24 for d in [frames[0][0], *frames[1], *frames[2]])
    released = [r for d in frames[3] for r in _feed_all(assembler, d)]
    assert released == [(2.0, payloads[1]), (3.0, payloads[2]), (4.0, payloads[3])]
    assert assembler.drops["incomplete frame"] == 1 and assembler.restarts == 0
    assert _feed_all(assembler, frames[0][1]) == [] and assembler.drops["stale chunk"] == 1
    assert assembler.pending_bytes == 0


@pytest.mark.parametrize("late", [1, 2])
def test_chunks_reordered_across_frames_give_every_frame_in_order(late: int) -> None:
    """The last chunk of a frame arrives after the whole next frame (``late`` frames later): nothing is lost,
    the frames come out in the order they were sent, and no restart is seen (RflySim's frames of a few
    datagrams each, on a network that reorders)."""
    assembler = Reassembler()
    payloads = [pack_payload(np.full(6, k, np.float32), random_points(15_000, seed=k)) for k in range(1 + late)]
    frames = [split_datagrams(payload, 0.1 * k) for k, payload in enumerate(payloads)]
    assert len(frames[0]) == 2
    order = [frames[0][0], *[d for frame in frames[1:] for d in frame], frames[0][1]]
    ready = [r for d in order for r in _feed_all(assembler, d)]
    assert ready == [(0.1 * k, payload) for k, payload in enumerate(payloads)]
    assert (assembler.frames, assembler.restarts, sum(assembler.drops.values())) == (1 + late, 0, 0)


def test_frames_of_two_senders_wait_only_for_their_own() -> None:
    """A frame missing a chunk holds back its own sender's later frames, never another sender's."""
    assembler = Reassembler()
    mine = [split_datagrams(pack_payload(np.zeros(6), random_points(15_000, seed=k)), 0.1 * k) for k in range(2)]
    other = split_datagrams(pack_payload(np.ones(6), random_points(10, seed=9)), 0.05)
    assert _feed_all(assembler, mine[0][0], "a") == []
    assert [r for d in mine[1] for r in _feed_all(assembler, d, "a")] == []
    assert [r[0] for r in _feed_all(assembler, other[0], "b")] == [0.05] and assembler.source == "b"
    ready = _feed_all(assembler, mine[0][1], "a")
    assert [r[0] for r in ready] == [0.0, 0.1] and assembler.source == "a"


@pytest.mark.parametrize(
    ("mutate", "reason"),
    [
        (lambda d: d[:10], "truncated header"),
        (lambda d: struct.pack("<i", 42) + d[4:], "wrong checksum"),
        (lambda d: d[:4] + struct.pack("<i", len(d) + 5) + d[8:], "length field"),
        (lambda d: d[:12] + struct.pack("<i", 0) + d[16:], "chunk count out of range"),
        (lambda d: d[:12] + struct.pack("<i", 10**9) + d[16:], "chunk count out of range"),
        (lambda d: d[:8] + struct.pack("<i", 7) + d[12:], "chunk index out of range"),
    ],
)
def test_garbage_datagrams_are_counted(mutate, reason: str) -> None:
    datagram = split_datagrams(pack_payload(np.zeros(6), random_points(10)), 0.5)[0]
    assembler = Reassembler()
    assert assembler.feed(mutate(datagram)) is None
    assert any(reason in key for key in assembler.drops), assembler.drops
    assert assembler.feed(datagram) is not None  # and it keeps working


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.one_of(
    st.binary(max_size=200),
    st.builds(lambda idx, cnt, ts, body: DATAGRAM_HEADER.pack(FRAME_CHECKSUM, 24 + len(body), idx, cnt, ts) + body,
              st.integers(-3, 5), st.integers(-2, 10**9), st.sampled_from([0.0, 0.1, 0.2, 7.5, -1.0, math.nan]),
              st.binary(max_size=250)),
), max_size=60))
def test_fuzzed_reassembler_never_crashes_or_grows(datagrams: list[bytes]) -> None:
    # A small budget the generated input can exceed: 60 bodies of up to 250 bytes on six timestamps.
    assembler = Reassembler(max_frame_bytes=400, max_pending=2, max_chunks=8)
    for datagram in datagrams:
        result = assembler.feed(datagram)
        if result is not None:
            assert isinstance(result[1], bytes) and len(result[1]) <= 400
        assert len(assembler._pending) <= 2
        assert assembler.pending_bytes <= 2 * (1 + assembler.reorder_frames) * 400  # each may hold later frames


def test_the_fuzz_bound_is_reachable() -> None:
    """Without the size limit the same kind of input would hold more than the bound."""
    body = bytes(250)
    datagrams = [DATAGRAM_HEADER.pack(FRAME_CHECKSUM, 24 + len(body), i, 5, 0.1) + body for i in range(4)]
    assembler = Reassembler(max_frame_bytes=400, max_pending=2, max_chunks=8)
    for datagram in datagrams:
        assembler.feed(datagram)
    assert assembler.drops["frame too large"] == 1 and assembler.pending_bytes <= 400
    unbounded = Reassembler(max_frame_bytes=10_000, max_pending=2, max_chunks=8)
    for datagram in datagrams:
        unbounded.feed(datagram)
    assert unbounded.pending_bytes == 1000 > 2 * 400


def frame_datagrams(timestamp: float, seed: int = 0) -> list[bytes]:
    return split_datagrams(pack_payload(np.zeros(6), random_points(25_000, seed)), timestamp)


def test_timestamps_going_back_are_a_restart_not_deafness() -> None:
    assembler = Reassembler()
    done = [assembler.feed(d) for t in (0.0, 0.1, 0.2, 0.3) for d in frame_datagrams(t)]
    assert sum(r is not None for r in done) == 4
    # The publisher restarts: its clock starts again at 0. Every frame of the new run arrives.
    again = [assembler.feed(d) for t in (0.0, 0.1, 0.2) for d in frame_datagrams(t, seed=2)]
    assert [r[0] for r in again if r is not None] == [0.0, 0.1, 0.2]
    assert assembler.restarts == 1 and "went back" in assembler.last_error


def test_one_forged_datagram_costs_no_frame() -> None:
    assembler = Reassembler()
    forged = struct.pack("<4i1d", 1234567890, 52, 0, 1, 1e300) + struct.pack("<6fi", 0, 0, 0, 0, 0, 0, 0)
    assert _feed_all(assembler, frame_datagrams(0.0)[0]) == []
    assert _feed_all(assembler, forged) == []  # a well-formed empty frame: it waits for the frame begun before
    delivered = [r for t in (0.1, 0.2) for d in frame_datagrams(t) for r in _feed_all(assembler, d)]
    # The incomplete first frame given up, the forged one is delivered in its place, and every later frame.
    assert [r[0] for r in delivered] == [1e300, 0.1, 0.2]


def test_a_duplicate_frame_is_dropped() -> None:
    assembler = Reassembler()
    datagrams = frame_datagrams(0.5)
    assert [assembler.feed(d) is not None for d in datagrams] == [False, False, True]
    assert all(assembler.feed(d) is None for d in datagrams)
    assert assembler.drops["duplicate frame"] == 1


def test_request_bytes_field_by_field(mid70: SensorConfig) -> None:
    data = sensor_request(mid70)
    assert len(data) == 92
    fields = struct.unpack("<16H15f", data)
    assert fields[:8] == (12345, 0, 6, 1, 0, 250, 40, 10)
    assert fields[8:16] == (0, 127, 0, 0, 1, 9999, 0, 0)
    assert fields[16] == pytest.approx(70.432, rel=1e-6)
    assert fields[17:20] == pytest.approx((0.0, 0.0, -0.3))
    assert fields[20:23] == (0.0, 0.0, 0.0)
    assert fields[23:31] == pytest.approx((600, 2.956, 1.4, 1.18, 10, 5, 1, 0), rel=1e-6)


def test_send_protocol_and_addresses(mid70: SensorConfig) -> None:
    destination = send_protocol_destination(mid70)
    assert (destination.transport, destination.host, destination.port) == ("shm", "127.0.0.1", 9999)
    from dataclasses import replace

    udp = replace(mid70, send_protocol=(1, 192, 168, 1, 20, 20100, 0, 0))
    assert send_protocol_destination(udp).transport == "udp"
    assert parse_host_port("127.0.0.1:9999") == ("127.0.0.1", 9999)
    assert parse_host_port("localhost", 20010) == ("localhost", 20010)
    for bad in ("127.0.0.1:x", "127.0.0.1:0", ":80", "host"):
        with pytest.raises(LivoxVizError):
            parse_host_port(bad)
    # An empty port ("HOST:$PORT" with PORT unset) went to the default port; int() took signs, "_" and any script's
    # digits.
    for bad in ("127.0.0.1:", "127.0.0.1: ", "127.0.0.1:+5", "127.0.0.1:1_000", "127.0.0.1: 80", "127.0.0.1:\u0663"):
        with pytest.raises(LivoxVizError, match="allowed: HOST alone for the default port, or HOST:PORT"):
            parse_host_port(bad, 20010)
        with pytest.raises(LivoxVizError, match="; allowed: HOST:PORT with PORT a number 1-65535"):
            parse_host_port(bad)
    # Split at the last colon, an IPv6 address was host ":" and port 1, and the request went nowhere.
    for ipv6 in ("::1", "[::1]:9999", "fe80::1"):
        with pytest.raises(LivoxVizError, match="is IPv6; allowed: an IPv4 address or a host name"):
            parse_host_port(ipv6, 20010)


def test_shared_memory_round_trip(tmp_path: Path, mid70: SensorConfig) -> None:
    path = tmp_path / "RflySim3DImg_0"
    writer = SharedMemoryLink(path, shm_size(mid70), create=True)
    reader = SharedMemoryLink(path, shm_size(mid70))
    assert path.stat().st_size == 250 * 40 * 6 + 37
    assert reader.read() is None
    points = random_points(9_000)
    assert writer.write(0.3, np.arange(6.0), points)
    frame = reader.read()
    assert frame is not None and np.array_equal(frame.xyz_int16, points) and frame.timestamp == 0.3
    assert path.read_bytes()[0] == 4  # the reader marked it done
    assert reader.read() is None
    path.write_bytes(b"\x03" + path.read_bytes()[1:])  # a reader is busy: the writer waits
    assert not writer.write(0.4, np.zeros(6), points)
    writer.close()
    reader.close()


def test_loopback_udp_publish_and_listen(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    port = free_udp_port()
    received = tmp_path / "received.npz"
    sent = tmp_path / "sent.npz"
    listener = start_listening(["--port", str(port), "--frames", "5", "--timeout", "20", "--record", str(received)])
    assert main(["publish", "--to", f"127.0.0.1:{port}", "--seconds", "0.5", "--speed", "10"]) == 0
    listener.join(30)
    assert not listener.is_alive()
    assert main(["scan", "--seconds", "0.5", "--out", str(sent)]) == 0
    got, want = np.load(received), np.load(sent)
    assert np.array_equal(got["xyz_int16"], want["xyz_int16"])
    assert np.array_equal(got["frame"], want["frame"])
    np.testing.assert_array_equal(got["xyz_sensor"], want["xyz_sensor"])


def test_listen_on_a_port_in_use(capsys: pytest.CaptureFixture[str]) -> None:
    busy = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    busy.bind(("127.0.0.1", 0))
    try:
        code = main(["listen", "--host", "127.0.0.1", "--port", str(busy.getsockname()[1]), "--frames", "1"])
    finally:
        busy.close()
    assert code == 2 and "in use" in capsys.readouterr().err


@pytest.mark.parametrize("host", ["::1", "192.0.2.1"])
def test_listen_on_an_address_it_cannot_bind_says_what_it_can(host: str, capsys: pytest.CaptureFixture[str]) -> None:
    # An IPv6 address, and another machine's (TEST-NET-1, never this machine's).
    code = main(["listen", "--host", host, "--port", "0", "--frames", "1"])
    err = capsys.readouterr().err
    assert code == 2 and f"cannot listen on {host}:0" in err and "allowed: an IPv4 address of this machine" in err
    assert "Traceback" not in err


def test_listen_on_a_port_the_system_refuses_names_the_port_not_the_address(
        monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    """Port 80 for a user who is not root (or a reserved port on Windows): the message blamed the address."""
    import errno

    def refuse(_sock: socket.socket, _address: object) -> None:
        raise PermissionError(errno.EACCES, "Permission denied")

    monkeypatch.setattr(socket.socket, "bind", refuse)
    code = main(["listen", "--host", "127.0.0.1", "--port", "80", "--frames", "1"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1, err
    assert "cannot listen on 127.0.0.1:80 (Permission denied): ports below 1024 need administrator rights" in err
    assert "allowed: a port from 1024 to 65535, or 0 for any free one" in err and "IPv4 address" not in err


def test_request_dry_run(capsys: pytest.CaptureFixture[str], mid70: SensorConfig) -> None:
    assert main(["request", "--to", "127.0.0.1", "--dry-run"]) == 0
    out = capsys.readouterr().out
    assert bytes.fromhex(out.split()[-1]) == sensor_request(mid70)


def test_request_to_the_broadcast_address_reaches_a_listener(capsys: pytest.CaptureFixture[str],
                                                             mid70: SensorConfig) -> None:
    # Without SO_BROADCAST the send was refused: "cannot send to 255.255.255.255:20010 (Permission denied)".
    listener = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    listener.bind(("0.0.0.0", 0))
    listener.settimeout(5.0)
    try:
        port = listener.getsockname()[1]
        assert main(["request", "--to", f"255.255.255.255:{port}"]) == 0, capsys.readouterr().err
        data, _ = listener.recvfrom(4096)
    finally:
        listener.close()
    assert data == sensor_request(mid70)


def test_a_frame_whose_point_count_lies_is_counted_once_and_the_next_arrives() -> None:
    """A datagram that reassembles but whose PointNum claims more points than it holds: one bad payload in the
    receiver's report and in the drops, then the next good frame is received as sent."""
    import time

    from livox_viz.wire.transport import UdpReceiver

    receiver = UdpReceiver("127.0.0.1", 0)
    good = random_points(10)
    lying = bytearray(pack_payload(np.zeros(6), good))
    struct.pack_into("<i", lying, len(lying) - 6 * 10 - 4, 11)  # PointNum: 11 points, 10 in the payload
    sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        for payload, t in ((bytes(lying), 0.1), (pack_payload(np.ones(6), good), 0.2)):
            for datagram in split_datagrams(payload, t):
                sender.sendto(datagram, ("127.0.0.1", receiver.port))
        deadline = time.monotonic() + 10
        frames = []
        for frame in receiver.frames(lambda: bool(frames) or time.monotonic() > deadline):
            frames.append(frame)
    finally:
        sender.close()
        receiver.socket.close()
    assert len(frames) == 1 and frames[0].timestamp == pytest.approx(0.2)
    np.testing.assert_array_equal(frames[0].xyz_int16, good)
    assert receiver.report.bad_payloads == 1 and receiver.assembler.drops["bad payload"] == 1


def test_a_receiver_yields_every_frame_a_late_chunk_frees_in_order() -> None:
    """Over UDP: a frame's last chunk after the whole next frame; the datagram that completes the first frame
    frees the second too, and the receiver yields both, in order, with their points and its report counting
    both."""
    import time

    from livox_viz.wire.transport import UdpReceiver

    receiver = UdpReceiver("127.0.0.1", 0)
    points = [random_points(15_000, seed=k) for k in range(2)]
    frames_sent = [split_datagrams(pack_payload(np.full(6, k, np.float32), p), 0.1 * (k + 1))
                   for k, p in enumerate(points)]
    sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        for datagram in [frames_sent[0][0], *frames_sent[1], frames_sent[0][1]]:
            sender.sendto(datagram, ("127.0.0.1", receiver.port))
        deadline = time.monotonic() + 10
        frames = []
        for frame in receiver.frames(lambda: len(frames) >= 2 or time.monotonic() > deadline):
            frames.append(frame)
    finally:
        sender.close()
        receiver.socket.close()
    assert [f.timestamp for f in frames] == pytest.approx([0.1, 0.2])
    for frame, sent in zip(frames, points, strict=True):
        np.testing.assert_array_equal(frame.xyz_int16, sent)
    assert (receiver.report.frames, receiver.report.points) == (2, 30_000)
