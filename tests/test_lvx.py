"""LVX2 and LVX 1.1: what we write reads back, lies where Livox's specifications put it, and bad files are refused."""

from __future__ import annotations

import os
import struct
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pytest

from livox_viz.casting.scan import LidarScanner
from livox_viz.cli import main
from livox_viz.config.mount import sensor_mount
from livox_viz.config.presets import load_preset
from livox_viz.core.errors import LivoxVizError
from livox_viz.core.poses import Pose
from livox_viz.core.rotations import flu_from_frd
from livox_viz.files.export import PointCloudWriter
from livox_viz.files.lvx_format import HEADS, livox_head
from livox_viz.files.lvx_read import iter_lvx, read_lvx
from livox_viz.scene.scenes import open_scene

# The layouts as the specifications' tables give them, written out here again (not imported): struct formats.
PUBLIC = "<16s4BI"  # 24 bytes
PRIVATE = "<IB"  # 5
LVX2_DEVICE = "<16s16sIBBB6f"  # 63
LVX1_DEVICE = "<16s16sBBB6f"  # 59
FRAME = "<QQQ"  # 24
LVX2_PACKAGE = "<BIBBQHBIB4s"  # 27
LVX1_PACKAGE = "<BBBBBIBBQ"  # 19


def test_the_layouts_are_the_specifications_sizes() -> None:
    sizes = [struct.calcsize(f) for f in (PUBLIC, PRIVATE, LVX2_DEVICE, LVX1_DEVICE, FRAME, LVX2_PACKAGE,
                                          LVX1_PACKAGE)]
    assert sizes == [24, 5, 63, 59, 24, 27, 19]


@pytest.fixture(scope="module")
def mid360_frames() -> tuple[list, object]:
    cfg = load_preset("livox_mid360").with_returns_model("ideal")
    cfg = replace(cfg, sensor_ang_euler=(0.1, -0.2, 0.3), sensor_pos_xyz=(0.5, -0.25, -1.0))
    scene = open_scene("urban")
    return list(LidarScanner(cfg, scene.mesh, scene.vehicle_pose, seed=3).frames(0.23)), cfg


def write(path: Path, frames: list, head) -> Path:
    with PointCloudWriter(path, livox=head) as writer:
        for frame in frames:
            writer.write(frame)
    return path


