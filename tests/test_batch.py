"""``livox-viz batch``: a grid of scans as jobs, locally and on Dask, each output the scan run alone; resumable;
a broken job fails alone; a bad spec is one line before any job starts."""

from __future__ import annotations

import contextlib
import csv
import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from livox_viz.cli import batch_commands, main
from livox_viz.cli.batch_spec import EXAMPLE, MAX_JOBS, read_spec, scan_argv

SPEC = """seconds = 0.1
[grid]
sensors = ["livox_mid70"]
scenes = ["urban"]
trajectories = ["none", "line", "circle"]
seeds = [3]
returns = ["ideal"]
outputs = ["npz", "las+rosbag"]
"""


def _manifest(folder: Path) -> list[dict[str, str]]:
    with open(folder / "manifest.csv", newline="") as handle:
        return list(csv.DictReader(handle))


def _files(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file() and p.name != "job.json"}


@pytest.fixture(scope="module")
def local_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """The six-job spec run on the local pool of two processes."""
    folder = tmp_path_factory.mktemp("batch")
    spec = folder / "spec.toml"
    spec.write_text(SPEC)
    assert main(["batch", str(spec), "--out", str(folder / "local"), "--jobs", "2"]) == 0
    return spec, folder / "local"


def test_every_job_of_a_local_batch_writes_what_the_scan_alone_writes(local_run: tuple[Path, Path],
                                                                      tmp_path: Path) -> None:
    spec, out = local_run
    jobs = read_spec(spec)
    rows = _manifest(out)
    assert len(jobs) == len(rows) == 6 and {row["status"] for row in rows} == {"done"}
    for job, row in zip(jobs, rows, strict=True):
        alone = tmp_path / job.name
        alone.mkdir()
        assert main(scan_argv(job, alone, None)) == 0
        assert _files(out / "jobs" / job.name) == _files(alone), job.name
        record = json.loads((out / "jobs" / job.name / "job.json").read_text())
        assert row["job"] == record["job"] == job.name and int(row["points"]) == record["points"] > 5_000
        assert record["frames"] == 1 and record["seed"] == 3 and float(row["duration_s"]) > 0
        assert set(record["files"]) == {"cloud.npz"} or {"cloud.las", "bag/metadata.yaml"} <= set(record["files"])
        for name, about in record["files"].items():
            import hashlib

            assert hashlib.sha256((out / "jobs" / job.name / name).read_bytes()).hexdigest() == about["sha256"]
            assert f"{name}:{about['sha256']}" in row["files"]


def test_the_same_batch_on_a_dask_local_cluster_writes_the_same_files(local_run: tuple[Path, Path],
                                                                      tmp_path: Path) -> None:
    """Handed to the cluster two at a time (--jobs 2)."""
    pytest.importorskip("distributed")
    spec, out = local_run
    from distributed import Client

    environment = dict(os.environ)
    handed: list = []
    most = [0]
    submit = Client.submit

    def counted(client: Client, *args, **kwargs):
        future = submit(client, *args, **kwargs)
        handed.append(future)
        most[0] = max(most[0], sum(not f.done() for f in handed))
        return future

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(Client, "submit", counted)
        assert main(["batch", str(spec), "--out", str(tmp_path / "dask"), "--dask", "local:2", "--jobs", "2"]) == 0
    assert len(handed) == 6 and most[0] == 2  # --jobs: at most two jobs on the cluster at once
    # Dask's nannies put their workers' variables into the spawning process's environment: not into ours.
    assert dict(os.environ) == environment
    local, dask = _manifest(out), _manifest(tmp_path / "dask")
    assert [(r["job"], r["status"], r["points"], r["files"]) for r in dask] == [
        (r["job"], r["status"], r["points"], r["files"]) for r in local]
    for row in local:
        assert _files(tmp_path / "dask" / "jobs" / row["job"]) == _files(out / "jobs" / row["job"])


def test_a_rerun_runs_nothing_finished_again(local_run: tuple[Path, Path], capsys: pytest.CaptureFixture[str]) -> None:
    spec, out = local_run
    before = {p: p.stat().st_mtime_ns for p in (out / "jobs").rglob("*")}
    assert main(["batch", str(spec), "--out", str(out)]) == 0
    assert "6 already finished; 0 to run" in capsys.readouterr().err
    assert {p: p.stat().st_mtime_ns for p in (out / "jobs").rglob("*")} == before


def test_a_batch_killed_half_way_is_finished_by_running_it_again(tmp_path: Path,
                                                                 capsys: pytest.CaptureFixture[str]) -> None:
    """Killed (the batch and its workers, SIGKILL) once two jobs are done: the rerun runs the four others only, and
    leaves the two as they were. Meanwhile another batch in that folder is refused, naming the running one; the
    killed one's manifest holds whole rows of finished jobs, and its lock does not block the rerun."""
    spec = tmp_path / "spec.toml"
    spec.write_text(SPEC)
    out = tmp_path / "out"
    argv = [sys.executable, "-m", "livox_viz", "batch", str(spec), "--out", str(out), "--jobs", "1"]
    process = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, start_new_session=True)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and len(list(out.glob("jobs/*/job.json"))) < 2:
        time.sleep(0.05)
    try:
        assert main(["batch", str(spec), "--out", str(out)]) == 2
    finally:
        os.killpg(process.pid, signal.SIGKILL)
        process.communicate()
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"--out {out}: another batch is running there (process {process.pid}, " in err
    finished = {p.parent.name: p.stat().st_mtime_ns for p in out.glob("jobs/*/job.json")}
    assert 2 <= len(finished) < 6
    assert {row["status"] for row in _manifest(out)} <= {"done"} and {row["job"] for row in _manifest(out)} <= set(
        finished)
    rerun = subprocess.run(argv, capture_output=True, text=True, timeout=300)
    assert rerun.returncode == 0, rerun.stderr
    assert f"{len(finished)} already finished; {6 - len(finished)} to run" in rerun.stderr
    assert {p.parent.name: p.stat().st_mtime_ns for p in out.glob("jobs/*/job.json")
            if p.parent.name in finished} == finished
    rows = _manifest(out)
    assert len(rows) == 6 and {row["status"] for row in rows} == {"done"}
    assert not [p for p in out.rglob("*") if ".livox-viz-" in p.name]  # the killed job's temporaries are gone


