"""Files, outputs and bags under hostile use: huge frames, bad output paths, far-away worlds, read-only
files, full disks, endless inputs, bad ROS names, warnings and signals (issue 15)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from livox_viz.cli import main
from tests.conftest import SEED_JSON


def test_a_frame_of_more_rays_than_one_cast_part_is_cast_in_parts(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                                  capsys: pytest.CaptureFixture[str]) -> None:
    """5000 x 220 rays per frame (1.1 M, over CAST_PART) and a fixed sensor: the parts join, as one cast would."""
    from livox_viz.casting import scan

    config = tmp_path / "wide.json"
    config.write_text(json.dumps({**SEED_JSON, "DataWidth": 5000, "DataHeight": 220, "DataCheckFreq": 1}))
    assert 5000 * 220 > scan.CAST_PART
    out = tmp_path / "wide.npz"
    argv = ["scan", "--config", str(config), "--seconds", "1", "--scene", "open_field", "--out", str(out)]
    assert main(argv) == 0, capsys.readouterr().err
    split = np.load(out)
    monkeypatch.setattr(scan, "CAST_PART", 1 << 30)  # the same frame cast in one part
    whole = tmp_path / "whole.npz"
    assert main([*argv[:-1], str(whole)]) == 0
    whole_data = np.load(whole)
    assert len(split["t"]) > 100_000
    for name in ("xyz_int16", "t", "xyz_world", "frame"):
        np.testing.assert_array_equal(split[name], whole_data[name])


def one_line_error(err: str, *words: str) -> str:
    """The single ``livox-viz: error:`` line of ``err``, which must name each of ``words``."""
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("livox-viz: error: ") and "Traceback" not in err, err
    for word in words:
        assert word in lines[0], (word, lines[0])
    return lines[0]


def no_work(monkeypatch: pytest.MonkeyPatch) -> None:
    """Fail the test if ``scan`` starts casting (its outputs must be checked before any work)."""
    from livox_viz.cli import scan_commands

    def refuse(*args: object, **kwargs: object) -> None:
        raise AssertionError("the scene was loaded before the output paths were checked")

    monkeypatch.setattr(scan_commands, "scene_from_args", refuse)


# 2. Every output path is checked before any work ---------------------------------------------------
def test_a_bag_at_a_dangling_link_is_refused_before_any_work(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "target").mkdir()
    (tmp_path / "bag").symlink_to(tmp_path / "target" / "bag")  # dangling, into a folder that exists
    no_work(monkeypatch)
    assert main(["scan", "--seconds", "0.2", "--out", str(tmp_path / "a.ply"), "--rosbag", str(tmp_path / "bag")]) == 2
    one_line_error(capsys.readouterr().err, "bag", "symbolic link")
    assert sorted(p.name for p in tmp_path.rglob("*")) == ["bag", "target"]


@pytest.mark.parametrize("same", ["cloud.ply", "./cloud.ply", "link.ply"])
def test_a_bag_at_the_same_path_as_out_is_refused_before_any_work(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], same: str) -> None:
    monkeypatch.chdir(tmp_path)
    Path("link.ply").symlink_to(tmp_path / "cloud.ply")  # the bag through a link to where --out writes
    no_work(monkeypatch)
    assert main(["scan", "--seconds", "0.2", "--out", "cloud.ply", "--rosbag", same]) == 2
    one_line_error(capsys.readouterr().err, same)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link.ply"]


def test_a_symlink_loop_as_out_is_one_line(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    loop = tmp_path / "loop.ply"
    loop.symlink_to(loop)
    no_work(monkeypatch)
    assert main(["scan", "--seconds", "0.2", "--out", str(loop)]) == 2
    one_line_error(capsys.readouterr().err, "loop.ply", "loop of symbolic links")


def test_a_bag_that_cannot_be_moved_into_place_leaves_nothing(tmp_path: Path, frames_and_mount) -> None:
    """Something appears at the bag's path while it is written: refused in one line, nothing kept."""
    from livox_viz.core.errors import LivoxVizError
    from livox_viz.files.rosbag import RosbagWriter

    frames, mount = frames_and_mount
    with pytest.raises(LivoxVizError, match="appeared while writing"), RosbagWriter(tmp_path / "bag", mount) as bag:
        bag.write_frame(frames[0])
        (tmp_path / "bag").symlink_to(tmp_path / "elsewhere")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bag"]


@pytest.fixture(scope="module")
def frames_and_mount():
    from livox_viz import load_preset
    from livox_viz.casting.scan import LidarScanner
    from livox_viz.scene.scenes import open_scene

    scene = open_scene("urban")
    scanner = LidarScanner(load_preset("livox_mid70"), scene.mesh, scene.vehicle_pose, seed=1)
    return list(scanner.frames(0.2)), scanner.mounted.mount_pose


