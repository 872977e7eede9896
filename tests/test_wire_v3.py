"""RflySim SDK v3's wire beside v2's: four int16 a point, the ``<6i1d`` header with frame ids, the 144-byte
``<16H28f`` request, the four-value shared-memory block on either platform's opener, and round trips.

The layouts are checked byte for byte against ``struct`` packing written here from the layouts, and frames
against :func:`v3_client_frames`, a mirror of how RflySim's v3 client receives a lidar over UDP. It follows the
public copy Ding-Guo/RflySimVision ``sensor_pkg/VisionCaptureApi.py`` (``img_udp_thrdNew``: the first
datagram's checksum chooses ``<4i1d`` (1234567890) or ``<6i1d`` (1234567893); a datagram whose checksum or
length field is wrong is skipped; chunk 0 starts a frame and sets its chunk count, later chunks must carry its
timestamp; a repeated frame id's chunk 0 is skipped; for TypeID 20-23 posAng is float32[6] at 0, PointNum int32
at 24, then PointNum x 4 int16 from byte 28, all four scaled by otherParams[0] / 32767). None of its code is
copied; these are our own tests of the same layouts.
"""

from __future__ import annotations

import json
import math
import struct
import time
from pathlib import Path

import numpy as np
import pytest

from livox_viz import LivoxVizError, load_config, load_preset
from livox_viz.casting.codec import encode_int16
from livox_viz.cli import main
from livox_viz.wire import rflysim
from livox_viz.wire.rflysim import (
    Reassembler,
    SharedMemoryLink,
    WireFormat,
    open_named_mapping,
    open_shm_file,
    pack_payload,
    sensor_request,
    shm_size,
    split_datagrams,
    unpack_payload,
)

from .conftest import free_udp_port, start_listening
from .test_config_v3 import V3_MID360_EXAMPLE, V3_ROSETTE


def points4(count: int, seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).integers(-32767, 32768, size=(count, 4)).astype(np.int16)


def v3_client_frames(datagrams: list[bytes], range_max: float) -> list[tuple[float, np.ndarray, np.ndarray]]:
    """(timestamp, posAng, (N, 4) metres) of each lidar frame RflySim's v3 client would take from ``datagrams``."""
    frames = []
    checksum = None
    frame_id = -1
    chunks: dict[int, bytes] = {}
    expected = 0
    stamp = 0.0
    for datagram in datagrams:
        if checksum is None:
            checksum = struct.unpack_from("<i", datagram)[0]
        head = "<6i1d" if checksum == 1234567893 else "<4i1d"
        size = struct.calcsize(head)
        fields = struct.unpack_from(head, datagram)
        if head == "<6i1d":
            if fields[4] != frame_id and fields[2] == 0:
                frame_id = fields[4]
            elif fields[4] == frame_id and fields[2] == 0:
                continue  # the same frame again
        if fields[0] != checksum or fields[1] != len(datagram):
            continue
        if fields[2] == 0:
            chunks, expected, stamp = {0: datagram[size:]}, fields[3], fields[-1]
        elif expected and math.isclose(stamp, fields[-1], rel_tol=1e-5):
            chunks[fields[2]] = datagram[size:]
        if expected and len(chunks) == expected:
            data = b"".join(chunks[i] for i in range(expected))
            pose = np.frombuffer(data, dtype=np.float32, count=6)
            count = int(np.frombuffer(data, dtype=np.int32, count=1, offset=24)[0])
            values = np.frombuffer(data, dtype=np.int16, count=count * 4, offset=28).reshape(count, 4)
            frames.append((stamp, pose, values / 32767.0 * range_max))
            expected = 0
    return frames


def test_a_v3_payload_is_posang_pointnum_and_four_int16_a_point() -> None:
    points = points4(7_001)
    pose = np.array([1.5, -2.0, -30.25, 0.1, -0.2, 3.0])
    payload = pack_payload(pose, points)
    assert payload == struct.pack("<6fi", *pose, 7_001) + struct.pack(f"<{7_001 * 4}h", *points.ravel())
    frame = unpack_payload(payload, 0.5)
    assert frame.channels == 4 and np.array_equal(frame.xyz_int16, points[:, :3])
    assert np.array_equal(frame.channel4, points[:, 3])
    three = unpack_payload(pack_payload(pose, points[:, :3]), 0.5)
    assert three.channels == 3 and three.channel4 is None and np.array_equal(three.xyz_int16, points[:, :3])