def test_ctrl_c_leaves_no_temporary_of_the_job_in_flight(tmp_path: Path) -> None:
    """Ctrl-C while a worker writes a job's cloud: the batch kills its pool, and then removes that job's work folder
    (its raw columns can be gigabytes) at once, not only when the batch is run again."""
    spec = tmp_path / "spec.toml"
    spec.write_text(SPEC.replace("seconds = 0.1", "seconds = 30.0"))
    out = tmp_path / "out"
    argv = [sys.executable, "-m", "livox_viz", "batch", str(spec), "--out", str(out), "--jobs", "1"]
    process = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 300
        while time.monotonic() < deadline and not [p for p in out.glob("jobs/*/*") if ".livox-viz-" in p.name]:
            time.sleep(0.02)
        assert [p for p in out.glob("jobs/*/*") if ".livox-viz-" in p.name], "no job was writing"
        process.send_signal(signal.SIGINT)
        _, err = process.communicate(timeout=120)
    finally:
        process.kill()
        process.wait()
        process.stdout.close()  # not left to the collector when the test failed before communicate()
        process.stderr.close()
    assert process.returncode == 130, err
    assert "Traceback" not in err and "batch stopped by Ctrl-C" in err.splitlines()[-1], err
    assert not [p for p in out.rglob("*") if ".livox-viz-" in p.name]


def _two_jobs_run(tmp_path: Path) -> tuple[Path, Path]:
    """A spec of two one-file jobs (seeds 3 and 4), run whole on one process: the spec and its out folder."""
    spec = tmp_path / "spec.toml"
    spec.write_text(SPEC.replace('"none", "line", "circle"', '"none"').replace('"npz", "las+rosbag"', '"npz"')
                    .replace("seeds = [3]", "seeds = [3, 4]"))
    out = tmp_path / "out"
    assert main(["batch", str(spec), "--out", str(out), "--jobs", "1"]) == 0
    return spec, out


def test_a_finished_job_without_its_row_counts_in_the_progress_lines(tmp_path: Path,
                                                                     capsys: pytest.CaptureFixture[str]) -> None:
    """A batch killed after a job's files were written but before its row: the next run writes the row, and its
    points are in the progress lines as in the summary (the lines said fewer)."""
    spec, out = _two_jobs_run(tmp_path)
    first, second = _manifest(out)
    with open(out / "manifest.csv", newline="") as handle:
        header = handle.readline()
    (out / "manifest.csv").write_text(header)  # neither row written
    for path in sorted((out / "jobs" / second["job"]).rglob("*"), reverse=True):  # the second job runs again
        path.unlink() if path.is_file() else path.rmdir()
    capsys.readouterr()
    assert main(["batch", str(spec), "--out", str(out), "--jobs", "1"]) == 0
    summary, err = capsys.readouterr()
    total = int(first["points"]) + int(second["points"])
    assert f"[2/2] done {second['job']} ({int(second['points']):,} points" in err, err
    assert f"0 failed, {total:,} points, about" in err.splitlines()[-1], err
    assert f"2 of 2 jobs done, 0 failed, {total:,} points" in summary


def test_a_job_with_a_broken_scene_fails_alone_with_its_message(tmp_path: Path,
                                                                capsys: pytest.CaptureFixture[str]) -> None:
    broken = tmp_path / "broken.obj"
    broken.write_text("v 0 0 0\nv 1 0 0\nf 1 2 3\n")
    spec = tmp_path / "spec.toml"
    spec.write_text(SPEC.replace('scenes = ["urban"]', 'scenes = ["urban", "broken.obj"]').replace(
        '"none", "line", "circle"', '"none"').replace('"npz", "las+rosbag"', '"npz"'))
    out = tmp_path / "out"
    assert main(["batch", str(spec), "--out", str(out), "--jobs", "1"]) == 1
    err = capsys.readouterr().err
    rows = {row["scene"]: row for row in _manifest(out)}
    assert rows["urban"]["status"] == "done" and rows["urban"]["error"] == ""
    assert rows[str(broken)]["status"] == "failed" and "broken.obj" in rows[str(broken)]["error"]
    assert rows[str(broken)]["error"] in err and "1 failed" in err
    # Not run again unless asked; --retry runs it again (the finished one stays as it was).
    records = {p.parent.name: p.stat().st_mtime_ns for p in out.glob("jobs/*/job.json")}
    assert main(["batch", str(spec), "--out", str(out)]) == 1
    assert "1 failed: --retry runs it again" in capsys.readouterr().err
    assert {p.parent.name: p.stat().st_mtime_ns for p in out.glob("jobs/*/job.json")} == records
    assert main(["batch", str(spec), "--out", str(out), "--retry"]) == 1
    assert "1 failed one again; 1 to run" in capsys.readouterr().err
    again = {p.parent.name: p.stat().st_mtime_ns for p in out.glob("jobs/*/job.json")}
    assert [name for name in records if again[name] != records[name]] == [rows[str(broken)]["job"]]


