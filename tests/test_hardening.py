"""Hostile but realistic use: bad input everywhere, kill signals, size limits, a listener that stays awake."""

from __future__ import annotations

import errno
import json
import os
import signal
import socket
import stat
import struct
import subprocess
import sys
import time
from pathlib import Path

import laspy
import numpy as np
import pytest
import trimesh

from livox_viz.cli import main
from livox_viz.core.atomic import remove_dead_leftovers, write_text_atomic
from livox_viz.fitting.reference import shipped_table_dir
from tests.conftest import SEED_JSON, free_udp_port, start_listening

HUGE = {**SEED_JSON, "DataWidth": 5000, "DataHeight": 2000, "DataCheckFreq": 1000}


def write_inputs(folder: Path) -> None:
    """The bad files the table below names, made fresh in ``folder``."""
    (folder / "a_folder.ply").mkdir()
    (folder / "a_folder.npz").mkdir()
    (folder / "a_folder.png").mkdir()
    (folder / "a_folder.json").mkdir()
    (folder / "huge.json").write_text(json.dumps(HUGE))
    (folder / "deep.json").write_text("[" * 100_000 + "]" * 100_000)
    # A number past float's range overflows every check that converts it; two detection figures at one range
    # divide by zero in the lidar equation's loss.
    (folder / "big_int.json").write_text(json.dumps(SEED_JSON)[:-1] + ', "LivoxVizReturns": {"blind_zone_m": 1'
                                         + "0" * 400 + "}}")
    (folder / "twice.json").write_text(json.dumps(SEED_JSON)[:-1] + ', "CameraFOV": 30}')
    (folder / "same_range.json").write_text(json.dumps(
        {**SEED_JSON, "LivoxVizReturns": {"detection_range_m": [[0.1, 1e5], [0.8, 1e5]]}}))
    box = {"type": "box", "center": [5, 0, 0], "size": [1, 1, 1]}
    (folder / "big_scene.json").write_text(json.dumps({"objects": [{**box, "material": 0.5}]}).replace(
        "0.5", "1" + "0" * 400))
    (folder / "deep_scene.json").write_text('{"objects": ' + "[" * 100_000 + "]" * 100_000 + "}")
    (folder / "walls.obj").write_text("v 5 -1 -1\nv 5 1 -1\nv 5 0 1\nf 1 2 3\n")
    (folder / "walls.materials.json").write_text('{"walls": ' + "[" * 100_000 + "]" * 100_000 + "}")
    (folder / "nan.json").write_text(json.dumps(SEED_JSON).replace("2.956", "NaN"))
    (folder / "wide.json").write_text(json.dumps({**SEED_JSON, "DataWidth": 1e9}))
    (folder / "empty.json").write_text("")
    (folder / "header_only.csv").write_text("Time/s,Azimuth/deg,Zenith/deg\n")
    (folder / "latin1.csv").write_bytes("Time/s,Azimuth/deg,Zenith/deg\n0,1,2\n0,\xe9,3\n".encode("latin-1"))
    rows = "\n".join(f"{k / 1e5},{10 * np.cos(k / 50):.6f},{90 + 10 * np.sin(k / 50):.6f},7,8" for k in range(3000))
    (folder / "short_extra.csv").write_text("Time/s,Azimuth/deg,Zenith/deg,Reflectivity,Tag\n" + rows + "\n")
    (folder / "bad_cell.csv").write_text("Time/s,Azimuth/deg,Zenith/deg\n0,1,91\n0,1,x\n")
    table = np.load(shipped_table_dir() / "mid40.npy")[:5000]
    np.save(folder / "short.npy", table)
    np.save(folder / "tiny.npy", table[:1000])
    np.save(folder / "pickled.npy", np.array([{"a": 1}, 2], dtype=object), allow_pickle=True)
    with open(folder / "lying.npy", "wb") as handle:  # its header claims two billion rows
        np.lib.format.write_array_header_1_0(handle, {"descr": "<f8", "fortran_order": False,
                                                      "shape": (2_000_000_000, 2)})
        handle.write(bytes(1600))