@pytest.mark.parametrize("lie", [1, -1, 7_001 * 2])
def test_a_v3_payload_whose_point_count_lies_is_refused(lie: int) -> None:
    payload = bytearray(pack_payload(np.zeros(6), points4(7_001)))
    struct.pack_into("<i", payload, 24, 7_001 + lie)
    with pytest.raises(LivoxVizError, match=rf"PointNum {7_001 + lie} but the payload holds"):
        unpack_payload(bytes(payload), 0.0)


def test_new_header_datagrams_byte_for_byte() -> None:
    payload = pack_payload(np.arange(6.0), points4(20_000))  # 160 028 bytes -> 3 chunks
    datagrams = split_datagrams(payload, 1.25, frame_id=41)
    assert len(datagrams) == 3
    for index, datagram in enumerate(datagrams):
        chunk = payload[index * 60000 : (index + 1) * 60000]
        assert datagram == struct.pack("<6i1d", 1234567893, 32 + len(chunk), index, 3, 41, 0, 1.25) + chunk
    old = split_datagrams(payload, 1.25)
    assert old[1] == struct.pack("<4i1d", 1234567890, 24 + 60000, 1, 3, 1.25) + payload[60000:120000]


def test_the_v3_client_decodes_what_we_send_in_both_headers() -> None:
    frames = [(k * 0.1, np.array([k, 2.0, -3.0, 0.1, 0.2, 0.3 * k]), points4(9_000 + k, seed=k)) for k in range(4)]
    for frame_ids in (True, False):
        datagrams = [d for k, (t, pose, pts) in enumerate(frames)
                     for d in split_datagrams(pack_payload(pose, pts), t, frame_id=k if frame_ids else None)]
        got = v3_client_frames(datagrams, 600.0)
        assert len(got) == 4
        for (t, pose, pts), (stamp, their_pose, metres) in zip(frames, got, strict=True):
            assert stamp == t
            np.testing.assert_allclose(their_pose, pose, rtol=1e-6)
            np.testing.assert_array_equal(metres, pts / 32767.0 * 600.0)


def test_the_reassembler_takes_both_headers_and_keeps_frame_ids() -> None:
    assembler = Reassembler()
    old = split_datagrams(pack_payload(np.zeros(6), points4(10)[:, :3]), 0.0)
    new = split_datagrams(pack_payload(np.zeros(6), points4(12)), 0.1, frame_id=7)
    assert assembler.feed(old[0], "a") is not None and assembler.frame_id is None
    done = assembler.feed(new[0], "b")
    assert done is not None and assembler.frame_id == 7
    assert unpack_payload(done[1], done[0], frame_id=assembler.frame_id).channels == 4


@pytest.mark.parametrize(("datagram", "reason"), [
    (struct.pack("<6i1d", 1234567891, 40, 0, 1, 0, 0, 0.0) + b"x" * 8, "wrong checksum"),
    (struct.pack("<6i1d", 1234567893, 41, 0, 1, 0, 0, 0.0) + b"x" * 8, "length field does not match the datagram"),
    (struct.pack("<6i1d", 1234567893, 24, 0, 1, 0, 0, 0.0)[:28], "truncated header"),
    (struct.pack("<4i1d", 1234567890, 99, 0, 1, 0.0) + b"x" * 8, "length field does not match the datagram"),
])
def test_neither_header_or_a_lying_length_is_counted_and_dropped(datagram: bytes, reason: str) -> None:
    assembler = Reassembler()
    assert assembler.feed(datagram, "a") is None
    assert assembler.drops == {reason: 1}
    good = split_datagrams(pack_payload(np.zeros(6), points4(5)), 0.0, frame_id=0)
    assert assembler.feed(good[0], "a") is not None  # and the next frame arrives