@pytest.mark.parametrize(("change", "message"), [
    (("[grid]", "seed = 4\n[grid]"), "unknown key 'seed'; allowed: grid, seconds"),
    (("seeds = [3]", "seeds = [3]\nsensor = ['x']"), "unknown key 'grid.sensor'; allowed: sensors, scenes"),
    (("seeds = [3]", f"seeds = {list(range(2000))}"), "the grid makes 12,000 jobs; allowed: at most 10,000"),
    (('scenes = ["urban"]', 'scenes = ["nowhere.obj"]'), "grid.scenes: 'nowhere.obj' is neither a built-in scene"),
    (('sensors = ["livox_mid70"]', 'sensors = ["livox_mid99"]'), "grid.sensors: unknown preset 'livox_mid99'"),
    (('sensors = ["livox_mid70"]', 'sensors = ["/dev/zero"]'),
     "grid.sensors: '/dev/zero' is not a regular file (a device, FIFO or socket); allowed: a preset name"),
    (('scenes = ["urban"]', 'scenes = ["/"]'), "nor an existing file (a folder); allowed"),
    (('"none", "line", "circle"', '"/dev/zero"'), "grid.trajectories: '/dev/zero' is not a regular file"),
    (('outputs = ["npz", "las+rosbag"]', 'outputs = ["npz+las"]'), "grid.outputs holds 'npz+las'; allowed"),
    (("seconds = 0.1", "seconds = 1e9"), "asks 100,000,000,000,000 points"),
    (("seconds = 0.1", "seconds = 1e-300"), "seconds = 1e-300 holds no point of livox_mid70's scan; allowed: at least"),
    (("seeds = [3]", "seeds = [-1]"), "grid.seeds holds -1; allowed: whole numbers"),
    (("seconds = 0.1", "seconds = 0.1\n[grid"), "not a readable TOML spec"),
    (("seconds = 0.1", "seconds = 0.1\nimu_rate = 5"), "imu_rate = 5; allowed: IMU samples per second, 200 to 10000"),
    (("seconds = 0.1", "seconds = 0.1\nimu_rate = 1e9"), "imu_rate = 1000000000.0; allowed: IMU samples per second"),
])
def test_a_bad_spec_is_one_line_before_any_job(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                               change: tuple[str, str], message: str) -> None:
    spec = tmp_path / "spec.toml"
    spec.write_text(SPEC.replace(*change))
    assert main(["batch", str(spec), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err and err.startswith("livox-viz: error: "), err
    assert "spec.toml: " in err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(("make", "message"), [
    (lambda out: out.chmod(0o555), "is not a writable folder; allowed: a folder this user can write"),
    (lambda out: (out / "jobs").write_text("mine"), "jobs is not a folder; allowed: a folder whose jobs/"),
    (lambda out: (out / "manifest.csv").mkdir(), "the manifest cannot be written there"),
    (lambda out: ((out / "manifest.csv").write_text("mine"), (out / "manifest.csv").chmod(0o444)),
     "the manifest cannot be written there"),
])
def test_an_out_folder_the_batch_cannot_write_is_one_line_before_any_job(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], make, message: str) -> None:
    """Even to root, who may write in a folder with no write bit but whose manifest is then refused."""
    spec = tmp_path / "spec.toml"
    spec.write_text(SPEC)
    out = tmp_path / "out"
    out.mkdir()
    make(out)
    try:
        assert main(["batch", str(spec), "--out", str(out)]) == 2
    finally:
        out.chmod(0o755)
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err and err.startswith(f"livox-viz: error: --out {out}: "), err
    assert not (out / "jobs").is_dir() or not any((out / "jobs").iterdir())


def test_a_folder_of_another_batch_is_refused_and_its_manifest_kept(tmp_path: Path,
                                                                  capsys: pytest.CaptureFixture[str]) -> None:
    spec = tmp_path / "spec.toml"
    spec.write_text(SPEC)
    out = tmp_path / "out"
    out.mkdir()
    theirs = "job,status\nsomeone-else-s0-1234567890,done\n"
    (out / "manifest.csv").write_text(theirs)
    assert main(["batch", str(spec), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    assert "holds another batch's manifest (1 of its jobs, e.g. someone-else-s0-1234567890, are not jobs of " \
           "spec.toml); allowed: this spec's own folder" in err, err
    assert (out / "manifest.csv").read_text() == theirs and not (out / "jobs").exists()
    (out / "manifest.csv").write_text("x;y\n")  # a user's own file of that name, not a manifest
    assert main(["batch", str(spec), "--out", str(out)]) == 2
    assert "holds a manifest.csv that is not a batch's manifest" in capsys.readouterr().err
    assert (out / "manifest.csv").read_text() == "x;y\n" and not (out / "jobs").exists()


def test_a_grown_spec_keeps_its_folder_a_shrunk_one_does_not(local_run: tuple[Path, Path], tmp_path: Path) -> None:
    """A folder's manifest whose jobs are all still the spec's (a seed added) is the spec's own: it finishes there."""
    spec, folder = local_run
    grown = tmp_path / "grown.toml"
    grown.write_text(spec.read_text().replace("seeds = [3]", "seeds = [3, 4]"))
    batch_commands._check_same_batch(folder, read_spec(grown), "grown.toml")
    shrunk = tmp_path / "shrunk.toml"
    shrunk.write_text(spec.read_text().replace('trajectories = ["none", "line", "circle"]', 'trajectories = ["line"]'))
    with pytest.raises(batch_commands.UsageError, match=r"\(4 of its jobs, e\.g\. livox_mid70-urban-none-"):
        batch_commands._check_same_batch(folder, read_spec(shrunk), "shrunk.toml")


def test_an_unreachable_scheduler_is_one_line_before_any_job(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("distributed")
    import socket

    monkeypatch.setattr(batch_commands, "CONNECT_SECONDS", 1.0)
    with socket.socket() as probe:  # a port nothing listens on
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    spec = tmp_path / "spec.toml"
    spec.write_text(SPEC)
    assert main(["batch", str(spec), "--out", str(tmp_path / "out"), "--dask", f"tcp://127.0.0.1:{port}"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"--dask tcp://127.0.0.1:{port}: cannot reach the scheduler" in err
    assert "allowed: a running Dask scheduler's address" in err
    assert not (tmp_path / "out").exists()
    assert main(["batch", str(spec), "--out", str(tmp_path / "out"), "--dask", "local:zero"]) == 2
    assert "allowed: local:N with N from 1 to 1024" in capsys.readouterr().err


@pytest.mark.parametrize(("answer", "message"), [
    (b"HTTP/1.0 400 Bad Request\r\n\r\n" * 4, "no Dask scheduler this can use there (MemoryError: "),
    (None, "no Dask scheduler answered within 1 s (something accepts connections there but does not answer as one)"),
])
def test_an_address_that_is_not_a_scheduler_is_one_line_before_any_job(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], answer: bytes | None,
        message: str) -> None:
    """A web server's port (what it answers read as a Dask message's length), or a peer that never answers: Dask's
    own timeout covers the connection only, and its handshake waited for ever."""
    pytest.importorskip("distributed")
    import socket
    import threading

    monkeypatch.setattr(batch_commands, "CONNECT_SECONDS", 1.0)
    listener = socket.create_server(("127.0.0.1", 0))
    port = listener.getsockname()[1]
    held: list[socket.socket] = []

    def serve() -> None:
        listener.settimeout(30.0)  # then the peers go (before this fix, Client() waited until then)
        try:
            while True:
                peer, _ = listener.accept()
                held.append(peer)
                if answer is not None:
                    peer.sendall(answer)
        except OSError:
            pass
        for peer in held:
            peer.close()

    server = threading.Thread(target=serve, daemon=True)
    server.start()
    spec = tmp_path / "spec.toml"
    spec.write_text(SPEC)
    try:
        assert main(["batch", str(spec), "--out", str(tmp_path / "out"), "--dask", f"tcp://127.0.0.1:{port}"]) == 2
    finally:
        listener.close()
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"--dask tcp://127.0.0.1:{port}: {message}" in err, err
    assert "allowed: a running Dask scheduler's address" in err
    assert not (tmp_path / "out").exists()


def test_dask_local_workers_leave_ctrl_c_to_the_batch() -> None:
    """A terminal's Ctrl-C reaches every process of its group: a LocalCluster's workers printed their
    KeyboardInterrupt tracebacks while the batch was stopping them itself."""
    import socket
    import warnings

    pytest.importorskip("distributed")
    before = signal.getsignal(signal.SIGINT)
    # A user's own Dask holds the dashboard's port: the cluster warned "Port 8787 is already in use" (a full suite
    # failed on it while another Dask ran on the machine).
    dashboard = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    try:
        dashboard.bind(("0.0.0.0", 8787))
        dashboard.listen()
    except OSError:
        pass  # held already
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            runner = batch_commands.DaskRunner("local:1")
        try:
            ignored = runner.client.run(lambda: signal.getsignal(signal.SIGINT) == signal.SIG_IGN)
        finally:
            runner.close()
    finally:
        dashboard.close()
    assert list(ignored.values()) == [True]
    assert signal.getsignal(signal.SIGINT) is before  # this process takes Ctrl-C as before


def test_dask_local_workers_stopped_with_a_job_in_hand_say_nothing(capfd: pytest.CaptureFixture[str]) -> None:
    """Ctrl-C stops a LocalCluster whose worker runs a job: its worker and nanny printed Dask's warnings ("Async
    instruction ... ended with CancelledError", "Worker process still alive after 4.0 seconds, killing") under
    the batch's one line."""
    pytest.importorskip("distributed")
    runner = batch_commands.DaskRunner("local:1")
    try:
        future = runner.client.submit(time.sleep, 60, pure=False)
        runner._futures[future] = None
        for _ in range(1200):  # until the worker has started it
            if any(runner.client.processing().values()) and runner.client.run(
                    lambda dask_worker: len(dask_worker.state.executing)).popitem()[1]:
                break
            time.sleep(0.05)
        else:
            pytest.fail("the worker never started the task")
    finally:
        runner.stop()
    err = capfd.readouterr().err
    assert "WARNING" not in err and "CancelledError" not in err and "Traceback" not in err, err


@pytest.mark.parametrize("encoding", ["utf-8-sig", "utf-16"])
def test_the_example_saved_by_windows_tools_reads_as_it_is(tmp_path: Path, encoding: str) -> None:
    """Notepad's byte-order mark, and Windows PowerShell 5.1's ``batch --example > spec.toml`` (UTF-16)."""
    spec = tmp_path / "spec.toml"
    spec.write_bytes(EXAMPLE.encode(encoding))
    plain = tmp_path / "plain.toml"
    plain.write_text(EXAMPLE, encoding="utf-8")
    assert [job.name for job in read_spec(spec)] == [job.name for job in read_spec(plain)]


def test_a_folder_given_as_the_spec_is_named_a_folder(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["batch", str(tmp_path), "--out", str(tmp_path / "out")]) == 2
    assert f"{tmp_path}: is a folder; allowed: a TOML or JSON batch spec file" in capsys.readouterr().err


def test_the_example_spec_is_a_valid_spec(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["batch", "--example"]) == 0
    spec = tmp_path / "spec.toml"
    spec.write_text(capsys.readouterr().out)
    assert spec.read_text() == EXAMPLE
    jobs = read_spec(spec)
    assert len(jobs) == 8 and len({job.name for job in jobs}) == 8 and len(jobs) <= MAX_JOBS
    assert {job.outputs for job in jobs} == {("npz",)} and {job.seed for job in jobs} == {0, 1}


class _Pretend:
    """A runner that pretends: each job it takes ends at once, done, with a record (``job.json``) and no files;
    after ``LIMIT`` jobs it stops the batch as Ctrl-C does. Counts the jobs it took."""

    LIMIT = 3
    taken = 0

    def __init__(self, processes: int) -> None:
        self.where = f"pretend ({processes})"

    def run(self, jobs, root: Path, workers: int | None):
        for job in jobs:
            _Pretend.taken += 1
            record = {"job": job.name, **job.parameters(), "status": "done", "frames": 1, "points": 10,
                      "duration_s": 0.0, "files": {}, "error": ""}
            folder = root / "jobs" / job.name
            folder.mkdir(parents=True)
            (folder / "job.json").write_text(json.dumps(record))
            yield record
            if _Pretend.taken % self.LIMIT == 0:
                signal.raise_signal(signal.SIGINT)
                yield None

    def stop(self) -> None:
        pass


def _huge_spec(tmp_path: Path, seeds: int = 100_000) -> Path:
    """A spec of ``2 x seeds`` jobs."""
    spec = tmp_path / "huge.toml"
    spec.write_text(SPEC.replace("seeds = [3]", f"seeds = {list(range(seeds))}").replace(
        '"none", "line", "circle"', '"none"'))
    return spec


@pytest.fixture
def named(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """How many times a job was named (its name is its hash: the cost of a job that is only listed)."""
    from livox_viz.cli import batch_spec

    count = [0]
    name = batch_spec.Job.name

    def counted(job: batch_spec.Job) -> str:
        count[0] += 1
        return name.fget(job)

    monkeypatch.setattr(batch_spec.Job, "name", property(counted))
    return count


def test_a_huge_grid_names_its_jobs_only_as_they_are_run(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                         named: list[int], capsys: pytest.CaptureFixture[str]) -> None:
    """200,000 jobs with --force, stopped after three: only those (and the few taken ahead) are named, the
    progress counts of the grid's total, the manifest holds their three rows; a rerun skips them by reading their
    records and the manifest's index, naming no more jobs than it takes."""
    monkeypatch.setattr(batch_commands, "LocalRunner", _Pretend)
    monkeypatch.setattr(_Pretend, "taken", 0)
    spec = _huge_spec(tmp_path)
    out = tmp_path / "out"
    assert main(["batch", str(spec), "--out", str(out), "--force", "--jobs", "1"]) == 128 + signal.SIGINT
    err = capsys.readouterr().err
    assert named[0] <= 10, named
    assert "batch: 200,000 jobs from huge.toml: 0 already finished; 200,000 to run" in err
    assert "[3/200,000] done livox_mid70-urban-none-s1-ideal-npz-" in err
    assert "batch stopped by Ctrl-C: 3 of 200,000 jobs done, 0 failed, 30 points" in err
    rows = _manifest(out)
    assert [row["job"] for row in rows] == [job.name for job in read_spec(spec, force=True)[:3]]
    named[0] = 0
    assert main(["batch", str(spec), "--out", str(out), "--force", "--jobs", "1"]) == 128 + signal.SIGINT
    err = capsys.readouterr().err
    assert "3 already finished; 199,997 to run" in err and "[6/200,000] done" in err
    assert named[0] <= 15, named
    assert [row["job"] for row in _manifest(out)] == [job.name for job in read_spec(spec, force=True)[:6]]


def test_a_manifest_cut_in_a_row_loses_that_row_only(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    """A batch killed while it appended a row leaves a part of a line: the rerun drops it, keeps every row before
    it, and the job whose row it was gets its whole row from its record."""
    monkeypatch.setattr(batch_commands, "LocalRunner", _Pretend)
    monkeypatch.setattr(_Pretend, "taken", 0)
    spec = _huge_spec(tmp_path, seeds=20_000)
    out = tmp_path / "out"
    main(["batch", str(spec), "--out", str(out), "--force"])
    manifest = (out / "manifest.csv").read_bytes()
    lines = manifest.splitlines(keepends=True)
    assert len(lines) == 4 and all(line.endswith(b"\n") for line in lines)
    (out / "manifest.csv").write_bytes(b"".join(lines[:3]) + lines[3][:25])  # the third row cut
    capsys.readouterr()
    main(["batch", str(spec), "--out", str(out), "--force"])
    err = capsys.readouterr().err
    assert "2 already finished; 39,998 to run" in err and "[4/40,000] done" in err
    assert "batch stopped by Ctrl-C: 6 of 40,000 jobs done" in err, err
    assert (out / "manifest.csv").read_bytes().startswith(b"".join(lines[:3]))
    rows = _manifest(out)
    assert sorted(row["job"] for row in rows) == sorted(job.name for job in read_spec(spec, force=True)[:6])
    assert all(row["status"] == "done" and row["points"] == "10" for row in rows)


def test_counts_of_one_are_singular(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                    capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setattr(batch_commands, "LocalRunner", _Pretend)
    monkeypatch.setattr(_Pretend, "taken", 1)  # the one job runs to its end
    spec = tmp_path / "spec.toml"
    spec.write_text(SPEC.replace('"none", "line", "circle"', '"none"').replace('"npz", "las+rosbag"', '"npz"'))
    assert main(["batch", str(spec), "--out", str(tmp_path / "out")]) == 0
    captured = capsys.readouterr()
    assert "batch: 1 job from spec.toml: 0 already finished; 1 to run" in captured.err
    assert "(10 points, 0.0 s); 0 failed, 10 points" in captured.err
    assert "batch: 1 of 1 job done, 0 failed, 10 points; manifest" in captured.out
    assert "1 jobs" not in captured.err + captured.out
    assert batch_commands._count(1, "point") == "1 point" and batch_commands._count(2, "process") == "2 processes"


def test_a_second_batch_in_a_folder_is_refused_while_the_first_runs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                                  capsys: pytest.CaptureFixture[str]) -> None:
    """The lock of a live process refuses the batch in one line naming it, before any job; a killed one's lock
    (gone, or ended and not yet reaped) does not block the rerun."""
    monkeypatch.setattr(batch_commands, "LocalRunner", _Pretend)
    monkeypatch.setattr(_Pretend, "taken", 0)
    spec = tmp_path / "spec.toml"
    spec.write_text(SPEC)
    out = tmp_path / "out"
    out.mkdir()
    other = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    lock = out / ".batch.lock"
    held = json.dumps({"pid": other.pid, "host": socket.gethostname(), "started": "2026-01-02 03:04:05",
                       "running": []})
    lock.write_text(held)
    try:
        assert main(["batch", str(spec), "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and err.startswith(f"livox-viz: error: --out {out}: another batch is running "
                                                       f"there (process {other.pid}, since 2026-01-02 03:04:05)"), err
        assert not (out / "jobs").exists() and not (out / "manifest.csv").exists() and lock.exists()
        other.kill()
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline and batch_commands.process_alive(other.pid):
            time.sleep(0.01)
        # Ended, not yet reaped (a zombie): stale.
        assert main(["batch", str(spec), "--out", str(out)]) == 128 + signal.SIGINT
    finally:
        other.kill()
        other.wait()
    assert len(_manifest(out)) == 3 and not lock.exists()
    lock.write_text(held)  # its process now gone
    assert main(["batch", str(spec), "--out", str(out)]) == 128 + signal.SIGINT
    assert len(_manifest(out)) == 6 and not lock.exists()


def test_a_lock_whose_process_id_another_process_took_is_stale(tmp_path: Path) -> None:
    """A batch killed long ago left its lock; its process id now belongs to a live process started later (the
    lock's start differs): the lock is stale. The same lock with that process's own start is held, and so is
    one from an older version, which wrote no start."""
    other = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    lock = batch_commands.BatchLock(tmp_path)
    try:
        started = batch_commands.process_start(other.pid)
        for written, held in ((None, True), (started, True), ("an-earlier-boot:12345", False)):
            fields = {"pid": other.pid, "host": socket.gethostname(), "started": "2026-01-02 03:04:05"}
            lock.path.write_text(json.dumps({**fields, **({} if written is None else {"process_start": written})}))
            assert (lock.holder() is not None) == (held or started is None), written
        lock.acquire()  # the stale one taken over
        assert json.loads(lock.path.read_text())["process_start"] == batch_commands.process_start(os.getpid())
        lock.release()
    finally:
        other.kill()
        other.wait()


def test_stopping_the_local_pool_does_not_wait_on_a_lock_a_killed_worker_held(tmp_path: Path) -> None:
    """A worker killed while it put a result keeps the result queue's lock held, and Pool.terminate waited on it for
    ever (a CI run hung 300 s in stop). Here this process holds the lock, as the dead worker did."""
    import threading

    grid = read_spec(_huge_spec(tmp_path), force=True)
    runner = batch_commands.LocalRunner(1)
    running = runner.run(iter(grid), tmp_path / "out", 1)
    next(running)  # the pool is up
    assert runner._pool._outqueue._wlock.acquire(timeout=10)
    stopping = threading.Thread(target=runner.stop, daemon=True)
    stopping.start()
    stopping.join(60)
    assert not stopping.is_alive(), "stop() waited on the result queue's lock"
    running.close()


def test_a_worker_that_dies_on_its_own_ends_the_batch_with_one_line(tmp_path: Path) -> None:
    """The pool starts another process for one that died (a signal, the out-of-memory killer), but the job it
    ran is lost, and the batch waited for that job's result for ever (a full run of the suite hung 120 s here)."""
    grid = read_spec(_huge_spec(tmp_path), force=True)
    runner = batch_commands.LocalRunner(1)
    running = runner.run(iter(grid), tmp_path / "out", 1)
    next(running)  # the pool is up, a job in hand
    worker = next(iter(runner._pool._pool))
    os.kill(worker.pid, signal.SIGKILL)
    started = time.monotonic()
    with pytest.raises(batch_commands.LivoxVizError, match=rf"process {worker.pid}\) died \(killed by SIGKILL\) "
                                                           r"while it ran a job; .* run the batch again"):
        for _ in running:
            assert time.monotonic() - started < 30, "still waiting for the dead worker's job"
    runner.stop()


def test_the_local_pool_takes_jobs_as_it_has_room(tmp_path: Path) -> None:
    """A pool of one process holds at most two jobs (one running, one queued): of a grid of 200,000, it has
    taken no more than that when the first ends (it took all of them, each queued in the pool, before)."""
    grid = read_spec(_huge_spec(tmp_path), force=True)
    taken = [0]

    def jobs():
        for job in grid:
            taken[0] += 1
            yield job

    runner = batch_commands.LocalRunner(1)
    try:
        for record in runner.run(jobs(), tmp_path / "out", 1):
            if record is not None:
                break
    finally:
        runner.stop()
    assert record["status"] == "done" and record["job"] == grid[0].name, record
    assert taken[0] == 2


class _InProcess:
    """A runner of each job in this process (a pool's process takes seconds to start, eight times here)."""

    def __init__(self, processes: int) -> None:
        self.where = "this process"

    def run(self, jobs, root: Path, workers: int | None):
        for job in jobs:
            yield batch_commands.run_job(job, str(root), 1)

    def stop(self) -> None:
        pass


def test_a_job_whose_input_files_changed_runs_again(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    """A job's name hashes its parameters, file paths among them, not what the files hold: its record keeps each
    input file's SHA-256 (the sensor config, the scene JSON, its mesh, the mesh's sidecar, the TUM flight), and a
    rerun runs a job again when one of them changed, without --retry (a broken scene fixed runs; touching a file
    without changing it does not)."""
    config = tmp_path / "sensor.json"
    config.write_text((Path(__file__).parents[1] / "presets" / "livox_mid40.json").read_text(encoding="utf-8"))
    wall = tmp_path / "wall.obj"
    wall.write_text("o wall\nv 0 0 0\nv 1 0 0\nf 1 2 3\n")  # degenerate: the scene fails to load
    sidecar = tmp_path / "wall.materials.json"
    flight = tmp_path / "flight.tum"
    flight.write_text("".join(f"{t / 10} {t / 10} 0 -1.5 0 0 0 1\n" for t in range(20)))
    (tmp_path / "scene.json").write_text(json.dumps({"objects": [{"type": "mesh", "path": "wall.obj"}]}))
    spec = tmp_path / "spec.toml"
    spec.write_text(SPEC.replace('["livox_mid70"]', '["sensor.json"]').replace('["urban"]', '["scene.json"]').replace(
        '"none", "line", "circle"', '"flight.tum"').replace('"npz", "las+rosbag"', '"npz"'))
    out = tmp_path / "out"
    monkeypatch.setattr(batch_commands, "LocalRunner", _InProcess)

    def run() -> tuple[str, int]:
        status = main(["batch", str(spec), "--out", str(out), "--jobs", "1"])
        (row,) = _manifest(out)
        assert status == (row["status"] != "done")
        return row["status"], next(out.glob("jobs/*/job.json")).stat().st_mtime_ns

    assert run()[0] == "failed"
    first = run()
    assert first[0] == "failed" and "1 failed: --retry runs it again" in capsys.readouterr().err
    wall.write_text("o wall\nv 10 -5 -5\nv 10 5 -5\nv 10 0 5\nf 1 2 3\n")  # fixed: a wall ahead
    fixed = run()
    assert fixed[0] == "done" and fixed[1] != first[1]
    record = json.loads(next(out.glob("jobs/*/job.json")).read_text())
    assert set(record["inputs"]) == {str(config), str(tmp_path / "scene.json"), str(wall), str(sidecar), str(flight)}
    assert record["inputs"][str(sidecar)] is None
    os.utime(wall)  # touched, not changed
    assert run() == fixed
    last = fixed
    for edit in (lambda: sidecar.write_text('{"wall": 0.2}'),  # a sidecar that appears changes the scene too
                 lambda: sidecar.write_text('{"wall": 0.9}'),
                 lambda: flight.write_text(flight.read_text() + "2.0 2.0 0 -1.5 0 0 0 1\n"),
                 lambda: config.write_text(config.read_text() + "\n")):
        edit()
        again = run()
        assert again[0] == "done" and again[1] != last[1], edit
        last = again
    assert run() == last


def _file_size_limit(limit: int):
    """A child's preexec: files no larger than ``limit`` bytes, a write past it failing with EFBIG (as a full disk's
    ENOSPC) rather than killing the process with SIGXFSZ."""
    def limited() -> None:
        import resource

        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, resource.RLIM_INFINITY))
    return limited


@pytest.mark.skipif(not hasattr(signal, "SIGXFSZ"), reason="file size limits are POSIX's")
def test_a_batch_whose_disk_fills_ends_with_one_line_naming_the_file_and_leaves_no_worker(tmp_path: Path) -> None:
    """Issue 47: a full disk under a local batch printed the system's words, then the pool's finaliser sent its
    workers SIGTERM, which a worker took as a scan takes one, and the batch waited on it for ever."""
    spec = tmp_path / "spec.toml"
    spec.write_text(SPEC.replace("seconds = 0.1", "seconds = 0.05").replace("seeds = [3]", f"seeds = {list(range(24))}")
                    .replace('"none", "line", "circle"', '"none"').replace('["npz", "las+rosbag"]', '["ply"]'))
    process = subprocess.Popen([sys.executable, "-m", "livox_viz", "batch", str(spec), "--out", str(tmp_path / "out"),
                                "--jobs", "2"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               start_new_session=True, preexec_fn=_file_size_limit(3000))
    try:
        _out, err = process.communicate(timeout=120)
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
            process.communicate()
    assert process.returncode == 2, err[-2000:]
    last = err.strip().splitlines()[-1]
    assert last.startswith("livox-viz: error: ") and "manifest.csv: cannot add job" in last, err[-2000:]
    assert "Traceback" not in err
    # Every worker of the pool is gone with the batch (a session of its own: nothing of it is left; the resource
    # tracker ends once the batch's end of its pipe is closed).
    assert_session_ends(process.pid, 10)


def assert_session_ends(session: int, seconds: float) -> None:
    """Return once no process of the session (process group) ``session`` is left; fail, listing them, after
    ``seconds``."""
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        try:
            os.killpg(session, 0)
        except ProcessLookupError:
            return
        time.sleep(0.1)
    left = subprocess.run(["ps", "-o", "pid,args", "-g", str(session)], capture_output=True, text=True).stdout
    raise AssertionError(f"processes of the batch left running after {seconds:g} s:\n{left}")


@pytest.mark.parametrize("damage", [None, [], {"cloud.npz": None}, "deep"])
def test_a_hand_damaged_record_is_a_job_to_run_again_not_a_crash(local_run: tuple[Path, Path], tmp_path: Path,
                                                                 damage: object) -> None:
    """Issue 47: such a job.json crashed the rerun with AttributeError or RecursionError."""
    import shutil

    _, out = local_run
    copy = tmp_path / "out"
    shutil.copytree(out, copy)
    name = _manifest(copy)[0]["job"]
    record_path = copy / "jobs" / name / "job.json"
    assert batch_commands.finished_record(copy, name) is not None
    if damage == "deep":
        record_path.write_text("[" * 100_000 + "]" * 100_000)
    else:  # still JSON, and still this job's: damaged in meaning only
        record_path.write_text(json.dumps({**json.loads(record_path.read_text()), "files": damage}))
    assert batch_commands.finished_record(copy, name) is None


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="FIFOs are POSIX's")
def test_a_fifo_or_an_endless_file_in_place_of_a_record_or_the_lock_blocks_nothing(tmp_path: Path) -> None:
    """Issue 47: a FIFO as a job's job.json or as OUT/.batch.lock blocked the batch in open() past SIGINT and
    SIGTERM; a link to /dev/zero was read until the memory ran out."""
    import threading

    (tmp_path / "jobs" / "a").mkdir(parents=True)
    (tmp_path / "jobs" / "b").mkdir()
    os.mkfifo(tmp_path / "jobs" / "a" / "job.json")
    os.symlink("/dev/zero", tmp_path / "jobs" / "b" / "job.json")
    os.mkfifo(tmp_path / batch_commands.LOCK)
    answers: dict[str, object] = {}

    def ask() -> None:
        answers["a"] = batch_commands.finished_record(tmp_path, "a")
        answers["b"] = batch_commands.finished_record(tmp_path, "b")
        answers["lock"] = batch_commands.BatchLock(tmp_path).holder()

    asking = threading.Thread(target=ask, daemon=True)
    asking.start()
    asking.join(10)
    assert not asking.is_alive(), "a read blocked"
    assert answers["a"] is None and answers["b"] is None
    # A FIFO at the lock is no lock of a live batch: taken as held only while it is young, as a half-written one.
    assert answers["lock"] is None or answers["lock"]["pid"] == "?"


def test_a_lock_the_disk_cannot_hold_is_removed_and_named(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Issue 47: a full disk while the lock was written left an empty .batch.lock and said only 'No space left on
    device'; a rerun was then refused for 10 s as 'another batch is running there (process ?, since just now)'."""
    import errno

    lock = batch_commands.BatchLock(tmp_path)
    real_fdopen = os.fdopen

    class Full:
        def __init__(self, handle) -> None:
            self.handle = handle

        def __enter__(self):
            return self

        def __exit__(self, *exc) -> None:
            self.handle.close()

        def write(self, text: str) -> int:
            raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(batch_commands.os, "fdopen", lambda *a, **k: Full(real_fdopen(*a, **k)))
    with pytest.raises(batch_commands.LivoxVizError, match=r"cannot write its lock .*\.batch\.lock \(No space left "
                                                           r"on device\); nothing was run"):
        lock.acquire()
    monkeypatch.undo()
    assert not (tmp_path / batch_commands.LOCK).exists()
    assert lock.holder() is None


def test_a_killed_batch_takes_its_pool_with_it(tmp_path: Path) -> None:
    """Issue 47: SIGKILL of a local batch left its workers running (re-parented to init); they finished their jobs
    beside the rerun's. Each worker now leaves when the batch is gone."""
    from .conftest import SEED_JSON

    # Jobs of a minute each (10 minutes of a 1 x 1 x 1000 Hz sensor): a worker left running is still there later.
    (tmp_path / "slow.json").write_text(json.dumps({**SEED_JSON, "DataWidth": 1, "DataHeight": 1,
                                                   "DataCheckFreq": 1000}))
    spec = tmp_path / "spec.toml"
    spec.write_text(SPEC.replace("seconds = 0.1", "seconds = 600").replace('["livox_mid70"]', '["slow.json"]')
                    .replace('"none", "line", "circle"', '"none"').replace('["npz", "las+rosbag"]', '["ply"]')
                    .replace("seeds = [3]", "seeds = [1, 2]"))
    process = subprocess.Popen([sys.executable, "-m", "livox_viz", "batch", str(spec), "--out", str(tmp_path / "out"),
                                "--jobs", "2"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                               start_new_session=True, cwd=tmp_path)
    try:
        deadline = time.monotonic() + 120
        while len(list((tmp_path / "out").glob("jobs/*/"))) < 2:  # both jobs under way
            assert time.monotonic() < deadline and process.poll() is None, "the jobs did not start"
            time.sleep(0.1)
        time.sleep(1.0)
        process.kill()
        process.wait()
        assert_session_ends(process.pid, 15)
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(process.pid, signal.SIGKILL)


def test_a_rerun_after_the_outputs_went_counts_them_as_jobs_to_run(local_run: tuple[Path, Path], tmp_path: Path,
                                                                  capsys: pytest.CaptureFixture[str]) -> None:
    """Issue 47: with every output deleted, a rerun said '6 already finished; 0 to run on a local pool of 1
    process', ran all six on that one process, showed '[5/6]' five times and counted twice the points of the
    summary."""
    import re
    import shutil

    spec, out = local_run
    copy = tmp_path / "out"
    shutil.copytree(out, copy)
    points = sum(int(row["points"]) for row in _manifest(copy))
    for output in copy.glob("jobs/*/*"):
        if output.name != "job.json":
            shutil.rmtree(output) if output.is_dir() else output.unlink()
    capsys.readouterr()
    assert main(["batch", str(spec), "--out", str(copy), "--jobs", "2"]) == 0
    captured = capsys.readouterr()
    assert "6 jobs from spec.toml: 0 already finished; 6 to run on a local pool of 2 processes" in captured.err
    progress = re.findall(r"batch: \[(\d+)/6\] done .*?; 0 failed, ([\d,]+) points", captured.err)
    assert [int(k) for k, _ in progress] == [1, 2, 3, 4, 5, 6]
    assert int(progress[-1][1].replace(",", "")) == points
    assert f"6 of 6 jobs done, 0 failed, {points:,} points" in captured.out


def test_a_killed_batch_s_job_in_flight_that_finished_counts_in_the_first_line(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A batch killed after a job's files were written but before its row, the job still listed in flight in its
    lock: the rerun takes the row from the lock's list before it counts, so its first line says the job is
    finished (not "1 to run", for a job it then only skips)."""
    spec, out = _two_jobs_run(tmp_path)
    first, second = _manifest(out)
    with open(out / "manifest.csv", newline="") as handle:
        header = handle.readline()
        kept = handle.readline()
    (out / "manifest.csv").write_text(header + kept)  # the second job's row never written
    gone = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True,
                          check=True)
    (out / ".batch.lock").write_text(json.dumps({"pid": int(gone.stdout), "host": socket.gethostname(),
                                                 "started": "2026-01-02 03:04:05", "running": [second["job"]]}))
    capsys.readouterr()
    assert main(["batch", str(spec), "--out", str(out), "--jobs", "1"]) == 0
    err = capsys.readouterr().err
    assert "batch: 2 jobs from" in err and "2 already finished; 0 to run" in err, err
    assert [row["job"] for row in _manifest(out)] == [first["job"], second["job"]]


@pytest.mark.parametrize(("seconds", "said"), [(59.4, "0:59"), (3599.4, "59:59"), (3600.0, "1:00:00"),
                                               (3661.0, "1:01:01")])
def test_the_progress_clock_turns_to_hours_at_one_hour(seconds: float, said: str) -> None:
    assert batch_commands._clock(seconds) == said


def test_each_job_s_place_in_the_grid_is_where_the_grid_makes_it(tmp_path: Path) -> None:
    """``place_of`` (how a tidied manifest orders its rows) gives each job's own index in the grid, and None for a
    name the grid does not make with those parameters."""
    spec = tmp_path / "spec.toml"
    spec.write_text(SPEC.replace("seeds = [3]", "seeds = [3, 4]"))
    grid = read_spec(spec)
    assert grid.total == 12
    for index in range(grid.total):
        job = grid[index]
        assert grid.place_of(job.name, job.parameters()) == index
    assert grid.place_of(grid[1].name, grid[0].parameters()) is None