BAD_INPUTS: list[tuple[list[str], str]] = [
    (["scan", "--seconds", "0.1", "--out", "a_folder.ply"], "is a folder"),
    (["pattern", "--seconds", "0.1", "--out", "a_folder.npz"], "is a folder"),
    (["render", "--seconds", "0.1", "--out", "a_folder.png"], "is a folder"),
    (["fit", "short.npy", "--out", "a_folder.json"], "is a folder"),
    (["listen", "--port", "0", "--seconds", "0.1", "--record", "a_folder.npz"], "is a folder"),
    (["scan", "--seconds", "0.1", "--out", "/proc/livox.ply"], "the folder /proc is read-only"),
    (["listen", "--port", "0", "--seconds", "0.1", "--record", "/proc/livox.npz"], "the folder /proc is read-only"),
    (["scan", "--seconds", "0.1", "--out", "missing/x.ply"], "does not exist"),
    (["pattern", "--seed", "-1", "--out", "p.npz"], "allowed: a whole number from 0"),
    (["scan", "--seed", "-1", "--out", "p.ply"], "allowed: a whole number from 0"),
    (["coverage", "--seed", "-1"], "allowed: a whole number from 0"),
    (["listen", "--port", "0", "--frames", "0"], "allowed: a whole number >= 1"),
    (["listen", "--port", "0", "--frames", "-5"], "allowed: a whole number >= 1"),
    (["render", "--seed", "-1", "--out", "r.png"], "allowed: a whole number from 0"),
    (["publish", "--seed", "-1", "--to", "127.0.0.1:9"], "allowed: a whole number from 0"),
    (["fit", "short.npy"], "allowed: at least 0.1 s"),
    (["compare", "tiny.npy"], "allowed: at least 0.05 s"),
    (["render", "--reference", "short.npy", "--seconds", "0.05", "--size", "200x150", "--out", "r.png"], ""),
    (["fit", "header_only.csv"], "no data rows"),
    (["fit", "latin1.csv"], "not UTF-8"),
    (["fit", "short_extra.csv"], "allowed: at least 0.1 s"),
    (["fit", "bad_cell.csv"], "at line 3"),
    (["fit", "pickled.npy"], "holds Python objects (pickled data, never loaded); allowed: a NumPy .npy array"),
    (["compare", "lying.npy"], "2,000,000,000 rows; allowed: at most 10,000,000"),
    (["fit", "a_folder.ply"], "is a folder"),
    (["listen", "--port", "70000"], "allowed: 0 (any free port) to 65535"),
    (["listen", "--port", "-1"], "allowed: 0 (any free port) to 65535"),
    (["info", "--config", "deep.json"], "nested too deeply"),
    (["info", "--config", "nan.json"], "nan.json: otherParams[1] = NaN"),
    (["info", "--config", "big_int.json"],
     "LivoxVizReturns.blind_zone_m = 10000000000000000000... (401 digits), too large for a number"),
    (["info", "--config", "same_range.json"], "the brighter target must reach farther"),
    (["info", "--config", "twice.json"], "twice.json: the key 'CameraFOV' appears twice in one object"),
    (["scan", "--scene", "big_scene.json", "--seconds", "0.1", "--out", "s.ply"],
     "objects[0].material = 10000000000000000000... (401 digits), too large"),
    (["scan", "--scene", "deep_scene.json", "--seconds", "0.1", "--out", "s.ply"], "nested too deeply"),
    (["scan", "--scene", "walls.obj", "--seconds", "0.1", "--out", "s.ply"],
     "walls.materials.json: not a readable material sidecar (JSON nested too deeply"),
    (["info", "--config", "wide.json"], "DataWidth = 1000000000.0; allowed: an integer in [1, 5000]"),
    (["info", "--config", "empty.json"], "is empty"),
    (["info", "--config", "a_folder.json"], "is a folder"),
    (["scan", "--config", "huge.json", "--seconds", "0.1", "--out", "h.ply"], "asks for 1,000,000,000 points"),
    (["scan", "--seconds", "1e9", "--out", "h.ply"], "allowed: at most 100,000,000; pass --force"),
    (["pattern", "--config", "huge.json", "--seconds", "0.1", "--out", "h.npz"], "allowed: at most"),
    (["render", "--config", "huge.json", "--out", "r.png"], "integration window asks for"),
    (["publish", "--config", "huge.json", "--to", "127.0.0.1:9", "--seconds", "1"], "allowed: at most"),
    (["coverage", "--cell-deg", "100"], "larger than the FOV's half-angle"),
    (["publish", "--speed", "1e-9", "--to", "127.0.0.1:9"], "allowed: 0.01 to 1000"),
    (["request", "--to", "127.0.0.1", "--window", "99999", "--dry-run"], "allowed: 0 to 45525"),
    (["gui", "--listen", "--port", "0"], "needs a display"),
    (["scan", "--seconds", "2", "--trajectory", "nowhere.txt", "--out", "m.npz"], "no such TUM trajectory"),
    (["scan", "--seconds", "0.1", "--imu-noise", "1,2,3", "--rosbag", "bag"], "allowed: 4 numbers"),
]