def test_the_request_is_92_or_144_bytes_field_by_field(tmp_path: Path) -> None:
    (tmp_path / "v3.json").write_text(json.dumps({**V3_ROSETTE, "EularOrQuat": 1, "SensorAngQuat": [0.5, 0.5, 0.5,
                                                  0.5], "SensorAngEular": [0.1, 0.2, 0.3]}))
    cfg = load_config(tmp_path / "v3.json")
    request = sensor_request(cfg)
    assert len(request) == 144
    fields = struct.unpack("<16H28f", request)
    assert fields[:16] == (12345, 0, 22, 1, 0, 250, 40, 10, 1, 127, 0, 0, 1, 9999, 0, 0)
    want = [70.432, 0, 0, -0.3, 1, 0.1, 0.2, 0.3, 0.5, 0.5, 0.5, 0.5, 600, 2.956, 1.4, 1.18, 10, 5, 1, 0,
            0, 0, 0, 0, 0, 3.5, 0, 7]
    np.testing.assert_allclose(fields[16:], np.float32(want))
    # The old form is 92 bytes whatever the SDK: RflySim's own Mid-360 example, its W x H as written.
    (tmp_path / "mid360.json").write_text(json.dumps({**V3_MID360_EXAMPLE, "DataWidth": 100}))
    old = sensor_request(load_config(tmp_path / "mid360.json"))
    assert len(old) == 92 and struct.unpack("<16H15f", old)[:8] == (12345, 0, 23, 1, 0, 100, 272, 10)
    assert struct.unpack("<16H15f", old)[16:] == pytest.approx([0, 0, 0, -0.3, 0, 0, 0, 100, 0, 0, 0, 0, 0, 0, 0])


def test_request_dry_run_of_a_v3_config(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "v3.json").write_text(json.dumps(V3_ROSETTE))
    assert main(["request", "--config", str(tmp_path / "v3.json"), "--to", "127.0.0.1", "--dry-run"]) == 0
    out = capsys.readouterr().out
    assert "(144 bytes)" in out and bytes.fromhex(out.split()[-1]) == sensor_request(load_config(tmp_path / "v3.json"))


def test_wire_formats_of_each_typeid(tmp_path: Path) -> None:
    (tmp_path / "a.json").write_text(json.dumps(V3_ROSETTE))
    (tmp_path / "b.json").write_text(json.dumps(V3_MID360_EXAMPLE))
    assert WireFormat.of(load_preset("livox_mid70")) == WireFormat(3, False, False)
    assert WireFormat.of(load_config(tmp_path / "a.json")) == WireFormat(4, True, False)
    assert WireFormat.of(load_config(tmp_path / "b.json")) == WireFormat(4, True, True)
    assert shm_size(load_config(tmp_path / "b.json")) == 64 * 272 * 8 + 37


class _NamedMappings:
    """Stands in for Windows's ``mmap.mmap(-1, size, tagname=NAME)``: each name is a file in a folder, so what a
    link writes through the named mapping is what one over the POSIX file of the same name reads."""

    def __init__(self, folder: Path) -> None:
        self.folder = folder
        self.opened: list[tuple[int, int, str]] = []

    def __call__(self, fileno: int, size: int, tagname: str) -> object:
        self.opened.append((fileno, size, tagname))
        return open_shm_file(self.folder / tagname, size, create=True)


@pytest.mark.parametrize("channels", [3, 4])
def test_both_openers_lay_out_the_same_bytes(tmp_path: Path, channels: int) -> None:
    size = 500 * channels * 2 + 37
    points = points4(400, seed=channels)[:, :channels]
    (tmp_path / "posix").mkdir()
    file_link = SharedMemoryLink(tmp_path / "posix" / "RflySim3DImg_3", size, create=True, channels=channels)
    assert file_link.write(1.5, np.arange(6.0), points)
    posix_bytes = (tmp_path / "posix" / "RflySim3DImg_3").read_bytes()
    # The layout, from the spec: flag 2, float64 time at 1, posAng float32 at 9, PointNum at 33, points at 37.
    assert posix_bytes == (struct.pack("<Bd6fi", 2, 1.5, *range(6), 400)
                           + points.astype("<i2").tobytes() + bytes(size - 37 - points.nbytes))
    mappings = _NamedMappings(tmp_path)
    block = open_named_mapping(rflysim.shm_name(3), size, mapping=mappings)
    assert mappings.opened == [(-1, size, "RflySim3DImg_3")]
    windows_link = SharedMemoryLink(None, size, channels=channels, block=block, name="RflySim3DImg_3")
    assert windows_link.write(1.5, np.arange(6.0), points)
    assert (tmp_path / "RflySim3DImg_3").read_bytes() == posix_bytes
    # Each reads what the other's opener wrote.
    reader = SharedMemoryLink(tmp_path / "RflySim3DImg_3", size, channels=channels)
    frame = reader.read()
    assert frame is not None and frame.channels == channels and np.array_equal(frame.xyz_int16, points[:, :3])
    assert windows_link.read() is None  # taken: the flag says done (4)
    for link in (file_link, windows_link, reader):
        link.close()