def test_mid360_round_trip(tmp_path: Path, mid360_frames) -> None:
    frames, cfg = mid360_frames
    head = livox_head(".lvx2", "livox_mid360", cfg.point_rate, cfg.lasers, 1, sensor_mount(cfg))
    recording = read_lvx(write(tmp_path / "scan.lvx2", frames, head))
    slots = np.concatenate([f.stream_index for f in frames])
    fired = frames[-1].timestamp * cfg.point_rate + frames[-1].ray_count
    # Every firing has its row, in firing order (the last package filled up with no-returns).
    assert len(recording) == -(-int(fired) // 96) * 96
    assert np.array_equal(np.flatnonzero(~recording.no_return), slots)
    xyz = flu_from_frd(np.concatenate([f.xyz_decoded for f in frames]))
    assert np.abs(recording.points_m[slots] - xyz).max() <= 0.0005 + 1e-9
    assert np.abs(recording.times_s[slots] - np.concatenate([f.t for f in frames])).max() < 1e-8
    # The firings that returned nothing too: their time is their slot's.
    assert np.abs(recording.times_s[: int(fired)] - np.arange(int(fired)) / cfg.point_rate).max() < 1e-8
    assert np.array_equal(recording.lasers[slots], slots % 4)
    assert np.array_equal(recording.reflectivity[slots], np.concatenate([f.reflectivity for f in frames]))
    assert np.array_equal(recording.tags[slots], np.concatenate([f.tag for f in frames]))
    assert not recording.points_m[recording.no_return].any()
    device = recording.devices[0]
    assert (device.device_type, device.name, device.extrinsic_enable) == (9, "Mid-360", True)
    # The mount: FRD (0.5, -0.25, -1.0) is FLU (0.5, 0.25, 1.0); the angles turned likewise.
    assert np.allclose(device.extrinsics[3:], (0.5, 0.25, 1.0), atol=1e-6)
    assert np.allclose(device.extrinsics[:3], np.degrees((0.1, 0.2, -0.3)), atol=1e-4)


def test_lvx2_bytes_lie_where_the_specification_puts_them(tmp_path: Path, mid360_frames) -> None:
    frames, cfg = mid360_frames
    head = livox_head(".lvx2", "livox_mid360", cfg.point_rate, cfg.lasers, 1, Pose())
    data = write(tmp_path / "scan.lvx2", frames, head).read_bytes()
    signature, a, b, c, d, magic = struct.unpack_from(PUBLIC, data, 0)
    assert signature == b"livox_tech".ljust(16, b"\0") and (a, b, c, d) == (2, 0, 0, 0) and magic == 0xAC0EA767
    assert struct.unpack_from(PRIVATE, data, 24) == (50, 1)
    device = struct.unpack_from(LVX2_DEVICE, data, 29)
    assert device[4] == 9 and device[5] == 1 and device[6:] == (0.0,) * 6
    position, index, packages = 24 + 5 + 63, 0, []
    while position < len(data):
        current, following, frame_index = struct.unpack_from(FRAME, data, position)
        assert (current, frame_index) == (position, index)
        cursor = position + 24
        while cursor < following:
            package = struct.unpack_from(LVX2_PACKAGE, data, cursor)
            version, lidar_id, lidar_type, stamp_type, stamp, counter, data_type, length, _, reserve = package
            assert (version, lidar_id, lidar_type, stamp_type, data_type, length, reserve) == (
                0, device[2], 8, 0, 1, 96 * 14, b"\0" * 4)
            assert counter == len(packages) % 65536
            # Each frame holds the packages of its 50 ms.
            assert stamp // 50_000_000 == index
            packages.append((stamp, cursor + 27))
            cursor += 27 + length
        assert cursor == following
        position, index = following, index + 1
    assert index == 5  # 0.23 s: frames of 0-50, ..., 200-250 ms
    stamps = np.array([stamp for stamp, _ in packages])
    assert np.array_equal(stamps, np.round(np.arange(len(packages)) * 96 * 1e9 / cfg.point_rate))
    # The first return's bytes: int32 mm x, y, z (FLU), reflectivity, tag, in its firing's place.
    first = frames[0]
    slot = int(first.stream_index[0])
    x, y, z, reflectivity, tag = struct.unpack_from("<iiiBB", data, packages[slot // 96][1] + 14 * (slot % 96))
    expected = np.rint(flu_from_frd(first.xyz_decoded[:1])[0] * 1000).astype(int)
    assert (x, y, z) == tuple(expected) and (reflectivity, tag) == (first.reflectivity[0], first.tag[0])


@dataclass
class Made:
    """A frame as a scan gives it, made by hand."""

    stream_index: np.ndarray
    ray_count: int
    timestamp: float
    xyz_decoded: np.ndarray
    reflectivity: np.ndarray
    tag: np.ndarray
    return_number: np.ndarray
    index: int = 0

    def __len__(self) -> int:
        return len(self.stream_index)


def made_frames(rate: int, rays: int, frames: int, echoes: int, seed: int = 0) -> list[Made]:
    """Frames of ``rays`` firings, about half returning, each with 1 to ``echoes`` returns (FRD metres)."""
    rng = np.random.default_rng(seed)
    out = []
    for k in range(frames):
        fired = np.flatnonzero(rng.random(rays) < 0.5) + k * rays
        counts = rng.integers(1, echoes + 1, len(fired))
        index = np.repeat(fired, counts)
        number = np.concatenate([np.arange(1, c + 1) for c in counts]).astype(np.uint8)
        out.append(Made(index, rays, k * rays / rate, rng.uniform(-50, 50, (len(index), 3)),
                        rng.integers(1, 255, len(index)).astype(np.uint8),
                        (number << 4).astype(np.uint8), number, k))
    return out


@pytest.mark.parametrize(("name", "echoes", "per_package"), [("livox_horizon", 2, 48), ("livox_avia", 3, 30),
                                                              ("livox_mid40", 1, 100), ("livox_tele15", 1, 96)])
def test_lvx1_round_trip_single_dual_triple(tmp_path: Path, name: str, echoes: int, per_package: int) -> None:
    model = next(h for h in HEADS if name in h.presets)
    frames = made_frames(model.rate, 2400, 3, echoes)
    head = livox_head(".lvx", name, model.rate, model.lines, echoes, Pose())
    recording = read_lvx(write(tmp_path / "scan.lvx", frames, head)).returns()
    assert recording.source == "LVX 1.1" and recording.device_type == model.device_type
    index = np.concatenate([f.stream_index for f in frames])
    number = np.concatenate([f.return_number for f in frames])
    order = np.lexsort((number, index))
    assert np.array_equal(recording.return_number, number[order])
    assert np.abs(recording.points_m - flu_from_frd(np.concatenate([f.xyz_decoded for f in frames]))[order]).max() \
        <= 0.0005 + 1e-9
    assert np.abs(recording.times_s - index[order] / model.rate).max() < 1e-8
    assert np.array_equal(recording.lasers, (index[order] % model.lines).astype(np.uint8))
    tags = np.concatenate([f.tag for f in frames])[order]
    assert np.array_equal(recording.tags, tags if name != "livox_mid40" else np.zeros_like(tags))
    size = (tmp_path / "scan.lvx").stat().st_size
    packages = -(-3 * 2400 // per_package)
    assert size - 88 - 24 * (-(-3 * 2400 * 10**9 // model.rate) // 50_000_000 + 1) in (
        packages * (19 + per_package * echoes * (13 if name == "livox_mid40" else 14)),)


def lvx1_file(packages: list[bytes], device_type: int = 7, magic: int = 0xAC0EA767, frames: int = 1,
              next_offset: int | None = None) -> bytes:
    """An LVX 1.1 file made by hand to the specification (not by our writer): ``packages`` split into ``frames``."""
    head = struct.pack(PUBLIC, b"livox_tech", 1, 1, 0, 0, magic) + struct.pack(PRIVATE, 50, 1)
    head += struct.pack(LVX1_DEVICE, b"3GGDJ1234567890", b"", 0, device_type, 0, 0, 0, 0, 0, 0, 0)
    out = bytearray(head)
    per = -(-len(packages) // frames)
    for k in range(frames):
        body = b"".join(packages[k * per: (k + 1) * per])
        start = len(out)
        out += struct.pack(FRAME, start, start + 24 + len(body) if next_offset is None else next_offset, k) + body
    return bytes(out)


def lvx1_package(data_type: int, stamp: int, points: bytes, device: int = 0) -> bytes:
    return struct.pack(LVX1_PACKAGE, device, 5, 1, 1, 0, 0, 0, data_type, stamp) + points


def cartesian(count: int, start: int = 1) -> bytes:
    return b"".join(struct.pack("<iiiBB", 1000 * (start + k), -2 * (start + k), 3, 7, 0x10) for k in range(count))


def test_a_hand_made_avia_file_with_imu_and_dual_packages(tmp_path: Path) -> None:
    interval = 4167
    packages = [lvx1_package(2, 0, cartesian(96)),
                lvx1_package(6, 1000, struct.pack("<6f", 0.1, 0.2, 0.3, 0.0, 0.0, 1.0)),  # IMU: skipped
                lvx1_package(2, 96 * interval, cartesian(96, 97)),
                lvx1_package(4, 192 * interval, cartesian(96, 193)),  # dual: 48 pulses of two returns
                lvx1_package(4, 240 * interval, cartesian(96, 289))]
    path = tmp_path / "avia.lvx"
    path.write_bytes(lvx1_file(packages))
    recording = read_lvx(path)
    assert recording.skipped == {"IMU packages": 1} and recording.devices[0].name == "Avia"
    assert recording.devices[0].serial == "3GGDJ1234567890"
    assert len(recording) == 4 * 96
    assert np.allclose(recording.points_m[:, 0], np.arange(1, 385))
    assert np.allclose(recording.points_m[:, 1], -2e-3 * np.arange(1, 385))
    # Single packages: point i at timestamp + i * interval, line i % 6; dual: pulse i // 2.
    single = np.arange(192)
    assert np.allclose(recording.times_s[:192], single * interval / 1e9, atol=1e-9)
    assert np.array_equal(recording.lasers[:192], single % 6)
    pulse = np.arange(192) // 2
    assert np.allclose(recording.times_s[192:], (192 + (pulse % 48) + (pulse // 48) * 48) * interval / 1e9,
                       atol=1e-9)
    assert np.array_equal(recording.lasers[192:], (pulse % 48) % 6)
    assert np.array_equal(recording.return_number[192:], np.tile([1, 2], 96))


def test_a_hand_made_hap_lvx2(tmp_path: Path) -> None:
    head = struct.pack(PUBLIC, b"livox_tech", 2, 0, 0, 0, 0xAC0EA767) + struct.pack(PRIVATE, 50, 1)
    head += struct.pack(LVX2_DEVICE, b"HAPSN", b"", 77, 247, 10, 1, 1.0, 2.0, 3.0, 0.1, 0.2, 0.3)
    body = b"".join(struct.pack(LVX2_PACKAGE, 0, 77, 8, 0, 10**9 + k * 212_400, k, 1, 1344, 0, b"\0" * 4)
                    + cartesian(96, 96 * k) for k in range(3))
    data = head + struct.pack(FRAME, len(head), len(head) + 24 + len(body), 0) + body
    path = tmp_path / "hap.lvx2"
    path.write_bytes(data)
    recording = read_lvx(path)
    assert recording.devices[0].name == "HAP" and recording.devices[0].extrinsics == pytest.approx(
        (1.0, 2.0, 3.0, 0.1, 0.2, 0.3))
    assert np.array_equal(recording.lasers, np.arange(288) % 96 % 6)
    assert np.allclose(recording.times_s, 1.0 + np.arange(288) * 2212.5e-9, atol=1e-9)


def _corrupt(tmp_path: Path, data: bytes, name: str = "bad.lvx") -> Path:
    path = tmp_path / name
    path.write_bytes(data)
    return path


@pytest.mark.parametrize(("change", "message"), [
    ({"magic": 0x12345678}, "magic code 0x12345678; allowed: 0xAC0EA767"),
    ({"device_type": 9}, "device type 9, unknown to LVX 1.1; allowed: 1 Mid-40/100"),
    ({"next_offset": 10**6}, "truncated: frame 0 at byte 88 ends at byte 1,000,000, past the file's end"),
    ({"next_offset": 40}, "says the next frame starts at byte 40, before its own end (its offsets loop back)"),
])
def test_bad_headers_are_refused_in_one_line(tmp_path: Path, change: dict, message: str) -> None:
    path = _corrupt(tmp_path, lvx1_file([lvx1_package(2, 0, cartesian(96))], **change))
    with pytest.raises(LivoxVizError, match=message.replace("(", r"\(").replace(")", r"\)")) as error:
        read_lvx(path)
    assert "\n" not in str(error.value)


@pytest.mark.parametrize(("data_type", "message"), [(1, "data type 1 \\(spherical\\) is not read"),
                                                    (9, "data type 9 \\(unknown\\) is not read")])
def test_an_unknown_point_type_is_refused(tmp_path: Path, data_type: int, message: str) -> None:
    path = _corrupt(tmp_path, lvx1_file([lvx1_package(data_type, 0, bytes(900))]))
    with pytest.raises(LivoxVizError, match=message):
        read_lvx(path)


def test_a_frame_that_comes_back_to_an_earlier_one_is_refused(tmp_path: Path) -> None:
    data = bytearray(lvx1_file([lvx1_package(2, k, cartesian(96)) for k in range(4)], frames=2))
    second = struct.unpack_from(FRAME, data, 88)[1]
    struct.pack_into(FRAME, data, second, 88, 88 + 24, 1)  # the second frame claims to be the first again
    with pytest.raises(LivoxVizError, match="says it starts at byte 88; allowed: frames one after the other"):
        read_lvx(_corrupt(tmp_path, bytes(data)))


def test_a_cut_file_is_refused_and_nothing_is_read_past_its_end(tmp_path: Path) -> None:
    data = lvx1_file([lvx1_package(2, k, cartesian(96)) for k in range(4)], frames=2)
    path = _corrupt(tmp_path, data[:-10])
    with pytest.raises(LivoxVizError, match="truncated: frame 1 at byte"):
        read_lvx(path)
    with pytest.raises(LivoxVizError, match="not a Livox file"):
        read_lvx(_corrupt(tmp_path, b"PK\x03\x04" + bytes(40), "zip.lvx"))
    with pytest.raises(LivoxVizError, match="ends inside its public header"):
        read_lvx(_corrupt(tmp_path, b"livox_tech", "short.lvx"))


def test_a_huge_file_is_refused_before_it_is_read(tmp_path: Path) -> None:
    data = lvx1_file([lvx1_package(2, 0, cartesian(96))], next_offset=(4 << 30) - 1)
    path = _corrupt(tmp_path, data, "huge.lvx")
    os.truncate(path, 4 << 30)  # a sparse 4 GiB file: its first frame claims nearly all of it
    with pytest.raises(LivoxVizError, match=r"holds about 302,[0-9,]+ points \(4\.00 GiB\); allowed: at most"):
        read_lvx(path)
    with pytest.raises(LivoxVizError, match=r"frame 0 at byte 88 claims 4,096\.0 MiB; allowed: frames of at most 64"):
        next(iter_lvx(path))


def test_the_writer_refuses_another_heads_format_and_frames_without_firings(tmp_path: Path) -> None:
    with pytest.raises(LivoxVizError, match=r"a Horizon is written as \.lvx, not \.lvx2; allowed: \.lvx2 takes "
                                            r"Mid-360 \(device type 9\) or HAP \(10\)"):
        livox_head(".lvx2", "livox_horizon", 240_000, 6, 1, Pose())
    with pytest.raises(LivoxVizError, match=r"is no Livox head \.lvx knows"):
        livox_head(".lvx", "my_rosette", 100_000, 1, 1, Pose())
    with pytest.raises(LivoxVizError, match="fires 1 lasers in turn, a Mid-360 4"):
        livox_head(".lvx2", "livox_mid360", 200_000, 1, 1, Pose())
    with pytest.raises(LivoxVizError, match="needs the scan's Livox head"):
        PointCloudWriter(tmp_path / "x.lvx2")
    head = livox_head(".lvx2", "livox_mid360", 200_000, 4, 1, Pose())
    with pytest.raises(LivoxVizError, match="holds points in the sensor's frame"):
        PointCloudWriter(tmp_path / "x.lvx2", coordinates="world", livox=head)
    writer = PointCloudWriter(tmp_path / "x.lvx2", livox=head)
    with pytest.raises(LivoxVizError, match="needs each point's firing"):
        writer.write(object())  # type: ignore[arg-type]
    writer.abort()
    assert list(tmp_path.iterdir()) == []


def test_a_failed_write_keeps_the_old_file(tmp_path: Path) -> None:
    path = tmp_path / "old.lvx2"
    path.write_bytes(b"the user's old file")
    head = livox_head(".lvx2", "livox_mid360", 200_000, 4, 1, Pose())
    with pytest.raises(RuntimeError), PointCloudWriter(path, livox=head) as writer:
        writer.write(made_frames(200_000, 20_000, 1, 1)[0])
        raise RuntimeError("the scan failed")
    assert path.read_bytes() == b"the user's old file"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["old.lvx2"]


def test_scan_writes_lvx2_and_refuses_the_wrong_head(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "mid360.lvx2"
    assert main(["scan", "--preset", "livox_mid360", "--returns", "ideal", "--seconds", "0.1", "--out",
                 str(out)]) == 0
    assert read_lvx(out).devices[0].device_type == 9
    assert main(["scan", "--preset", "livox_mid70", "--seconds", "0.1", "--out", str(tmp_path / "x.lvx2")]) != 0
    error = capsys.readouterr().err.strip().splitlines()
    assert len(error) == 1 and "a Mid-70 is written as .lvx, not .lvx2" in error[0]
    assert not (tmp_path / "x.lvx2").exists()


def test_batch_takes_the_livox_formats_as_outputs() -> None:
    from livox_viz.cli.batch_spec import OUTPUTS, SpecError, _outputs

    assert {"lvx2", "lvx"} <= set(OUTPUTS)
    assert _outputs("lvx2+rosbag", "spec") == ("lvx2", "rosbag")
    with pytest.raises(SpecError, match="allowed: one of npz, ply, pcd, las, csv, lvx2, lvx, rosbag"):
        _outputs("lvx3", "spec")


def ros1_bag(path: Path, messages: int = 3, points: int = 50, custom_msg: bool = True) -> Path:
    """A ROS 1 bag as livox_ros_driver records one: CustomMsg on /livox/lidar and its PointCloud2 (x, y, z,
    intensity float32, tag, line uint8: no time) on /livox/points, 100 ms apart."""
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    from livox_viz.files.rosbag import CUSTOM_MSG, CUSTOM_POINT_MSG

    store = get_typestore(Stores.ROS1_NOETIC)
    types = get_types_from_msg(CUSTOM_POINT_MSG, "livox_ros_driver/msg/CustomPoint")
    types.update(get_types_from_msg(CUSTOM_MSG.replace("CustomPoint", "livox_ros_driver/CustomPoint"),
                                    "livox_ros_driver/msg/CustomMsg"))
    store.register(types)
    t = store.types
    with Writer(path) as writer:
        lidar = writer.add_connection("/livox/lidar", "livox_ros_driver/msg/CustomMsg", typestore=store)
        cloud = writer.add_connection("/livox/points", "sensor_msgs/msg/PointCloud2", typestore=store)
        for k in range(messages):
            base = 1_700_000_000 * 10**9 + k * 100_000_000
            stamp = t["builtin_interfaces/msg/Time"](sec=base // 10**9, nanosec=base % 10**9)
            header = t["std_msgs/msg/Header"](seq=k, stamp=stamp, frame_id="livox_frame")
            custom = [t["livox_ros_driver/msg/CustomPoint"](offset_time=i * 10_000, x=float(k), y=0.5 * i, z=0.0,
                                                             reflectivity=i % 200, tag=0x10, line=i % 6)
                      for i in range(points)]
            message = t["livox_ros_driver/msg/CustomMsg"](header=header, timebase=base, point_num=points, lidar_id=0,
                                                          rsvd=np.zeros(3, np.uint8), points=custom)
            if custom_msg:
                writer.write(lidar, base, store.serialize_ros1(message, lidar.msgtype))
            rows = np.zeros(points, [("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("intensity", "<f4"), ("tag", "u1"),
                                     ("line", "u1")])
            rows["x"], rows["y"], rows["intensity"], rows["line"] = k, 0.5 * np.arange(points), 9, np.arange(points) % 6
            fields = [t["sensor_msgs/msg/PointField"](name=n, offset=o, datatype=d, count=1)
                      for n, o, d in (("x", 0, 7), ("y", 4, 7), ("z", 8, 7), ("intensity", 12, 7), ("tag", 16, 2),
                                      ("line", 17, 2))]
            message = t["sensor_msgs/msg/PointCloud2"](header=header, height=1, width=points, fields=fields,
                                                       is_bigendian=False, point_step=18, row_step=18 * points,
                                                       data=np.frombuffer(rows.tobytes(), np.uint8), is_dense=True)
            writer.write(cloud, base, store.serialize_ros1(message, cloud.msgtype))
    return path


def test_ros1_bags_of_livox_ros_driver(tmp_path: Path) -> None:
    from livox_viz.files.livox_bag import read_livox_bag

    recording = read_livox_bag(ros1_bag(tmp_path / "drive.bag"))
    assert recording.source == "ROS 1 bag" and len(recording) == 150
    k, i = np.divmod(np.arange(150), 50)
    assert np.allclose(recording.times_s - 1.7e9, k * 0.1 + i * 1e-5, atol=1e-6)
    assert np.array_equal(recording.lasers, i % 6) and np.array_equal(recording.reflectivity, i % 200)
    assert np.allclose(recording.points_m[:, 1], 0.5 * i) and recording.no_return.sum() == 1  # k = 0, i = 0
    # Without the CustomMsg, the PointCloud2 (no time field): point i at the stamp + i * (100 ms / 50 points).
    clouds = read_livox_bag(ros1_bag(tmp_path / "points.bag", custom_msg=False))
    assert np.allclose(clouds.times_s - 1.7e9, k * 0.1 + i * 2e-3, atol=1e-6)
    assert np.array_equal(clouds.lasers, i % 6) and np.allclose(clouds.points_m, recording.points_m)
    with pytest.raises(LivoxVizError, match="not a bag rosbags reads"):
        read_livox_bag(_corrupt(tmp_path, b"#ROSBAG V2.0\n" + bytes(100), "broken.bag"))


def test_compare_and_fit_take_livox_recordings(tmp_path: Path, mid360_frames) -> None:
    from livox_viz.fitting.reference import load_reference

    frames, cfg = mid360_frames
    head = livox_head(".lvx2", "livox_mid360", cfg.point_rate, cfg.lasers, 1, sensor_mount(cfg))
    table = load_reference(write(tmp_path / "scan.lvx2", frames, head))
    slots = np.concatenate([f.stream_index for f in frames])
    assert table.rate == cfg.point_rate and table.plane == "panorama"
    assert np.array_equal(table.slots, slots - slots[0])  # the no-return firings are the table's gaps
    bag = load_reference(ros1_bag(tmp_path / "drive.bag", messages=2, points=40))
    assert len(bag.t) == 79  # the one (0, 0, 0) point is no row