@pytest.mark.parametrize(("argv", "message"), BAD_INPUTS, ids=[" ".join(a)[:60] for a, _ in BAD_INPUTS])
def test_bad_input_is_one_line_exit_2_and_leaves_nothing(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], argv: list[str],
    message: str,
) -> None:
    import re

    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("DISPLAY", raising=False)
    write_inputs(tmp_path)
    before = sorted(p.name for p in tmp_path.iterdir())
    code = main(argv)
    err = capsys.readouterr().err
    if not message:  # a short table is a fine reference to draw: it must simply work
        assert code == 0, err
        assert sorted(p.name for p in tmp_path.iterdir()) == sorted([*before, "r.png"])
        return
    lines = [line for line in err.splitlines() if not line.startswith("publishing")]
    assert code == 2, err
    assert len(lines) == 1 and "Traceback" not in err and re.match(r"livox-viz( [a-z]+)?: error: ", lines[0]), err
    assert re.search(message if "|" in message else re.escape(message), lines[0]), lines[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_publish_where_every_send_is_refused_is_one_line(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                        capsys: pytest.CaptureFixture[str]) -> None:
    """A network that refuses every datagram (a firewall; the broadcast address was this test's case until the
    sender allowed broadcasts) ends publish with one line, not a frame counter that counts nothing sent."""
    import socket

    def refused(self, data, address):
        raise PermissionError(errno.EACCES, "Permission denied")

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(socket.socket, "sendto", refused)
    code = main(["publish", "--to", "127.0.0.1:9", "--seconds", "0.2", "--unpaced"])
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if not line.startswith(("publishing", "  1 frames"))]
    assert code == 2 and "Traceback" not in err, err
    assert lines == ["livox-viz: error: nothing could be sent to udp 127.0.0.1:9 (Permission denied)"], lines
    assert not list(tmp_path.iterdir())


def test_disk_full_is_one_line_and_leaves_nothing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    from livox_viz.files import npzstream

    def full(self, arrays):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(npzstream.NpzColumns, "append", full)
    out = tmp_path / "cloud.npz"
    assert main(["scan", "--seconds", "0.1", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "No space left on device" in err
    assert list(tmp_path.iterdir()) == []


def start_writing(tmp_path: Path, argv: list[str]) -> subprocess.Popen:
    """``livox-viz argv`` in a child, once its temporary files exist and it is well into the writing."""
    process = subprocess.Popen([sys.executable, "-m", "livox_viz", *argv], cwd=tmp_path,
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and not any(tmp_path.iterdir()):
        time.sleep(0.05)
    time.sleep(1.0)
    assert process.poll() is None, process.communicate()
    assert any(p.name.startswith(".big") for p in tmp_path.iterdir())  # the temporary exists now
    return process


def test_hang_up_removes_the_temporary_files_of_a_pattern(tmp_path: Path) -> None:
    process = start_writing(tmp_path, ["pattern", "--seconds", "900", "--out", str(tmp_path / "big.npz")])
    process.send_signal(signal.SIGHUP)
    _, err = process.communicate(timeout=60)
    assert process.returncode == 129
    assert "stopped by" in err and "Traceback" not in err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT])
def test_a_stopped_scan_keeps_what_it_scanned(tmp_path: Path, signum: int) -> None:
    """A signal stops the scan after the frame in hand; the LAS and the bag are finished with the frames scanned
    until then (third-party readers read them), the temporaries go, and the exit status says it was stopped."""
    out, bag = tmp_path / "big.las", tmp_path / "big_bag"
    process = start_writing(tmp_path, ["scan", "--seconds", "300", "--scene", "open_field", "--out", str(out),
                                       "--rosbag", str(bag)])
    # Signalled once the LAS's points pass two frames' (a loaded machine may take seconds for the first frames).
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and sum(p.stat().st_size for p in tmp_path.glob(".big.las*/body")) < 2 << 20:
        time.sleep(0.05)
    process.send_signal(signum)
    _, err = process.communicate(timeout=120)
    assert process.returncode == 128 + signum, err
    assert "Traceback" not in err and "stopped by" in err and "kept" in err
    assert "stopping after the frame in hand" in err  # said when the signal came, before the files were finished
    assert sorted(p.name for p in tmp_path.iterdir()) == ["big.las", "big_bag"]
    frames = np.unique(np.asarray(laspy.read(out).frame))
    assert frames.size >= 2 and np.array_equal(frames, np.arange(frames.size))  # whole frames from the first
    from mcap.reader import make_reader

    with open(next(bag.glob("*.mcap")), "rb") as handle:
        stamps: dict[str, list[int]] = {}
        for _, channel, message in make_reader(handle).iter_messages():
            stamps.setdefault(channel.topic, []).append(message.log_time)
    clouds = len(stamps["/livox/lidar"])
    assert clouds >= frames.size
    # The IMU and the ground truth end with the frames kept (at the last one's end), not at the 300 s asked.
    start = min(stamps["/livox/lidar"])
    frame_ns = 100_000_000  # the Mid-70's 10 Hz
    for topic in ("/livox/imu", "/odom", "/tf"):
        assert max(stamps[topic]) - start == pytest.approx(clouds * frame_ns, abs=5_000_000), topic


SWALLOWED_SIGNAL_SCRIPT = """
import os, signal, sys
import livox_viz.cli.scan_commands as commands
from livox_viz.cli import main
real = commands.scene_from_args
def swallowing(args, *rest):
    try:  # as trimesh imports its optional dependencies: under except BaseException
        os.kill(os.getpid(), signal.SIGTERM)
    except BaseException:
        pass
    return real(args, *rest)
commands.scene_from_args = swallowing
sys.exit(main(sys.argv[1:]))
"""


def test_a_signal_a_library_swallows_during_start_up_still_stops_the_scan(tmp_path: Path) -> None:
    """SIGTERM raised while a library imports under ``except BaseException`` (trimesh does): the scan still stops
    after its first frame, keeps it, and exits 143, instead of running its whole length with status 0."""
    out = tmp_path / "cloud.ply"
    result = subprocess.run([sys.executable, "-c", SWALLOWED_SIGNAL_SCRIPT, "scan", "--seconds", "30", "--out",
                             str(out)], capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert result.returncode == 143, result.stderr
    assert "stopped by SIGTERM after 0.1 of 30 s" in result.stderr and "Traceback" not in result.stderr
    assert len(trimesh.load(out).vertices) > 1000


def test_a_swallowed_signal_ends_a_command_that_finished_with_its_status(tmp_path: Path) -> None:
    """A command without a stop of its own (``info``) that ran to its end after a swallowed SIGHUP says so and
    returns 129, as the shell expects of a process told to stop."""
    script = SWALLOWED_SIGNAL_SCRIPT.replace("scan_commands", "pattern_commands").replace(
        "scene_from_args", "config_from_args").replace("SIGTERM", "SIGHUP")
    result = subprocess.run([sys.executable, "-c", script, "info"], capture_output=True, text=True, timeout=120,
                            cwd=tmp_path)
    assert result.returncode == 129, result.stderr
    assert "SIGHUP arrived while starting" in result.stderr and "Traceback" not in result.stderr
    assert "point rate         100,000 pts/s" in result.stdout  # info printed its figures


def test_a_dead_runs_leftovers_are_removed_by_the_next_run(tmp_path: Path) -> None:
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    leftover_file = tmp_path / f".cloud.ply.livox-viz-{dead.pid}.abc123.part"
    leftover_dir = tmp_path / f".cloud.npz.livox-viz-{dead.pid}.xyz789.work"
    leftover_file.write_bytes(b"x" * 1000)
    leftover_dir.mkdir()
    (leftover_dir / "points.las").write_bytes(b"y")
    alive = tmp_path / f".other.ply.livox-viz-{os.getpid()}.keep00.part"
    alive.write_bytes(b"ours")
    users = tmp_path / ".cloud.ply.my-own-hidden-file"
    users.write_bytes(b"not ours")
    write_text_atomic(tmp_path / "note.txt", "hello")
    assert not leftover_file.exists() and not leftover_dir.exists()
    assert alive.exists() and users.exists() and (tmp_path / "note.txt").read_text() == "hello"
    assert remove_dead_leftovers(tmp_path) == []


def test_writing_over_a_symlink_writes_the_target_and_keeps_its_mode(tmp_path: Path) -> None:
    target = tmp_path / "real.json"
    target.write_text("{}")
    target.chmod(0o640)
    link = tmp_path / "link.json"
    link.symlink_to(target)
    write_text_atomic(link, '{"new": 1}')
    assert link.is_symlink() and json.loads(target.read_text()) == {"new": 1}
    assert stat.S_IMODE(target.stat().st_mode) == 0o640


def test_the_default_command_takes_the_guis_options(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    assert main(["--preset", "livox_mid40", "--seconds", "0.05", "--size", "320x200"]) == 0
    out = capsys.readouterr().out
    assert "no display" in out
    assert (tmp_path / "offscreen" / "both.png").exists()


def test_one_listener_hears_two_publishers_in_a_row_and_a_forged_datagram(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    port = free_udp_port()
    received = tmp_path / "received.npz"
    listener = start_listening(["--host", "127.0.0.1", "--port", str(port), "--frames", "11", "--timeout", "20",
                                "--record", str(received)])
    assert main(["publish", "--to", f"127.0.0.1:{port}", "--seconds", "0.5", "--speed", "5"]) == 0
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as forger:
        for stamp in (1e300, 1e9):  # an absurd time (dropped and counted), then a Unix-like one (a frame)
            forger.sendto(struct.pack("<4i1d", 1234567890, 52, 0, 1, stamp) + struct.pack("<6fi", 0, 0, 0, 0, 0, 0, 0),
                          ("127.0.0.1", port))
    time.sleep(0.2)
    # The publisher restarts: its clock starts at 0 again, far behind the forged 1e9.
    assert main(["publish", "--to", f"127.0.0.1:{port}", "--seconds", "0.5", "--speed", "5"]) == 0
    listener.join(30)
    assert not listener.is_alive()
    out = capsys.readouterr()
    # Each publisher run and the forger send from their own port: three senders, each its own session.
    assert "received 11 frames" in out.out and "senders 3" in out.err and "3 sender sessions" in out.out
    assert "1 dropped (timestamp beyond 1e+10 s 1)" in out.out
    data = np.load(received)
    # The recording says how its int16 points were decoded (the wire carries no range), not that it is a scan.
    notes = json.loads(str(data["frame_of_reference"]))
    assert "listen" in notes["source"] and "decoded with the range 600 m of livox_mid70" in notes["source"]
    assert notes["points"].startswith("xyz_int16: the points as received")
    sent = tmp_path / "sent.npz"
    assert main(["scan", "--seconds", "0.5", "--out", str(sent)]) == 0
    one_run = np.load(sent)
    # Both runs in full, point for point, around the forged empty frame (index 5); each frame its own index.
    np.testing.assert_array_equal(data["xyz_int16"], np.concatenate([one_run["xyz_int16"]] * 2))
    np.testing.assert_array_equal(data["frame"], np.concatenate([one_run["frame"], one_run["frame"] + 6]))
    np.testing.assert_array_equal(data["sender_frame"], np.concatenate([one_run["frame"]] * 2))
    assert len(data["frame_pose"]) == 11


def test_listen_port_zero_says_which_port(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["listen", "--host", "127.0.0.1", "--port", "0", "--seconds", "0.3"]) == 0
    err = capsys.readouterr().err
    port = int(err.split("udp 127.0.0.1:")[1].split()[0])
    assert 0 < port <= 65535
    assert "decoding with the range 600 m of livox_mid70" in err  # the wire carries no range: it says which


def test_coverage_cells_up_to_the_fovs_half_angle_are_allowed(capsys: pytest.CaptureFixture[str]) -> None:
    """--cell-deg may reach the FOV's half-angle itself (livox_mid70: 70.432 / 2 deg), not a hair more."""
    assert main(["coverage", "--preset", "livox_mid70", "--seconds", "0.05", "--cell-deg", "35.216"]) == 0
    assert main(["coverage", "--preset", "livox_mid70", "--seconds", "0.05", "--cell-deg", "35.2161"]) == 2
    assert "allowed: up to 35.216" in capsys.readouterr().err


def test_a_dead_runs_leftover_link_is_removed_and_never_followed(tmp_path: Path) -> None:
    """A leftover name that is a symbolic link to a folder: the link goes, the folder it points at stays whole."""
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    users = tmp_path / "users_folder"
    users.mkdir()
    (users / "data.las").write_bytes(b"keep me")
    link = tmp_path / f".cloud.npz.livox-viz-{dead.pid}.xyz789.work"
    link.symlink_to(users, target_is_directory=True)
    assert remove_dead_leftovers(tmp_path) == [link]
    assert not link.is_symlink() and not link.exists()
    assert (users / "data.las").read_bytes() == b"keep me"


@pytest.mark.parametrize(("argv", "words"), [
    (["scan", "--seconds", "1e308", "--out", "x.ply"], "asks for more points than any run could make"),
    (["pattern", "--seconds", "1e308", "--out", "x.npz"], "asks for more points than any run could make"),
    (["coverage", "--seconds", "0.1,1e20"], "allowed: at most 200,000,000"),
    (["render", "--seconds", "1e308", "--out", "x.png"], "allowed: at most 100,000,000"),
    (["scan", "--seconds", "1e-300", "--out", "x.ply"], "holds no point"),
    (["publish", "--seconds", "1e-300", "--to", "127.0.0.1:9"], "holds no point"),
])
def test_absurd_scan_times_are_one_line_before_any_work(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                        capsys: pytest.CaptureFixture[str], argv: list[str],
                                                        words: str) -> None:
    """A time whose point count overflows int64 (it was a traceback, a negative count that passed the budget and
    printed 0.00 %, or a render drawing the rosette's random stream until memory ran out), or one that holds no
    point: refused in one line, nothing written."""
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert words in err and len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert "--force" not in err or argv[0] in ("scan", "pattern")  # only those commands have it
    assert list(tmp_path.iterdir()) == []


def test_points_before_saturates_instead_of_overflowing() -> None:
    from livox_viz.patterns.stream import MOST_POINTS, points_before

    assert points_before(1e308, 100_000.0) == MOST_POINTS and points_before(1e-300, 100_000.0) == 0
    assert points_before(2.0, 100_000.0) == 200_000
    counts = points_before(np.array([1e20, 1e308, 0.5]), 100_000.0)
    assert counts.tolist() == [MOST_POINTS, MOST_POINTS, 50_000]


def _urban_with(extra: dict) -> dict:
    scene = json.loads((Path(__file__).resolve().parents[1] / "presets" / "scenes" / "urban.json").read_text())
    scene["objects"].append(extra)
    return scene


@pytest.mark.parametrize(("scene", "words"), [
    (_urban_with({"type": "sphere", "center": [1e6, 0, 0], "radius": 1}), "the scene spans 1e+06 m; allowed: at most"),
    (_urban_with({"type": "box", "center": [1e8, 0, 0], "size": [1, 1, 1]}), "within 1e+07 m of the origin"),
    ({"objects": [{"type": "terrain", "center": [0, 0, 0], "size": [50, 50], "cells": 100000}]},
     "'cells' = 100000; allowed: a whole number from 1 to 1000"),
    ({"objects": [{"type": "terrain", "center": [0, 0, 0], "size": [50, 50], "cells": 2.5}]},
     "'cells' = 2.5; allowed: a whole number"),
    ({"objects": [{"type": "box", "center": [0, 0, 0], "size": [-1, 1, 1]}]}, "allowed: 3 numbers from 0.001"),
    ({"objects": [{"type": "ground", "center": [0, 0, 0], "size": [1e308, 1]}]}, "allowed: 2 numbers from 0.001"),
])
def test_scene_objects_out_of_bounds_are_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str], scene: dict,
                                                 words: str) -> None:
    """A scene Embree cannot cast right (geometry 1000 km out met wrong triangles near the sensor), a terrain of a
    hundred thousand cells a side (a 74 GiB allocation), a negative or astronomic size: refused in one line."""
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(scene))
    assert main(["scan", "--scene", str(path), "--seconds", "0.05", "--out", str(tmp_path / "o.npz")]) == 2
    err = capsys.readouterr().err
    assert words in err and len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scene.json"]


def test_a_mesh_vertex_beyond_float32_is_refused_as_a_span(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    mesh = tmp_path / "far.obj"
    mesh.write_text("v 0 0 0\nv 1 0 0\nv 0 1 1e39\nf 1 2 3\n")  # finite in float64, infinite in Embree's float32
    assert main(["scan", "--scene", str(mesh), "--seconds", "0.05", "--out", str(tmp_path / "o.npz")]) == 2
    assert "the scene spans 1e+39 m" in capsys.readouterr().err


def test_a_scene_90_km_across_still_casts_exactly_near_the_sensor(tmp_path: Path) -> None:
    """Within the allowed span a far object leaves the near cloud as it was (to the int16 step)."""
    near = tmp_path / "near.json"
    far = tmp_path / "far.json"
    near.write_text(json.dumps(_urban_with({"type": "sphere", "center": [-50, 0, -30], "radius": 1})))
    far.write_text(json.dumps(_urban_with({"type": "sphere", "center": [90_000, 0, 0], "radius": 1})))
    clouds = []
    for scene in (near, far):
        out = tmp_path / f"{scene.stem}.npz"
        assert main(["scan", "--scene", str(scene), "--seconds", "0.1", "--out", str(out)]) == 0
        clouds.append(np.load(out)["xyz_sensor"])
    from scipy.spatial import cKDTree

    # float32 around a middle 45 km away: a ray at an edge may flip (one in thousands), the rest land within a few
    # millimetres plus the int16 step of where they landed.
    gap, _ = cKDTree(clouds[0]).query(clouds[1])
    assert abs(len(clouds[1]) - len(clouds[0])) <= 5 and np.mean(gap > 600 / 32767 + 0.005) < 1e-3


def test_a_pipe_among_the_users_presets_blocks_no_command(user_presets: Path) -> None:
    """A FIFO named ``*.json`` in the user's preset folder (which every command lists) is passed over: reading it
    blocked ``presets``, ``info`` and every other command until a writer came."""
    os.mkfifo(user_presets / "stray.json")
    (user_presets / "mine.json").write_text(json.dumps(SEED_JSON))
    result = subprocess.run([sys.executable, "-m", "livox_viz", "presets"], capture_output=True, text=True,
                            timeout=60, env={**os.environ, "LIVOX_VIZ_PRESETS": str(user_presets)})
    assert result.returncode == 0, result.stderr
    assert "mine" in result.stdout and "stray" not in result.stdout


def test_a_reader_that_goes_away_ends_the_output_quietly() -> None:
    """``livox-viz info | head -1``: the pipe's reader leaves; the command stops without an error line (it said
    "error: Broken pipe") and with the status of a writer killed by SIGPIPE."""
    process = subprocess.Popen([sys.executable, "-m", "livox_viz", "info"], stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE)
    process.stdout.close()  # the reader is gone before the first line
    with process.stderr:
        err = process.stderr.read().decode()
    assert process.wait(timeout=60) == 128 + signal.SIGPIPE, err
    assert err == ""


@pytest.mark.parametrize(("text", "words"), [
    ('{"asset": {"version": "2.0"}, "meshes": [', "malformed JSON at line 1 column 42"),
    ("garbage\x00", "malformed JSON at line 1 column 1"),
    ("[" * 100_000, "nested"),
])
def test_a_broken_gltf_is_named_with_what_is_wrong(tmp_path: Path, capsys: pytest.CaptureFixture[str], text: str,
                                                   words: str) -> None:
    """A truncated, garbage or deeply nested .gltf (JSON) gets the JSON reader's line; trimesh's said
    "FileNotFoundError: model.gltf" of the file that was there."""
    mesh = tmp_path / "model.gltf"
    mesh.write_text(text)
    assert main(["scan", "--scene", str(mesh), "--seconds", "0.05", "--out", str(tmp_path / "o.npz")]) == 2
    err = capsys.readouterr().err
    assert f"{mesh}: not a readable glTF file (JSON)" in err and words in err and "FileNotFound" not in err


def test_objects_smaller_than_a_metre_are_scenes_too(tmp_path: Path) -> None:
    """A sphere of 0.3 m radius, a post 0.5 m high and 0.1 m thick, a 0.2 m box: sizes under a metre are sizes (the
    checks refuse 0 and negatives only), and the scan meets them where they stand."""
    scene = tmp_path / "small.json"
    scene.write_text(json.dumps({"objects": [
        {"type": "sphere", "center": [5, 0, 0], "radius": 0.3},
        {"type": "cylinder", "center": [5, 1, 0], "radius": 0.1, "height": 0.5},
        {"type": "box", "center": [5, -1, 0], "size": [0.2, 0.2, 0.2]},
    ], "vehicle_pose": [0, 0, 0, 0, 0, 0]}))
    out = tmp_path / "o.npz"
    assert main(["scan", "--scene", str(scene), "--seconds", "0.2", "--out", str(out)]) == 0
    hits = np.load(out)["xyz_world"]
    for centre, reach in (((5, 0, 0), 0.31), ((5, 1, 0), 0.26), ((5, -1, 0), 0.18)):
        near = np.linalg.norm(hits - np.array(centre), axis=1) <= reach
        assert near.sum() > 10, centre