def test_windows_opens_the_named_mapping(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """On Windows the shared-memory sender and receiver open ``RflySim3DImg_<SeqID>`` as a named mapping."""
    from livox_viz.wire import transport

    mappings = _NamedMappings(tmp_path)
    monkeypatch.setattr(rflysim.sys, "platform", "win32")
    monkeypatch.setattr(transport.sys, "platform", "win32")
    def named(name: str, size: int) -> object:
        return open_named_mapping(name, size, mapping=mappings)

    monkeypatch.setattr(rflysim, "open_named_mapping", named)
    monkeypatch.setattr(transport, "open_named_mapping", named)
    (tmp_path / "v3.json").write_text(json.dumps({**V3_ROSETTE, "SeqID": 5}))
    cfg = load_config(tmp_path / "v3.json")
    sender = transport.ShmSender(cfg, folder="/nonexistent")
    receiver = transport.ShmReceiver(cfg, folder="/nonexistent")
    assert [name for _, _, name in mappings.opened] == ["RflySim3DImg_5", "RflySim3DImg_5"]
    points = points4(1000)
    points[:, 3] = 0
    assert sender.send(0.2, np.zeros(6), points) == 1
    frames = receiver.poll()
    assert len(frames) == 1 and np.array_equal(frames[0].xyz_int16, points[:, :3])
    assert np.array_equal(frames[0].channel4, points[:, 3])
    sender.close()
    receiver.close()


def _publish_and_listen(tmp_path: Path, config: Path, seconds: str = "0.5") -> tuple[np.lib.npyio.NpzFile, ...]:
    port = free_udp_port()
    received, sent = tmp_path / "received.npz", tmp_path / "sent.npz"
    frames = str(round(float(seconds) * 10))
    listener = start_listening(["--port", str(port), "--frames", frames, "--timeout", "30", "--config", str(config),
                                "--record", str(received)])
    assert main(["publish", "--config", str(config), "--to", f"127.0.0.1:{port}", "--seconds", seconds,
                 "--speed", "10"]) == 0
    listener.join(60)
    assert not listener.is_alive()
    assert main(["scan", "--config", str(config), "--seconds", seconds, "--out", str(sent)]) == 0
    return np.load(received), np.load(sent)


def test_a_v3_publish_listen_round_trip_equals_scan(tmp_path: Path) -> None:
    config = tmp_path / "v3.json"
    config.write_text(json.dumps(V3_ROSETTE))
    got, want = _publish_and_listen(tmp_path, config)
    assert np.array_equal(got["xyz_int16"], want["xyz_int16"])
    assert np.array_equal(got["frame"], want["frame"])
    np.testing.assert_array_equal(got["xyz_sensor"], want["xyz_sensor"])
    assert np.array_equal(got["channel4"], np.zeros(len(got["frame"]), dtype=np.int32))
    # The new header's frame ids count frames: the recording keeps them as the sender's frame numbers.
    assert np.array_equal(np.unique(got["sender_frame"]), np.arange(5))


def test_a_mid360_publishes_world_points_and_listen_places_them(tmp_path: Path) -> None:
    config = tmp_path / "mid360.json"
    config.write_text(json.dumps({**V3_MID360_EXAMPLE, "SendProtocol": [1, 127, 0, 0, 1, 9999, 0, 0]}))
    got, want = _publish_and_listen(tmp_path, config, "0.3")
    fits = np.all(np.abs(want["xyz_world"]) <= 100.0, axis=1)
    assert fits.mean() > 0.5  # the default scene is mostly within 100 m of the origin
    assert np.array_equal(got["xyz_int16"], encode_int16(want["xyz_world"][fits], 100.0))
    # Placed in the sensor frame with the frame's posAng, they are the scan's own sensor points to the int16 step.
    np.testing.assert_allclose(got["xyz_sensor"], want["xyz_sensor"][fits], atol=100.0 / 32767 * 2)


def test_the_windows_listen_path_takes_v3_world_frames(tmp_path: Path) -> None:
    """``gui --listen`` opens its receiver through the wire's ``open_receiver``: a Mid-360's world points arrive
    where the scan put them (the session itself is untouched; no window needed)."""
    import argparse

    from livox_viz.widgets.session import Session

    from livox_viz.casting.scan import LidarScanner
    from livox_viz.cli.wire_commands import open_receiver
    from livox_viz.scene.scenes import open_scene
    from livox_viz.wire.transport import UdpSender, wire_points

    (tmp_path / "mid360.json").write_text(json.dumps(V3_MID360_EXAMPLE))
    cfg = load_config(tmp_path / "mid360.json")
    scene = open_scene("urban")
    session = Session(cfg, scene)
    receiver, _ = open_receiver(argparse.Namespace(shm=False, host="127.0.0.1", port=0, shm_dir=None), cfg)
    session.source = receiver
    scanner = LidarScanner(cfg, session.caster, session.vehicle_pose, seed=0)
    sender = UdpSender("127.0.0.1", receiver.port, WireFormat.of(cfg))
    frame = scanner.next_frame()
    sender.send(frame.timestamp, frame.sensor_pose.as_array(), wire_points(frame, sender.wire), frame.index)
    sender.close()
    added = 0
    deadline = time.monotonic() + 10
    while not added and time.monotonic() < deadline:
        added = session.tick()
    receiver.close()
    fits = np.all(np.abs(frame.xyz_world) <= cfg.range_max, axis=1)
    assert added == int(fits.sum()) > 0
    np.testing.assert_allclose(session.scene_ring.ordered(session.scene_ring.positions),
                               frame.xyz_world[fits], atol=cfg.range_max / 32767)


def _frame_datagrams(timestamp: float, frame_id: int, points: int = 5) -> list[bytes]:
    payload = rflysim.pack_payload(np.zeros(6), np.full((points, 4), 7, dtype=np.int16))
    return rflysim.split_datagrams(payload, timestamp, frame_id=frame_id)


def test_the_live_counters_say_frames_lost_whole_and_frame_ids_going_back() -> None:
    """Issue 47: about 40 % of an unpaced v3 stream lost whole said 'drops 0', though the frame ids showed the
    gaps; frame ids going backwards got no word."""
    assembler = rflysim.Reassembler()
    sent = [k for k in range(20) if k % 5 not in (1, 3)]  # 8 of 20 frames lost whole
    for k in sent:
        for datagram in _frame_datagrams(0.1 * k, k):
            assembler.feed(datagram, "sim")
    assert assembler.frames == len(sent)
    assert assembler.drops["lost frames (frame ids skipped)"] == 20 - len(sent) == 8
    assert assembler.restarts == 0
    # The same sender's ids start again (a restarted RflySim) with times that still go forward: one restart.
    for datagram in _frame_datagrams(5.0, 0):
        assembler.feed(datagram, "sim")
    assert assembler.restarts == 1 and "frame ids went back from 19 to 0" in assembler.last_error


def test_a_datagram_that_holds_no_frame_is_a_bad_payload_not_a_restart() -> None:
    """Issue 47: one dropped header-only datagram (a valid header, no payload) counted as a 'sender restart';
    random headers gave 80."""
    rng = np.random.default_rng(3)
    assembler = rflysim.Reassembler()
    for datagram in _frame_datagrams(50.0, 1):
        assembler.feed(datagram, "sim")
    for _ in range(100):  # header-only datagrams with random earlier times: each a whole (empty) "frame"
        header = rflysim.DATAGRAM_HEADER.pack(rflysim.FRAME_CHECKSUM, rflysim.DATAGRAM_HEADER.size, 0, 1,
                                              float(rng.uniform(0, 49)))
        assert assembler.feed(header, "sim") is None
    for datagram in _frame_datagrams(50.1, 2):
        assert assembler.feed(datagram, "sim") is not None
    assert assembler.restarts == 0 and assembler.drops["bad payload"] == 100 and assembler.frames == 2