# 3. A world 2000 km out keeps its coordinates -------------------------------------------------------------
FAR_NORTH = 2_000_000.0  # metres from the world origin (NED x): LAS int32 at 0.1 mm holds +-214 km only


@pytest.fixture(scope="module")
def far_scene(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A wall and a floor 2000 km north of the origin, with the vehicle in front of the wall."""
    scene = tmp_path_factory.mktemp("far") / "far.json"
    scene.write_text(json.dumps({"objects": [
        {"type": "box", "center": [FAR_NORTH + 30, 0, 0], "size": [1, 200, 200]},
        {"type": "box", "center": [FAR_NORTH, 0, 2.5], "size": [200, 200, 1]},
    ], "vehicle_pose": [FAR_NORTH, 0.0, 0.0, 0.0, 0.2, 0.1]}))
    return scene


@pytest.fixture(scope="module")
def far_frames(far_scene: Path) -> list:
    from livox_viz import load_preset
    from livox_viz.casting.scan import LidarScanner
    from livox_viz.scene.scenes import open_scene

    scene = open_scene(str(far_scene))
    return list(LidarScanner(load_preset("livox_mid70"), scene.mesh, scene.vehicle_pose, seed=4).frames(0.2))


def test_a_world_las_far_from_the_origin_is_written_with_offsets_from_the_data(
        tmp_path: Path, far_scene: Path, far_frames: list, capsys: pytest.CaptureFixture[str]) -> None:
    import laspy

    from livox_viz.core.rotations import enu_from_ned

    out = tmp_path / "far.las"
    assert main(["scan", "--scene", str(far_scene), "--seconds", "0.2", "--seed", "4", "--frame", "world",
                 "--out", str(out)]) == 0, capsys.readouterr().err
    las = laspy.read(out)
    expected = enu_from_ned(np.concatenate([f.xyz_world_decoded for f in far_frames]))
    assert len(expected) > 5000 and abs(las.header.offsets[1] - FAR_NORTH) < 100  # ENU y is north
    np.testing.assert_allclose(np.column_stack([las.x, las.y, las.z]), expected, rtol=0,
                               atol=0.5 * las.header.scales.max() + 1e-9)
    assert las.header.scales.max() == pytest.approx(1e-4)


@pytest.mark.parametrize("suffix", [".ply", ".pcd", ".csv"])
def test_world_ply_pcd_csv_keep_far_coordinates_exact(tmp_path: Path, far_frames: list, suffix: str) -> None:
    """Read back by plyfile, pypcd4 and numpy: float64 PLY, 1 um CSV text, float32 PCD relative to the offset its
    header states; not float32's 0.125 m steps 2000 km out."""
    from livox_viz.files.export import PointCloudWriter

    out = tmp_path / f"far{suffix}"
    with PointCloudWriter(out, "world") as writer:
        for frame in far_frames:
            writer.write(frame)
    expected = np.concatenate([f.xyz_world_decoded for f in far_frames])
    if suffix == ".ply":
        from plyfile import PlyData

        vertex = PlyData.read(str(out))["vertex"]
        assert vertex["x"].dtype == np.float64
        xyz = np.column_stack([vertex["x"], vertex["y"], vertex["z"]])
    elif suffix == ".pcd":  # float32 (PCL and Open3D read no binary float64) after the offset its header states
        import re

        from pypcd4 import PointCloud

        cloud = PointCloud.from_path(out)
        assert cloud.types[:3] == (np.float32,) * 3
        stated = re.search(rb"# offset: the point is \(x, y, z\) \+ \((\S+), (\S+), (\S+)\) m", out.read_bytes()[:600])
        offset = np.array([float(v.rstrip(b",")) for v in stated.groups()])
        np.testing.assert_array_equal(offset, [FAR_NORTH, 0, 0])
        xyz = cloud.numpy(("x", "y", "z")).astype(np.float64) + offset
    else:
        xyz = np.loadtxt(out, delimiter=",", skiprows=1)[:, :3]
    assert np.ptp(xyz[:, 0]) > 0.5
    np.testing.assert_allclose(xyz, expected, rtol=0, atol={".ply": 1e-9, ".pcd": 1e-5, ".csv": 1e-6}[suffix])


def test_an_empty_cloud_s_las_offset_is_zero_and_its_scale_the_finest() -> None:
    """No points (the bounds still infinite): a zero offset and the usual scale, three of each for the header."""
    from livox_viz.files.export import LAS_SCALE, las_offset_and_scale

    offset, scale = las_offset_and_scale(np.full(3, np.inf), np.full(3, -np.inf))
    assert offset.tolist() == [0.0, 0.0, 0.0] and scale.tolist() == [LAS_SCALE] * 3


def test_las_offset_and_scale_hold_any_extent() -> None:
    from livox_viz.files.export import las_offset_and_scale

    offset, scale = las_offset_and_scale(np.array([-1e3, 2e6 - 5, -10.0]), np.array([1e3, 2e6 + 5, 90.0]))
    np.testing.assert_array_equal(offset, [0, 2e6, 40])
    np.testing.assert_array_equal(scale, [1e-4] * 3)
    offset, scale = las_offset_and_scale(np.array([-6e6, 0, 0]), np.array([6e6, 1, 1]))  # 12,000 km wide
    assert 6e6 / scale[0] < 2**31 and scale[0] == pytest.approx(1e-2) and scale[1] == 1e-4
    offset, scale = las_offset_and_scale(np.full(3, np.inf), np.full(3, -np.inf))  # no point at all
    np.testing.assert_array_equal(offset, 0)


# 4. A read-only file is never replaced -------------------------------------------------------------
def test_a_file_with_no_write_bit_is_refused_even_for_root(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "cloud.ply"
    out.write_bytes(b"the user's protected file")
    out.chmod(0o444)
    assert main(["scan", "--seconds", "0.1", "--out", str(out)]) == 2
    one_line_error(capsys.readouterr().err, "cloud.ply", "read-only")
    assert out.read_bytes() == b"the user's protected file" and sorted(tmp_path.iterdir()) == [out]


def test_a_folder_with_no_write_bit_is_refused_even_for_root(tmp_path: Path,
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    folder = tmp_path / "kept"
    folder.mkdir()
    folder.chmod(0o555)
    try:
        assert main(["scan", "--seconds", "0.1", "--out", str(folder / "cloud.ply")]) == 2
        one_line_error(capsys.readouterr().err, "cloud.ply", "the folder")
        assert list(folder.iterdir()) == []
    finally:
        folder.chmod(0o755)


def test_a_file_the_user_may_not_write_is_refused_in_a_folder_they_may() -> None:
    """As a user other than the file's owner (root runs this as nobody): ``echo >`` would refuse, so must we,
    although the folder lets us rename over it."""
    import os
    import shutil
    import subprocess
    import sys
    import tempfile

    folder = Path(tempfile.mkdtemp(prefix="livox-viz-shared-"))  # pytest's own folder is closed to others
    try:
        folder.chmod(0o777)  # anyone may make and rename files here (no sticky bit)
        out = folder / "cloud.ply"
        out.write_bytes(b"someone else's file")
        out.chmod(0o644)
        command = [sys.executable, "-m", "livox_viz", "scan", "--seconds", "0.1", "--out", str(out)]
        as_nobody = ["setpriv", "--reuid=65534", "--regid=65534", "--clear-groups"]
        if os.geteuid() == 0 and shutil.which("setpriv") and subprocess.run(
                [*as_nobody, sys.executable, "-c", "import livox_viz.cli"], cwd=folder, capture_output=True,
                env={**os.environ, "HOME": str(folder)}).returncode == 0:
            command = [*as_nobody, *command]
            assert subprocess.run([*as_nobody, "sh", "-c", f"echo x > {out}"], capture_output=True).returncode != 0
        else:  # not root, or nobody cannot reach this interpreter: we own the file, so take our write bit away
            out.chmod(0o444)
        result = subprocess.run(command, capture_output=True, text=True, cwd=folder,
                                env={**os.environ, "HOME": str(folder), "LIVOX_VIZ_PRESETS": str(folder)})
        assert result.returncode == 2, result.stderr
        one_line_error(result.stderr, "cloud.ply", "read-only")
        assert out.read_bytes() == b"someone else's file" and sorted(folder.iterdir()) == [out]
    finally:
        shutil.rmtree(folder)


def test_a_pipe_behind_a_link_is_never_replaced(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A named pipe (a device would do the same; a test must not risk the machine's own /dev/null)."""
    import os
    import stat

    pipe = tmp_path / "pipe"
    os.mkfifo(pipe)
    link = tmp_path / "cloud.ply"
    link.symlink_to(pipe)
    assert main(["scan", "--seconds", "0.1", "--out", str(link)]) == 2
    one_line_error(capsys.readouterr().err, "pipe", "not a regular file")
    assert stat.S_ISFIFO(pipe.stat().st_mode) and sorted(p.name for p in tmp_path.iterdir()) == ["cloud.ply", "pipe"]


# 5. A full disk: one line naming the file, nothing left ------------------------------------------------
FULL_DISK_SCRIPT = """
import contextlib, io, json, resource, signal, sys
signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write past the limit fails with EFBIG, as a full disk's ENOSPC
from livox_viz.cli import main
results = []
for limit, argv in json.loads(sys.argv[1]):
    resource.setrlimit(resource.RLIMIT_FSIZE, (limit, resource.RLIM_INFINITY))
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        code = main(argv)
    resource.setrlimit(resource.RLIMIT_FSIZE, (resource.RLIM_INFINITY, resource.RLIM_INFINITY))
    results.append((code, err.getvalue()))
print(json.dumps(results))
"""


def test_a_full_disk_names_the_file_and_leaves_nothing(tmp_path: Path) -> None:
    """Every format and the bag, the disk filling at several points of the writing (a file size limit stands in
    for the full disk: the same failed writes, and buffered data that cannot be flushed when closing)."""
    import subprocess
    import sys

    runs = []
    for limit in (20_000, 200_000, 700_000):
        for name in ("cloud.ply", "cloud.pcd", "cloud.las", "cloud.npz", "cloud.csv"):
            runs.append((limit, ["scan", "--seconds", "0.4", "--out", name]))
        runs.append((limit, ["scan", "--seconds", "0.4", "--rosbag", "bag"]))
        runs += [(limit, ["pattern", "--seconds", "2", "--out", name]) for name in ("pattern.npz", "pattern.csv")]
    result = subprocess.run([sys.executable, "-c", FULL_DISK_SCRIPT, json.dumps(runs)], cwd=tmp_path,
                            capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    for (limit, argv), (code, err) in zip(runs, json.loads(result.stdout.splitlines()[-1]), strict=True):
        assert code == 2, (limit, argv, err)
        one_line_error(err, argv[-1])
    assert list(tmp_path.iterdir()) == []


# 5b. A full disk stops the writing at a whole frame; closing keeps the frames before -----------------------
@pytest.fixture(scope="module")
def four_frames() -> list:
    from livox_viz import load_preset
    from livox_viz.casting.scan import LidarScanner
    from livox_viz.scene.scenes import open_scene

    scene = open_scene("urban")
    return list(LidarScanner(load_preset("livox_mid70"), scene.mesh, scene.vehicle_pose, seed=1).frames(0.4))


def _read_sensor_points(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """The points (sensor FRD) and their frame numbers of a file, read by third-party readers (plyfile, pypcd4,
    laspy, numpy, the csv module)."""
    import csv

    import laspy
    import pypcd4
    from plyfile import PlyData

    from livox_viz.core.rotations import flu_from_frd

    if path.suffix == ".ply":
        vertex = PlyData.read(str(path))["vertex"]
        return np.column_stack([vertex["x"], vertex["y"], vertex["z"]]), np.asarray(vertex["frame"])
    if path.suffix == ".pcd":
        data = pypcd4.PointCloud.from_path(path).pc_data
        return np.column_stack([data["x"], data["y"], data["z"]]), np.asarray(data["frame"])
    if path.suffix == ".las":
        las = laspy.read(path)
        flu = np.column_stack([las.x, las.y, las.z])
        return flu_from_frd(flu), np.asarray(las["frame"])  # FLU and FRD differ by y and z signs: its own inverse
    if path.suffix == ".npz":
        data = np.load(path)
        return data["xyz_sensor"], data["frame"]
    with open(path, newline="") as handle:
        rows = list(csv.reader(line for line in handle if not line.startswith("#")))
    columns = {name: np.array([float(row[k]) for row in rows[1:]]) for k, name in enumerate(rows[0])}
    return np.column_stack([columns["x"], columns["y"], columns["z"]]), columns["frame"]


def _assert_holds(path: Path, frames: list) -> None:
    xyz, frame = _read_sensor_points(path)
    np.testing.assert_allclose(xyz, np.concatenate([f.xyz_decoded for f in frames]), atol=2e-4)
    assert frame.tolist() == np.concatenate([np.full(len(f), f.index) for f in frames]).tolist()


@pytest.mark.parametrize("suffix", [".ply", ".pcd", ".las", ".npz", ".csv"])
def test_a_disk_too_full_for_the_next_frame_stops_the_writing_and_close_keeps_the_frames_before(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, four_frames: list, suffix: str) -> None:
    """The writer checks the disk before each frame: a frame that does not fit is not written, nor any later one
    (the writer has stopped), and closing makes the file of the whole frames before, as readers see it."""
    from livox_viz.files import export

    asked: list[str] = []

    def free(folder: str) -> int:
        asked.append(str(folder))
        return 1 << 40 if len(asked) <= 2 else 4096

    monkeypatch.setattr(export, "free_bytes", free)
    out = tmp_path / f"rec{suffix}"
    writer = export.PointCloudWriter(out, "sensor")
    writer.write(four_frames[0])
    writer.write(four_frames[1])
    for frame in four_frames[2:]:
        with pytest.raises(export.WritingStopped, match=r"disk is full \(0\.0 MiB free"):
            writer.write(frame)
    assert (writer.frames, writer.count) == (2, len(four_frames[0]) + len(four_frames[1]))
    assert writer.close() == out
    _assert_holds(out, four_frames[:2])
    sidecar = export.sidecar_path(out)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([out.name, *([sidecar.name] if sidecar else [])])
    if sidecar is not None:  # a CSV's sidecar counts the rows kept
        assert json.loads(sidecar.read_text())["rows"] == writer.count
    assert all(Path(folder).parent == tmp_path for folder in asked)  # the disk of the destination


@pytest.mark.parametrize("suffix", [".ply", ".pcd", ".csv", ".las", ".npz"])
def test_only_npz_asks_room_for_a_second_copy_of_the_points(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, four_frames: list, suffix: str) -> None:
    """PLY, PCD, CSV and LAS are finished in place (a header over the room kept for it, a rename): a disk that
    holds each frame takes them all. An NPZ is assembled from its columns when closed: the writer stops while the
    disk still holds that copy."""
    from livox_viz.files import export

    whole = tmp_path / "whole" / f"rec{suffix}"
    whole.parent.mkdir()
    with export.PointCloudWriter(whole, "sensor") as writer:
        for frame in four_frames:
            writer.write(frame)
    free = export.FREE_MARGIN + whole.stat().st_size  # the room of the whole file, once
    monkeypatch.setattr(export, "free_bytes", lambda folder: free)
    out = tmp_path / f"rec{suffix}"
    with export.PointCloudWriter(out, "sensor") as writer:
        written = 0
        for frame in four_frames:
            try:
                writer.write(frame)
                written += 1
            except export.WritingStopped:
                break
    if suffix == ".npz":
        assert 1 <= written < len(four_frames)  # the points and their copy outgrow the room before the end
        assert out.stat().st_size <= free - export.FREE_MARGIN  # what it kept free held the file it made
    else:
        assert written == len(four_frames)
    _assert_holds(out, four_frames[:written])


FILE_LIMIT_SCRIPT = """
import json, resource, signal, sys
signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write past the limit fails with EFBIG, as a full disk's ENOSPC
from livox_viz import load_preset
from livox_viz.casting.scan import LidarScanner
from livox_viz.files.export import PointCloudWriter, WritingStopped
from livox_viz.scene.scenes import open_scene
scene = open_scene("urban")
frames = list(LidarScanner(load_preset("livox_mid70"), scene.mesh, scene.vehicle_pose, seed=1).frames(0.4))
writer = PointCloudWriter(sys.argv[2], "sensor", ascii=sys.argv[3] == "ascii")
resource.setrlimit(resource.RLIMIT_FSIZE, (int(sys.argv[1]), resource.RLIM_INFINITY))
stopped = ""
for frame in frames:
    try:
        writer.write(frame)
    except WritingStopped as error:
        stopped = str(error)
        break
writer.close()
print(json.dumps([writer.frames, stopped]))
"""


@pytest.mark.parametrize(("suffix", "mode"), [(".ply", "binary"), (".pcd", "binary"), (".pcd", "ascii"),
                                              (".csv", "ascii"), (".las", "binary")])
def test_a_write_that_fails_inside_a_frame_is_cut_back_to_the_frames_before(
        tmp_path: Path, four_frames: list, suffix: str, mode: str) -> None:
    """A write the disk refuses halfway through a frame (a file size limit stands in for the full disk: the same
    short write, then EFBIG): the part written is cut off, and closing keeps the whole frames before it."""
    import subprocess
    import sys

    from livox_viz.files import export
    from livox_viz.files.export import PointCloudWriter

    whole = tmp_path / f"whole{suffix}"
    with PointCloudWriter(whole, "sensor", ascii=mode == "ascii") as writer:
        for frame in four_frames:
            writer.write(frame)
    out = tmp_path / f"cut{suffix}"
    limit = int(whole.stat().st_size * 0.6)  # inside the third of four frames of about one size
    result = subprocess.run([sys.executable, "-c", FILE_LIMIT_SCRIPT, str(limit), str(out), mode],
                            capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    kept, stopped = json.loads(result.stdout.splitlines()[-1])
    assert kept == 2 and "cannot write" in stopped and str(out) in stopped
    _assert_holds(out, four_frames[:2])
    written = [path for path in (out, whole) for path in (path, export.sidecar_path(path)) if path is not None]
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(path.name for path in written)


def test_npz_columns_cut_back_to_the_rows_appended_whole(tmp_path: Path) -> None:
    """An append that fails after some columns were written: every column goes back to the whole chunks."""
    from livox_viz.files.npzstream import NpzColumns

    work = tmp_path / "work"
    work.mkdir()
    columns = NpzColumns(work, {"xyz": ("<f8", (3,)), "t": ("<f8", ()), "frame": ("<u4", ())})
    chunks = [{"xyz": np.full((n, 3), k + 0.5), "t": np.arange(n) + 10.0 * k, "frame": np.full(n, k)}
              for k, n in enumerate((5, 7, 9))]
    columns.append(chunks[0])
    columns.append(chunks[1])
    columns._files["frame"].close()
    columns._files["frame"] = open(work / "frame.raw", "rb")  # the last column's write fails (not writable)
    with pytest.raises(OSError):
        columns.append(chunks[2])
    assert (work / "xyz.raw").stat().st_size == 24 * (5 + 7 + 9)  # the failed chunk's first column was written
    columns.cut_to_rows()
    assert [(work / f"{name}.raw").stat().st_size for name in ("xyz", "t", "frame")] == [24 * 12, 8 * 12, 4 * 12]
    columns.finish(tmp_path / "cut.npz")
    data = np.load(tmp_path / "cut.npz")
    for name in ("xyz", "t", "frame"):
        np.testing.assert_array_equal(data[name], np.concatenate([chunks[0][name], chunks[1][name]]))


def test_each_npz_member_s_local_header_agrees_with_the_central_directory(tmp_path: Path) -> None:
    """numpy (Python's zipfile) reads only the central directory's method and flags; 7-Zip, unzip and streaming
    readers take the local header's. Each member's local header says what its central record says: stored, no
    flags, version 4.5 (ZIP64), the same CRC-32, name and ZIP64 sizes."""
    import struct
    import zipfile

    from livox_viz.files.npzstream import NpzColumns

    work = tmp_path / "work"
    work.mkdir()
    columns = NpzColumns(work, {"xyz": ("<f4", (3,)), "t": ("<f8", ())})
    columns.append({"xyz": np.ones((50, 3), np.float32), "t": np.arange(50.0)})
    columns.finish(tmp_path / "c.npz")
    blob = (tmp_path / "c.npz").read_bytes()
    with zipfile.ZipFile(tmp_path / "c.npz") as archive:
        members = archive.infolist()
        assert archive.testzip() is None
    assert [m.filename for m in members] == ["xyz.npy", "t.npy"]
    for member in members:
        at = member.header_offset
        (signature, version, flags, method, _time, _date, crc, packed, unpacked, name_length,
         extra_length) = struct.unpack("<IHHHHHIIIHH", blob[at:at + 30])
        assert (signature, version, flags, method) == (0x04034B50, 45, member.flag_bits, member.compress_type)
        assert (flags, method) == (0, zipfile.ZIP_STORED)
        assert crc == member.CRC and blob[at + 30:at + 30 + name_length] == member.filename.encode()
        extra = blob[at + 30 + name_length:at + 30 + name_length + extra_length]
        assert (packed, unpacked) == (0xFFFFFFFF, 0xFFFFFFFF)  # the sizes are in the ZIP64 extra field
        assert struct.unpack("<HHQQ", extra) == (1, 16, member.file_size, member.compress_size)


# 6. Inputs are read no further than their limit ----------------------------------------------------
ENDLESS_SCRIPT = """
import resource, sys
resource.setrlimit(resource.RLIMIT_AS, (3 << 30, 3 << 30))  # a regression fails here, not the machine
from livox_viz.cli import main
sys.exit(main(sys.argv[1:]))
"""


@pytest.mark.parametrize("argv", [["info", "--config", "/dev/zero"], ["info", "--preset", "/dev/zero"],
                                  ["fit", "--to", "/dev/zero", "--out", "f.json"]])
def test_an_endless_config_is_refused_at_its_size_limit(tmp_path: Path, argv: list[str]) -> None:
    import subprocess
    import sys

    result = subprocess.run([sys.executable, "-c", ENDLESS_SCRIPT, *argv], cwd=tmp_path, capture_output=True,
                            text=True, timeout=120)
    assert result.returncode == 2, result.stderr[-2000:]
    one_line_error(result.stderr, "/dev/zero", "at most 64 MiB")
    assert list(tmp_path.iterdir()) == []


# 7. ROS names as ROS 2 validates them ---------------------------------------------------------------
BAD_ROS_NAMES = [
    ("lidar=/tf", "the bag's own transform topic"),
    ("odom=/tf_static", "the bag's own transform topic"),
    ("points=/livox/lidar", "collide"),
    ("imu=/odom", "collide"),
    ("lidar=livox/lidar", "must be absolute"),
    ("lidar=/livox/lidar/", "must not end with"),
    ("imu=/livox//imu", "repeated '/'"),
    ("imu=/livox/9imu", "must not start with a number"),
    ("imu=/livox/imu-raw", "must not contain '-'"),
    ("imu=/" + "i" * 300, "longer than 247"),
    ("lidar=/~/lidar", "must not contain '~'"),
    ("body_frame=odom", "collide"),
    ("lidar_frame=base_link", "collide"),
    ("world_frame=/odom", "cannot start with a '/'"),
    ("lidar_frame=livox frame", "spaces"),
    ("tf=/x", "allowed: NAME=VALUE"),
]


@pytest.mark.parametrize(("names", "message"), BAD_ROS_NAMES, ids=[n[:30] for n, _ in BAD_ROS_NAMES])
def test_invalid_or_colliding_ros_names_are_one_line_before_any_work(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], names: str,
        message: str) -> None:
    no_work(monkeypatch)
    assert main(["scan", "--seconds", "0.2", "--rosbag", str(tmp_path / "bag"), "--ros-names", names]) == 2
    one_line_error(capsys.readouterr().err, message)
    assert list(tmp_path.iterdir()) == []


def test_valid_ros_names_reach_the_bag(tmp_path: Path) -> None:
    from rosbags.rosbag2 import Reader

    bag = tmp_path / "bag"
    names = "lidar=/drone_1/lidar,points=/drone_1/points,imu=/drone_1/imu_0,odom=/ground_truth/odom,"\
            "lidar_frame=drone_1/livox,body_frame=drone_1/base_link,world_frame=map"
    assert main(["scan", "--seconds", "0.2", "--rosbag", str(bag), "--ros-names", names]) == 0
    with Reader(bag) as reader:
        topics = {c.topic for c in reader.connections}
    assert topics == {"/drone_1/lidar", "/drone_1/points", "/drone_1/imu_0", "/ground_truth/odom", "/tf", "/tf_static"}


# 8. No RuntimeWarning reaches stderr (pytest turns every warning into an error) ------------------------
def test_a_fov_narrower_than_a_coverage_cell_has_a_coverage(tmp_path: Path,
                                                            capsys: pytest.CaptureFixture[str]) -> None:
    from livox_viz.patterns.metrics import LIVOX_CELL_DEG, coverage_curve

    xy = np.random.default_rng(0).uniform(-1e-4, 1e-4, (1000, 2))
    fraction = coverage_curve(xy, [0, 1, 1000], 5e-4, LIVOX_CELL_DEG)
    assert fraction[0] == 0 and 0 < fraction[1] <= fraction[2] <= 1  # the cells that meet at the boresight
    config = tmp_path / "narrow.json"
    config.write_text(json.dumps({**SEED_JSON, "CameraFOV": 0.001}))
    assert main(["compare", "--config", str(config), "livox_mid40"]) == 0, capsys.readouterr().err


def test_a_pose_beyond_any_local_frame_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["scan", "--seconds", "0.1", "--pose", "1e300,0,0,0,0,0", "--out", str(tmp_path / "x.npz")]) == 2
    one_line_error(capsys.readouterr().err, "1e+07 m")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("where", ["--pose", "SensorAngEular", "vehicle_pose"])
def test_an_angle_of_a_thousand_turns_and_more_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                           where: str) -> None:
    """At 1e20 rad the floats are 16,000 rad apart: the orientation was noise, taken without a word."""
    argv = ["scan", "--seconds", "0.1", "--out", str(tmp_path / "x.npz")]
    if where == "--pose":
        argv += ["--pose", "0,0,-2,0,0,1e20"]
    elif where == "SensorAngEular":
        config = tmp_path / "turned.json"
        config.write_text(json.dumps({**SEED_JSON, "SensorAngEular": [0, 1e20, 0]}))
        argv += ["--config", str(config)]
    else:
        scene = tmp_path / "turned_scene.json"
        scene.write_text(json.dumps({"objects": [{"type": "ground", "center": [0, 0, 0], "size": [50, 50]}],
                                     "vehicle_pose": [0, 0, -2, 1e20, 0, 0]}))
        argv += ["--scene", str(scene)]
    assert main(argv) == 2
    one_line_error(capsys.readouterr().err, "10000 rad")
    assert sorted(path.name for path in tmp_path.iterdir() if path.suffix == ".npz") == []
    turned = SEED_JSON | {"SensorAngEular": [0, -1e4, 6283.0]}  # the bound itself, and 1,000 turns, are taken
    config = tmp_path / "thousand_turns.json"
    config.write_text(json.dumps(turned))
    assert main(["info", "--config", str(config)]) == 0, capsys.readouterr().err


# 9. A signal at any moment of a writer's set-up leaves nothing ------------------------------------------
class Interrupted(BaseException):
    """Stands in for the exception a SIGTERM handler raises (the CLI's Terminated) or Ctrl-C."""


def interrupt_at(step: int, files: tuple[str, ...]):
    """A trace function raising :class:`Interrupted` at the ``step``-th bytecode run in ``files``: where a signal
    handler's exception can surface (and more: every opcode). Returns the tracer and a one-item list counting
    the steps seen."""
    seen = [0]

    def local(frame, event, arg):
        if event == "opcode":
            seen[0] += 1
            if seen[0] == step:
                raise Interrupted(step)
        return local

    def tracer(frame, event, arg):
        if frame.f_code.co_filename.endswith(files):
            frame.f_trace_opcodes = True
            return local
        return None

    return tracer, seen


def set_up_interrupted_everywhere(make, folder: Path, files: tuple[str, ...]) -> int:
    """Run ``make()`` interrupted at its 1st, 2nd, ... bytecode in ``files`` until it runs whole; after each
    interruption the CLI's own clean-up (:func:`remove_unfinished`) runs and ``folder`` must be empty.
    Returns how many points were tried.

    It runs in a thread of its own: an exception raised at some opcodes (inside an ``except`` block's own clean-up)
    leaves the thread's "exception being handled" set after its frame is gone. In the main thread that stale
    exception became the context of every later exception, and of an unrelated test's failure in CI.
    """
    import gc
    import threading

    outcome: list[object] = []

    def run() -> None:
        try:
            outcome.append(_interrupt_everywhere(make, folder, files))
        except BaseException as exc:  # the assertion, given back to the test's thread below
            outcome.append(exc)

    worker = threading.Thread(target=run)
    worker.start()
    worker.join()
    # What the interruptions left to the collector (a file opened a bytecode before it was kept, in a traceback's
    # cycle) is collected now, under the calling test's ignored warnings: collected later, its ResourceWarning
    # failed the next test on the worker (a fresh clone's make test).
    gc.collect()
    if isinstance(outcome[0], BaseException):
        raise outcome[0]
    return int(outcome[0])  # type: ignore[call-overload]


def _interrupt_everywhere(make, folder: Path, files: tuple[str, ...]) -> int:
    import sys

    from livox_viz.core.atomic import remove_unfinished

    step = 1
    previous = sys.gettrace()  # coverage's, when measured: given back after each try
    while True:
        tracer, seen = interrupt_at(step, files)
        sys.settrace(tracer)
        try:
            writer = make()
        except Interrupted:
            writer = None
        finally:
            sys.settrace(previous)
        if writer is not None:
            assert seen[0] < step  # ran whole: every step was tried
            writer.abort()
            assert list(folder.iterdir()) == []
            return step - 1
        remove_unfinished()  # what main() does when a signal stops it
        assert list(folder.iterdir()) == [], f"interrupted at step {step} of the set-up"
        step += 1


# A handle opened just before an interruption and not yet stored is closed by the garbage collector (with a
# ResourceWarning): harmless for a process that is stopping. What these tests look for is files left on disk.
SIGNAL_WARNINGS = [pytest.mark.filterwarnings("ignore::ResourceWarning"),
                   pytest.mark.filterwarnings("ignore::pytest.PytestUnraisableExceptionWarning")]


@pytest.mark.parametrize("suffix", [".ply", ".las", ".npz"])
@SIGNAL_WARNINGS[0]
@SIGNAL_WARNINGS[1]
def test_a_signal_anywhere_in_a_file_writers_set_up_leaves_nothing(tmp_path: Path, suffix: str) -> None:
    from livox_viz.files.export import PointCloudWriter

    def make():
        return PointCloudWriter(tmp_path / f"cloud{suffix}")

    make().abort()  # imports warmed: every step below is the set-up itself
    tried = set_up_interrupted_everywhere(make, tmp_path, ("livox_viz/core/atomic.py", "livox_viz/files/export.py",
                                                          "livox_viz/files/npzstream.py"))
    assert tried > 100


@SIGNAL_WARNINGS[0]
@SIGNAL_WARNINGS[1]
def test_a_signal_anywhere_in_a_bag_writers_set_up_leaves_nothing(tmp_path: Path,
                                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    """Every bytecode of the bag writer's constructor and of atomic.py; the rosbags part of the set-up (a
    quarter second a time) is stood in for by a file in the work folder, and interrupted for real below."""
    from livox_viz.core.poses import Pose
    from livox_viz.files.rosbag import RosbagWriter

    def open_light(self, mount) -> None:
        (self._work.path / "bag").mkdir()
        (self._work.path / "bag" / "metadata.yaml").write_text("stand-in")

    monkeypatch.setattr(RosbagWriter, "_open", open_light)

    def make():
        return RosbagWriter(tmp_path / "bag", Pose((0.1, 0.0, -0.2), 0.0, 0.2, 0.0))

    make().abort()
    assert set_up_interrupted_everywhere(make, tmp_path, ("livox_viz/core/atomic.py",
                                                          "livox_viz/files/rosbag.py")) > 100


def test_a_signal_in_the_bags_rosbags_set_up_leaves_nothing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    """SIGTERM while rosbags opens the bag (the last connection): one line, exit 143, nothing left."""
    import signal

    from rosbags.rosbag2 import Writer

    from livox_viz.cli import Terminated

    add_connection = Writer.add_connection

    def terminated_at_tf_static(self, topic, *args, **kwargs):
        if topic == "/tf_static":
            raise Terminated(signal.SIGTERM)
        return add_connection(self, topic, *args, **kwargs)

    monkeypatch.setattr(Writer, "add_connection", terminated_at_tf_static)
    assert main(["scan", "--seconds", "0.2", "--rosbag", str(tmp_path / "bag")]) == 143
    assert "stopped by SIGTERM" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []
