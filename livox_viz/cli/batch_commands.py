"""``batch``: a grid of scans run as jobs, on a local pool of processes or a Dask cluster, resumable.

Every job (:mod:`~livox_viz.cli.batch_spec`) is a normal ``scan`` (:func:`run_job`)
into a folder of its own, ``OUT/jobs/<job>/``, whose files are written atomically
as ``scan`` writes them; its record (parameters, outputs with their sizes and
SHA-256, frames, points, duration, or its error) goes last into ``job.json``
beside them, and as a row at the end of ``OUT/manifest.csv`` (:class:`Manifest`).
A job whose record says done and whose files are there is not run again, so a
batch stopped half-way (Ctrl-C, a killed process, a lost node) is finished by
running it again; a failed job is reported with its error, does not stop the
others, and runs again with ``--retry``. The grid is never listed: its jobs are
made, named and handed out as the runner has room (:func:`_bounded`), so the
batch's memory does not grow with it. One batch at a time holds a folder
(:class:`BatchLock`).

Jobs run on a local pool of processes (the default: nothing to start), or on
Dask distributed (``--dask ADDRESS`` for a running scheduler, a SLURM or
Kubernetes cluster's; ``--dask local:N`` for a ``LocalCluster`` of N processes),
the optional extra ``livox-viz[cluster]``. The workers must see ``OUT`` and the
spec's files at the same paths (a shared file system).
"""

from __future__ import annotations

import argparse
import csv
import hashlib
import io
import json
import logging
import multiprocessing
import multiprocessing.pool
import os
import shutil
import signal
import socket
import stat
import sys
import threading
import time
from array import array
from collections.abc import Callable, Iterator
from contextlib import contextmanager, suppress
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np

from livox_viz.core.atomic import atomic_path, remove_dead_leftovers, resolve_destination, write_text_atomic
from livox_viz.core.errors import LivoxVizError, os_error_reason
from livox_viz.core.portable import process_alive, process_start, usable_cores
from livox_viz.files.export import sidecar_path
from livox_viz.motion.flights import BUILTIN_TRAJECTORIES
from livox_viz.scene.scenes import scene_files

from .batch_spec import EXAMPLE, MAX_JOBS, NO_TRAJECTORY, Grid, Job, SpecError, read_spec, scan_argv
from .common import PROG, Command, UsageError, whole_number
from .signals import StopRequests, signal_name, signal_status

#: The batch's record in its folder, and its columns, one row a job in the spec's order.
MANIFEST = "manifest.csv"
MANIFEST_COLUMNS = ("job", "status", "sensor", "scene", "trajectory", "seed", "returns", "outputs", "seconds",
                    "frames", "points", "duration_s", "files", "error")
#: The lock of a folder a batch runs in.
LOCK = ".batch.lock"
#: Seconds after which a lock without its content (its batch killed while making it) is stale.
STALE_EMPTY_LOCK_SECONDS = 10.0
#: Seconds a batch waits for a Dask scheduler to answer.
CONNECT_SECONDS = 10.0
#: Jobs handed to a Dask cluster at once, at least (without --jobs).
DASK_IN_FLIGHT = 1000
#: Failed jobs named one by one at the end of a batch.
SHOWN_FAILURES = 20


# One job, in a worker ------------------------------------------------------------------------------
class _ScanParser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # type: ignore[override]
        raise UsageError(message)


def run_job(job: Job, root: str, workers: int | None) -> dict[str, Any]:
    """Run ``job``'s scan into ``root/jobs/<job>/`` and return its record (also written there as ``job.json``).

    Runs in a worker process (the local pool's or a Dask worker's); never raises for the job's own failure:
    the record says ``failed`` with the error's one line. A job stopped by a signal (the batch stopping its
    pool) keeps no record: its status ``stopped`` is this run's, and a rerun runs it again.
    """
    from .scan_commands import _scan_arguments, run_scan

    folder = Path(root) / "jobs" / job.name
    record: dict[str, Any] = {"job": job.name, **job.parameters(), "status": "failed", "frames": 0, "points": 0,
                              "duration_s": 0.0, "files": {}, "error": ""}
    start = time.perf_counter()
    try:
        folder.mkdir(parents=True, exist_ok=True)
        _clear(folder, job)
        if workers is None:
            workers = _workers_in_dask()
        record["inputs"] = input_digests(job)  # before the scan: a file edited while it runs makes it run again
        parser = _ScanParser(prog=f"{PROG} scan")
        _scan_arguments(parser)
        report = run_scan(parser.parse_args(scan_argv(job, folder, workers)[1:]), progress=io.StringIO())
        record.update(frames=report.frames, points=report.points)
        if report.stopped_by is not None:  # the batch is stopping: no record, so a rerun runs the job again
            record.update(status="stopped", duration_s=round(time.perf_counter() - start, 3),
                          error=f"stopped by {signal_name(report.stopped_by)} after {report.seconds:g} s of scan")
            return record
        else:
            record["files"] = _hashes(folder, job)
            record["status"] = "done"
    except LivoxVizError as error:
        record["error"] = str(error)
    except Exception as error:  # the job's own failure, whatever it is: the others go on
        record["error"] = f"{type(error).__name__}: {error}"
    record["duration_s"] = round(time.perf_counter() - start, 3)
    try:
        write_text_atomic(folder / "job.json", json.dumps(record, indent=1) + "\n")
    except (OSError, LivoxVizError) as error:
        record.update(status="failed", error=f"cannot write its record: {error}")
    return record


def _written(folder: Path, job: Job) -> list[Path]:
    """What the job writes in its folder: its file (and a CSV's sidecar), its bag."""
    paths = [folder / name for name in job.output_names().values()]
    return [*paths, *filter(None, (sidecar_path(path) for path in paths if path.suffix == ".csv"))]


def _clear(folder: Path, job: Job) -> None:
    """An earlier try's outputs and record (it did not finish: a rerun starts the job afresh)."""
    for path in (*_written(folder, job), folder / "job.json"):
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path)
        elif os.path.lexists(path):
            path.unlink()


def _hashes(folder: Path, job: Job) -> dict[str, dict[str, Any]]:
    """Each file the job wrote (a bag's files one by one): its size and SHA-256."""
    found: dict[str, dict[str, Any]] = {}
    for path in _written(folder, job):
        for file in sorted(path.rglob("*")) if path.is_dir() else [path]:
            if file.is_file():
                found[str(file.relative_to(folder))] = {"bytes": file.stat().st_size, "sha256": _sha256(file)}
    return found


def _sha256(path: Path) -> str:
    """A file's SHA-256, read a MiB at a time."""
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        while block := handle.read(1 << 20):
            digest.update(block)
    return digest.hexdigest()


def _workers_in_dask() -> int | None:
    """In a Dask worker: the cores of its process shared among its threads (each runs a job); else None (the
    scan's own default: every core this process may use)."""
    if "distributed" not in sys.modules:
        return None
    try:
        from distributed import get_worker

        threads = get_worker().state.nthreads
    except (ValueError, AttributeError):  # not inside a worker
        return None
    return max(1, usable_cores() // max(1, threads))


def _ignore_interrupts() -> None:
    """A local worker leaves Ctrl-C to the batch (which stops the pool): a terminal's Ctrl-C reaches every process
    of its group, and a job must not stop half-way on its own."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _local_worker_start() -> None:
    """A local pool's worker: Ctrl-C left to the batch (:func:`_ignore_interrupts`), and it ends when the batch does.

    A batch killed with SIGKILL left its workers running, re-parented to init: they finished their jobs, printed
    BrokenPipeError tracebacks, and a rerun started at once ran the same jobs beside them (issue 47). The worker
    watches its parent's sentinel (a pipe's end on POSIX, the process handle on Windows) and leaves at once when
    the batch is gone; its job's temporaries are left to the rerun, which removes a dead process's.
    """
    _ignore_interrupts()
    parent = multiprocessing.parent_process()
    if parent is None:
        return

    def watch() -> None:
        parent.join()
        os._exit(1)

    threading.Thread(target=watch, name="livox-viz-batch-parent", daemon=True).start()


# Records and the manifest ----------------------------------------------------------------------------
def input_digests(job: Job) -> dict[str, str | None]:
    """The SHA-256 of each file the job reads (its sensor config, its scene's files, its TUM trajectory; none for
    a preset or a built-in), None for one that is missing: a record keeps them, and an edited file makes the job
    run again (its name hashes the paths, not what they hold)."""
    files = [Path(job.sensor)] if job.sensor.endswith(".json") else []
    files += scene_files(job.scene)
    if job.trajectory != NO_TRAJECTORY and job.trajectory not in BUILTIN_TRAJECTORIES:
        files.append(Path(job.trajectory))
    return {str(path): _file_digest(path) for path in dict.fromkeys(files)}


#: Digests of input files by (path, size, modification time): a batch asks the same few files of every job.
_DIGESTS: dict[tuple[str, int, int], str] = {}


def _file_digest(path: Path) -> str | None:
    """A file's SHA-256, None when it is missing or unreadable."""
    try:
        status = path.stat()
        key = (str(path), status.st_size, status.st_mtime_ns)
        if key not in _DIGESTS:
            if len(_DIGESTS) > 4096:
                _DIGESTS.clear()
            _DIGESTS[key] = _sha256(path)
        return _DIGESTS[key]
    except OSError:
        return None


#: Bytes a job's record or the folder's lock may hold: both are a few hundred bytes; anything bigger is not ours.
MAX_OWN_FILE_BYTES = 1 << 20


def read_own_file(path: str | os.PathLike[str]) -> bytes | None:
    """The bytes of a small file the batch itself wrote (a job's record, the folder's lock), or None when there is
    no such regular file or it is larger than :data:`MAX_OWN_FILE_BYTES`.

    Opened without blocking and judged by what was opened (issue 47): a FIFO in its place blocked the batch in
    ``open()`` past SIGINT and SIGTERM, and a link to ``/dev/zero`` was read until the memory ran out.
    """
    try:
        descriptor = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_BINARY", 0))
    except OSError:
        return None
    with os.fdopen(descriptor, "rb") as handle:
        try:
            status = os.fstat(descriptor)
            if not stat.S_ISREG(status.st_mode) or status.st_size > MAX_OWN_FILE_BYTES:
                return None
            data = handle.read(MAX_OWN_FILE_BYTES + 1)
        except OSError:
            return None
    return data if len(data) <= MAX_OWN_FILE_BYTES else None


def _is_files_record(files: Any) -> bool:
    """A record's ``files``: each output's name with its ``bytes`` and ``sha256``."""
    return isinstance(files, dict) and all(
        isinstance(name, str) and isinstance(about, dict) and isinstance(about.get("bytes"), int)
        and isinstance(about.get("sha256"), str) for name, about in files.items())


def finished_record(root: Path, name: str) -> dict[str, Any] | None:
    """The job ``name``'s record from an earlier run, when its files are all there with their sizes and the files
    it read are as they were (else None: the job runs again)."""
    # Strings, not Paths: a rerun asks this of every job of the grid, most of them without a record yet.
    data = read_own_file(os.path.join(root, "jobs", name, "job.json"))
    if data is None:
        return None
    try:
        record = json.loads(data.decode("utf-8"))
    except (ValueError, RecursionError):  # a record nested 100,000 deep is no record (it crashed the rerun)
        return None
    # A record damaged by hand ("files": null, [], {"cloud.npz": null}) is no record either: the job runs again.
    if (not isinstance(record, dict) or record.get("job") != name or record.get("status") not in _STATUSES
            or not _is_files_record(record.get("files", {}))):
        return None
    inputs = record.get("inputs", {})  # a record of an older version has none: its files are taken as they were
    if not isinstance(inputs, dict) or any(not isinstance(path, str) or _file_digest(Path(path)) != digest
                                           for path, digest in inputs.items()):
        return None
    if record.get("status") == "done":
        for file_name, about in record.get("files", {}).items():
            file = root / "jobs" / name / file_name
            if not file.is_file() or file.stat().st_size != about.get("bytes"):
                return None
    return record


def _row(record: dict[str, Any]) -> list[Any]:
    """A record as the manifest's row, each field on one line (a torn last line is then a line without its end)."""
    files = " ".join(f"{name}:{about['sha256']}" for name, about in record.get("files", {}).items())
    row = [record.get("job"), record.get("status"), record.get("sensor"), record.get("scene"),
           record.get("trajectory"), record.get("seed"), record.get("returns"), record.get("outputs"),
           record.get("seconds"), record.get("frames", ""), record.get("points", ""), record.get("duration_s", ""),
           files, record.get("error", "")]
    return [" ".join(value.splitlines()) if isinstance(value, str) else value for value in row]


def _name_key(name: str) -> int:
    """A job name's 64-bit key in the index of the manifest's rows."""
    return int.from_bytes(hashlib.blake2b(name.encode("utf-8"), digest_size=8).digest(), "little")


_STATUSES = ("done", "failed")


class Manifest:
    """``OUT/manifest.csv``, grown by one row as each job finishes, and the index of the jobs it lists.

    A row is appended (and flushed) as a job ends, never the whole file rewritten per job (that was quadratic in
    the jobs): a batch killed at any moment leaves every earlier row, and at most a last line without its end,
    which the next run drops before it appends. The index says which jobs have a row and their last status and
    points: 17 bytes a row (a sorted array of 64-bit keys of the names, a status byte, the points), 170 MB for
    10**7 rows, so a rerun skips finished jobs without holding their names. A job that runs again (``--retry``,
    its files gone) gets a row after its old one; :meth:`tidy` keeps only each job's last row at the end of a run
    (one pass), and puts a grid of at most MAX_JOBS jobs in the spec's order, as a small batch's manifest always
    was. Rows are those of finished jobs (done or failed); a job without one has not finished.
    """

    def __init__(self, root: Path, grid: Grid, spec: str) -> None:
        self.path = root / MANIFEST
        self.grid = grid
        self.spec = spec
        self.done = self.failed = self.points = 0
        #: Rows that a later row of the same job makes stale (or that are no finished job's: an old version's
        #: ``pending``), so :meth:`tidy` has work.
        self.superseded = 0
        self._keys: np.ndarray = np.zeros(0, np.uint64)
        self._statuses: np.ndarray = np.zeros(0, np.int8)
        self._points: np.ndarray = np.zeros(0, np.int64)
        self._late: dict[str, tuple[str, int]] = {}  # rows appended this run for jobs the index may meet again
        self._end = 0  # where the last whole line ends
        self._seen: tuple[int, int] | None = None  # the file's size and time when read
        self._handle: Any = None
        self._header = list(MANIFEST_COLUMNS)

    # Reading ---------------------------------------------------------------------------------------------
    def read(self) -> None:
        """Read the rows there are (a last line without its end is left out), checking they are this grid's.

        Raises
        ------
        UsageError
            When the file is not a batch manifest, or lists jobs this spec does not make (another batch's).
        """
        out = self.path.parent
        self.done = self.failed = self.points = self.superseded = 0
        if not self.path.is_file():
            self._seen = None
            return
        keys: array[int] = array("Q")
        statuses: array[int] = array("b")
        points: array[int] = array("q")
        others = 0
        example = ""
        try:
            status = self.path.stat()
            with open(self.path, "rb") as raw:
                self._end = _whole_lines_end(raw)
                raw.seek(0)
                text = io.TextIOWrapper(io.BufferedReader(_Limited(raw, self._end)), encoding="utf-8", newline="")
                rows = csv.reader(text)
                header = next(rows, None)
                if header is None or "job" not in header:
                    raise ValueError("no job column")
                self._header = header
                if header != list(MANIFEST_COLUMNS):
                    self.superseded += 1  # another version's columns: tidy() writes them as this version's
                column = {name: header.index(name) for name in header}
                for row in rows:
                    if len(row) != len(header):
                        continue
                    name = row[column["job"]]
                    fields = dict(zip(header, row, strict=True))
                    if self.grid.place_of(name, fields) is None:
                        others += 1
                        example = example or name
                        continue
                    if fields.get("status") not in _STATUSES:
                        self.superseded += 1
                        continue
                    keys.append(_name_key(name))
                    statuses.append(_STATUSES.index(fields["status"]))
                    points.append(_whole(fields.get("points")))
        except (OSError, UnicodeDecodeError, csv.Error, ValueError):
            raise UsageError(f"--out {out}: holds a manifest.csv that is not a batch's manifest; allowed: a folder of "
                             "this spec's batch (to finish it) or a new one (it is not replaced)") from None
        if others:
            raise UsageError(f"--out {out}: holds another batch's manifest ({others:,} of its jobs, e.g. {example}, "
                             f"are not jobs of {self.spec}); allowed: this spec's own folder (to finish it) or a new "
                             "one (it is not replaced)")
        self._seen = (status.st_size, status.st_mtime_ns)
        self._index(np.frombuffer(keys, np.uint64), np.frombuffer(statuses, np.int8),
                    np.frombuffer(points, np.int64))

    def _index(self, keys: np.ndarray, statuses: np.ndarray, points: np.ndarray) -> None:
        """Keep each job's last row: its key, status and points, sorted by key."""
        order = np.argsort(keys, kind="stable")
        keys, statuses, points = keys[order], statuses[order], points[order]
        last: np.ndarray = np.ones(len(keys), bool)
        last[:-1] = keys[1:] != keys[:-1]
        self.superseded += int(len(keys) - last.sum())
        self._keys, self._statuses, self._points = keys[last], statuses[last], points[last]
        self.done = int((self._statuses == 0).sum())
        self.failed = int((self._statuses == 1).sum())
        self.points = int(self._points[self._statuses == 0].sum())

    def previous(self, name: str) -> tuple[str, int] | None:
        """The job's status and points in its last row, or None if the manifest has no row of it."""
        if name in self._late:
            return self._late[name]
        key = np.uint64(_name_key(name))
        at = int(np.searchsorted(self._keys, key))
        if at < len(self._keys) and self._keys[at] == key:
            return _STATUSES[self._statuses[at]], int(self._points[at])
        return None

    # Writing ---------------------------------------------------------------------------------------------
    def open(self) -> None:
        """Ready to append (the batch holds the folder's lock): read again if the file changed since it was read,
        drop a last line without its end, start a new file with its header."""
        if self.path.is_file():
            status = self.path.stat()
            if self._seen != (status.st_size, status.st_mtime_ns):
                self.read()
            if self.superseded and self._header != list(MANIFEST_COLUMNS):
                self.tidy()
                self.read()
        if not self.path.is_file():
            write_text_atomic(self.path, ",".join(MANIFEST_COLUMNS) + "\n")
            self._end = self.path.stat().st_size
        self._handle = open(self.path, "r+", newline="", encoding="utf-8")
        self._handle.truncate(self._end)
        self._handle.seek(self._end)

    def append(self, record: dict[str, Any], again: bool = False) -> None:
        """A finished job's row, on disk when this returns (flushed to the system, not synced: a power cut may
        lose the last rows, which the next run's records put back). ``again``: the job may be met again in this
        run (its row is remembered by name)."""
        previous = self.previous(record["job"])
        if previous is not None:
            self.superseded += 1
            self._count(*previous, -1)
        status = record["status"]
        points = int(record.get("points") or 0)
        self._count(status, points, 1)
        if again:
            self._late[record["job"]] = (status, points)
        text = io.StringIO()
        csv.writer(text, lineterminator="\n").writerow(_row(record))
        try:
            self._handle.write(text.getvalue())
            self._handle.flush()
        except OSError as error:  # a full disk: the message names the file (it said only the system's words)
            raise LivoxVizError(f"{self.path}: cannot add job {record['job']}'s row ({os_error_reason(error)}); "
                                "the rows before it are kept, and a rerun adds it from the job's record") from error

    def _count(self, status: str, points: int, sign: int) -> None:
        if status == "done":
            self.done += sign
            self.points += sign * points
        elif status == "failed":
            self.failed += sign

    def close(self) -> None:
        if self._handle is not None:
            self._handle.close()
            self._handle = None

    def tidy(self) -> None:
        """Rewrite the file (atomically, in one pass) with each finished job's last row only, in the spec's order
        when the grid has at most MAX_JOBS jobs; nothing to do for a bigger grid whose rows are each a job's only
        one."""
        self.close()
        small = self.grid.total <= MAX_JOBS
        if not self.path.is_file() or not (small or self.superseded):
            return
        keys: array[int] = array("Q")
        with open(self.path, newline="", encoding="utf-8") as handle:
            rows = csv.reader(handle)
            header = next(rows)
            for row in rows:
                keys.append(_name_key(row[header.index("job")]) if len(row) == len(header) else 0)
        found = np.frombuffer(keys, np.uint64)
        order = np.argsort(found, kind="stable")  # a job's rows stay in the file's order
        ends: np.ndarray = np.ones(len(found), bool)
        ends[:-1] = found[order][1:] != found[order][:-1]
        last: np.ndarray = np.zeros(len(found), bool)  # each job's last row
        last[order[ends]] = True
        kept: list[tuple[int, list[Any]]] = []
        with open(self.path, newline="", encoding="utf-8") as handle, atomic_path(self.path) as temporary, \
                open(temporary, "w", newline="", encoding="utf-8") as written:
            rows = csv.reader(handle)
            header = next(rows)
            table = csv.writer(written, lineterminator="\n")
            table.writerow(MANIFEST_COLUMNS)
            for number, row in enumerate(rows):
                if not last[number] or len(row) != len(header):
                    continue
                fields = dict(zip(header, row, strict=True))
                if fields.get("status") not in _STATUSES:
                    continue
                line = [fields.get(column, "") for column in MANIFEST_COLUMNS]
                if small:
                    kept.append((self.grid.place_of(fields["job"], fields) or 0, line))
                else:
                    table.writerow(line)
            table.writerows(line for _, line in sorted(kept, key=lambda placed: placed[0]))
        self.superseded = 0


def _whole(text: Any) -> int:
    try:
        return int(text)
    except (TypeError, ValueError):
        return 0


def _whole_lines_end(raw: BinaryIO) -> int:
    """Where the file's last whole line (ending in a newline) ends: a batch killed while appending a row left at
    most a part of a line after it."""
    end = raw.seek(0, os.SEEK_END)
    block = 1 << 16
    while end > 0:
        start = max(0, end - block)
        raw.seek(start)
        data = raw.read(end - start)
        newline = data.rfind(b"\n")
        if newline >= 0:
            return start + newline + 1
        end = start
    return 0


class _Limited(io.RawIOBase):
    """The first ``size`` bytes of a binary file, as a file."""

    def __init__(self, raw: BinaryIO, size: int) -> None:
        self.raw = raw
        self.left = size

    def readable(self) -> bool:
        return True

    def readinto(self, buffer: Any) -> int:
        count = min(len(buffer), self.left)
        data = self.raw.read(count)
        buffer[:len(data)] = data
        self.left -= len(data)
        return len(data)


# The folder's lock -----------------------------------------------------------------------------------
class BatchLock:
    """``OUT/.batch.lock``: one batch at a time in a folder, and the jobs it has in flight.

    Made with an exclusive create (``O_EXCL``, on Windows too), holding the batch's process id, host and start, and
    the names of the jobs it has handed out (rewritten atomically as they change): a batch killed with jobs in
    flight leaves them there, and the rerun puts the rows of those that finished into the manifest before it
    counts what is done. A lock whose process is gone (or ended and not yet reaped: :func:`process_alive`) is
    stale and taken over, and so is one whose process id another process now has (its start differs from the one
    written: :func:`process_start`); one made on another host (a shared folder) cannot be probed and is taken as
    held.
    """

    def __init__(self, root: Path) -> None:
        self.path = root / LOCK
        self.running: set[str] = set()
        #: The jobs the stale lock taken over listed as in flight.
        self.left_running: list[str] = []
        self._written: frozenset[str] = frozenset()
        self._held = False
        self._started = time.strftime("%Y-%m-%d %H:%M:%S")
        self._process_start = process_start(os.getpid())

    def holder(self) -> dict[str, Any] | None:
        """What the lock of a live batch says (its ``pid``, ``host``, ``started``), or None: no lock, or stale."""
        if not os.path.lexists(self.path):
            return None
        try:
            text = read_own_file(self.path)
            if text is None:
                raise ValueError(f"{self.path} is no lock this program wrote")
            data = json.loads(text.decode("utf-8"))
            pid = int(data["pid"])
            host = str(data.get("host", ""))
        except (OSError, ValueError, KeyError, TypeError, AttributeError, RecursionError):
            # Being written this instant, or a batch killed while it wrote it: stale once it is a few seconds old.
            try:
                young = time.time() - self.path.stat().st_mtime < STALE_EMPTY_LOCK_SECONDS
            except OSError:
                return None
            return {"pid": "?", "host": socket.gethostname(), "started": "just now"} if young else None
        if host != socket.gethostname():
            return data
        if pid == os.getpid() or not process_alive(pid):
            return None
        # A process id is reused: another process now holding the dead batch's id started at another time.
        written, now = data.get("process_start"), process_start(pid)
        return None if written is not None and now is not None and written != now else data

    def refuse_if_held(self) -> None:
        """Raise the one line naming the other batch, when a live one holds the folder."""
        holder = self.holder()
        if holder is not None:
            where = "" if holder.get("host") == socket.gethostname() else f" on host {holder.get('host')}"
            pid = holder.get("pid")
            raise UsageError(f"--out {self.path.parent}: another batch is running there (process {pid}{where}, "
                             f"since {holder.get('started', '?')}); allowed: wait for it to end, or another folder "
                             f"(if process {pid} is no livox-viz batch, remove {self.path})")

    def acquire(self) -> None:
        """Take the lock, or raise :meth:`refuse_if_held`'s line; a stale lock is taken over."""
        for _ in range(3):
            try:
                descriptor = os.open(self.path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
            except FileExistsError:
                self.refuse_if_held()
                self._take_stale()
                continue
            except OSError as error:
                raise UsageError(f"--out {self.path.parent}: cannot make its lock {self.path} ({error.strerror}); "
                                 "allowed: a folder this user can write") from None
            try:
                with os.fdopen(descriptor, "w", encoding="utf-8") as handle:
                    handle.write(self._text())
            except OSError as error:
                # A full disk: an empty lock left behind made the rerun say "another batch is running there
                # (process ?, since just now)" for 10 s (issue 47).
                with suppress(OSError):
                    os.unlink(self.path)
                raise LivoxVizError(f"--out {self.path.parent}: cannot write its lock {self.path} "
                                    f"({os_error_reason(error)}); nothing was run") from None
            self._held = True
            return
        self.refuse_if_held()
        raise UsageError(f"--out {self.path.parent}: its lock {self.path} keeps changing (batches started at once?); "
                         "allowed: one batch at a time in a folder")

    def _take_stale(self) -> None:
        """Move a stale lock aside (a rename: another batch taking it too finds it gone) and keep its jobs."""
        aside = self.path.with_name(f"{LOCK}.{os.getpid()}.stale")
        try:
            os.replace(self.path, aside)
        except FileNotFoundError:
            return
        except OSError as error:
            raise UsageError(f"--out {self.path.parent}: cannot take over the stale lock {self.path} "
                             f"({error.strerror}); allowed: remove it") from None
        try:
            running = json.loads((read_own_file(aside) or b"{}").decode("utf-8")).get("running", [])
            self.left_running = [name for name in running if isinstance(name, str)]
        except (OSError, ValueError, AttributeError, TypeError, RecursionError):
            pass
        try:
            aside.unlink(missing_ok=True)
        except IsADirectoryError:  # a folder named as the lock: moved aside, then removed if empty
            with suppress(OSError):
                aside.rmdir()
        except OSError:
            pass

    def _text(self) -> str:
        return json.dumps({"pid": os.getpid(), "process_start": self._process_start,
                           "host": socket.gethostname(), "started": self._started,
                           "running": sorted(self.running)}) + "\n"

    def save(self) -> None:
        """Write the jobs in flight into the lock when they changed (a hint for a rerun after a kill: a write
        refused, as Windows refuses to replace a file another process has open, is tried again at the next)."""
        if not self._held or self._written == self.running:
            return
        try:
            write_text_atomic(self.path, self._text())
            self._written = frozenset(self.running)
        except (OSError, LivoxVizError):
            pass

    def release(self) -> None:
        if self._held:
            self.path.unlink(missing_ok=True)
            self._held = False


# Where the jobs run ------------------------------------------------------------------------------------
def _bounded(jobs: Iterator[Job], limit: int, submit: Callable[[Job], None],
             finished: Callable[[], list[dict[str, Any]]]) -> Iterator[dict[str, Any] | None]:
    """Hand jobs out as they are taken, at most ``limit`` of them handed out and not yet ended; yield each
    record ``finished()`` gives back (it waits a moment), None when it gave none."""
    flying = 0
    taken_all = False
    while True:
        while not taken_all and flying < limit:
            job = next(jobs, None)
            if job is None:
                taken_all = True
            else:
                submit(job)
                flying += 1
        if not flying:
            return
        records = finished()
        if not records:
            yield None
        for record in records:
            flying -= 1
            yield record


class LocalRunner:
    """Jobs on a pool of ``processes`` local processes, each job's scan on ``cores // processes`` workers.

    Jobs are taken from their iterator as they are handed out, at most two a process in flight (one running, one
    queued so no process waits for the batch): a grid of millions of jobs is never held.
    """

    def __init__(self, processes: int) -> None:
        self.processes = processes
        self.in_flight = 2 * processes
        self.where = f"a local pool of {_count(processes, 'process')}"
        self._pool: Any = None
        self._workers: dict[int, Any] = {}  # every worker process the pool has had, by process id

    def run(self, jobs: Iterator[Job], root: Path, workers: int | None) -> Iterator[dict[str, Any] | None]:
        """Each job's record as it ends (None every 0.2 s meanwhile: a chance to notice a stop)."""
        import queue

        per_job = workers or max(1, usable_cores() // self.processes)
        done: queue.Queue = queue.Queue()

        def submit(job: Job) -> None:
            if self._pool is None:  # made for the first job only: a rerun with nothing left starts no process
                # spawn: workers start from a clean interpreter (the batch's own threads are not forked half-held).
                self._pool = multiprocessing.get_context("spawn").Pool(self.processes,
                                                                       initializer=_local_worker_start)
            self._pool.apply_async(run_job, (job, str(root), per_job), callback=done.put,
                                   error_callback=lambda error, job=job: done.put(_lost(job, error)))

        def finished() -> list[dict[str, Any]]:
            try:
                return [done.get(timeout=0.2)]
            except queue.Empty:
                self._check_workers()
                return []

        yield from _bounded(jobs, self.in_flight, submit, finished)
        if self._pool is not None:
            self._pool.close()
            self._pool.join()

    def _check_workers(self) -> None:
        """Raise when a worker of the pool died on its own (a signal, the system's out-of-memory killer): the pool
        starts another in its place but the job it ran is lost, and the batch waited for its result for ever (a
        test run hung that way). Its jobs have no record, so a rerun runs them."""
        pool = self._pool
        if pool is None:
            return
        for worker in list(getattr(pool, "_pool", ())):
            self._workers.setdefault(worker.pid, worker)
        for pid, worker in self._workers.items():
            code = worker.exitcode
            if code is not None and code != 0:
                how = f"killed by {signal_name(-code)}" if code < 0 else f"exit status {code}"
                raise LivoxVizError(f"batch: a process of the local pool (process {pid}) died ({how}) while it ran "
                                    "a job; the jobs in flight did not finish: run the batch again to run them")

    def stop(self) -> None:
        """Kill the workers and the pool (the batch then removes the temporaries of the jobs they were writing).

        The pool's own handler starts a new worker for each one that dies, so it is stopped first: a worker it
        started after the kill took ``terminate``'s SIGTERM as a scan takes one (stop after the frame in hand),
        then waited for ever on the task queue's lock that ``terminate`` holds while it drains the queue, and the
        batch hung joining it (issue 47: a full disk during a local batch; CI's suite hung the same way).
        """
        pool = self._pool
        if pool is None:
            return
        handler = getattr(pool, "_worker_handler", None)
        if handler is not None:
            handler._state = multiprocessing.pool.TERMINATE
            pool._change_notifier.put(None)
            handler.join(timeout=10)
        for worker in list(getattr(pool, "_pool", ())) or multiprocessing.active_children():
            worker.kill()
            worker.join(timeout=10)
        # A worker killed while it held a queue's lock holds it for ever; terminate takes both.
        _free_if_its_holder_died(getattr(pool._outqueue, "_wlock", None))
        _free_if_its_holder_died(getattr(pool._inqueue, "_rlock", None))
        pool.terminate()
        pool.join()


def _free_if_its_holder_died(lock) -> None:
    """Free the pool's result-queue lock if a killed worker held it: killed while it put a result, it held the lock
    for ever, and ``Pool.terminate`` (which puts its own sentinel there) waited on it: a stopped batch hung (once in
    CI). Not taken within a second, its holder is dead: a multiprocessing lock may be released by any process."""
    if lock is None:  # Windows' queues have none
        return
    lock.acquire(timeout=1.0)  # taken (then given back) or not (then its dead holder's): either way released
    lock.release()


@contextmanager
def _workers_ignore_interrupts() -> Iterator[None]:
    """Ctrl-C ignored while a LocalCluster spawns its worker processes, which keep it ignored (an ignored signal
    stays so through exec, and their event loops then take no Ctrl-C of their own): a terminal's Ctrl-C reaches
    every process of its group, and each worker printed its KeyboardInterrupt's traceback while the batch stopped
    them itself. Only the main thread may set a handler; elsewhere nothing changes."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.getsignal(signal.SIGINT)
    _ignore_interrupts()
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def _restore_environment(saved: dict[str, str]) -> None:
    """Make ``os.environ`` equal ``saved`` again (variables added since removed, changed ones put back)."""
    for name in set(os.environ) - set(saved):
        del os.environ[name]
    for name, value in saved.items():
        if os.environ.get(name) != value:
            os.environ[name] = value


class DaskRunner:
    """Jobs on Dask distributed: a scheduler's address, or ``local:N`` for a ``LocalCluster`` of N processes."""

    def __init__(self, address: str, jobs: int | None = None) -> None:
        try:
            from distributed import Client, LocalCluster
        except ImportError:
            raise UsageError(f"--dask {address}: Dask distributed is not installed; allowed: pip install "
                             "'livox-viz[cluster]', or no --dask (a local pool of processes)") from None
        self.address = address
        self._cluster = None
        if address.startswith("local:"):
            count = address.removeprefix("local:")
            if not count.isdigit() or not 1 <= int(count) <= 1024:
                raise UsageError(f"--dask {address}: allowed: local:N with N from 1 to 1024 processes, or a "
                                 "scheduler's address such as tcp://HOST:8786")
            self.processes = int(count)
            # Dask's nannies set their workers' variables (one BLAS thread, MALLOC_TRIM_THRESHOLD_) in this
            # process's own environment as they spawn them, where every later child would inherit them: a fit
            # launched afterwards by the same program ran four times slower.
            saved = dict(os.environ)
            try:
                with _workers_ignore_interrupts():
                    # Errors only from Dask's own loggers: stopped by Ctrl-C, each worker closing with a job in hand
                    # said "Async instruction ... ended with CancelledError" and its nanny "Worker process still
                    # alive after 4.0 seconds, killing", under the batch's one line.
                    # No dashboard, and the scheduler's own HTTP server on any free port: on 8787, the dashboard's,
                    # it warned "Port 8787 is already in use" next to a user's own Dask.
                    self._cluster = LocalCluster(n_workers=self.processes, threads_per_worker=1, processes=True,
                                                 dashboard_address=None, scheduler_kwargs={"dashboard_address": ":0"},
                                                 silence_logs=logging.ERROR)
            finally:
                _restore_environment(saved)
            self.client = Client(self._cluster)
            self.where = f"a Dask LocalCluster of {_count(self.processes, 'process')}"
        else:
            self.client = _connect(address)
            self.processes = max(1, len(self.client.scheduler_info().get("workers", {})))
            self.where = f"the Dask scheduler at {address}"
        # --jobs: at most that many jobs handed to the cluster at once (a share of a cluster others use too);
        # else enough that every worker finds work, and an adaptive cluster (which scales on the tasks it is
        # given) sees the batch's demand.
        self.in_flight = jobs or max(DASK_IN_FLIGHT, 2 * self.processes)
        if jobs is not None:
            self.where += f", at most {_count(jobs, 'job')} at once"
        self._futures: dict[Any, Job] = {}

    def run(self, jobs: Iterator[Job], root: Path, workers: int | None) -> Iterator[dict[str, Any] | None]:
        """Each job's record as it ends (None every 0.2 s meanwhile: a chance to notice a stop)."""
        from distributed import wait

        per_job = workers
        if per_job is None and self._cluster is not None:
            per_job = max(1, usable_cores() // self.processes)

        def submit(job: Job) -> None:
            future = self.client.submit(run_job, job, str(root), per_job, key=f"livox-viz-{job.name}", pure=False)
            self._futures[future] = job

        def finished() -> list[dict[str, Any]]:
            try:
                ended, _ = wait(list(self._futures), timeout=0.2, return_when="FIRST_COMPLETED")
            except TimeoutError:
                return []
            records = []
            for future in ended:
                job = self._futures.pop(future)
                try:
                    records.append(future.result())
                except Exception as error:  # a worker lost: the job failed, the others go on
                    records.append(_lost(job, error))
            return records

        yield from _bounded(jobs, self.in_flight, submit, finished)

    def stop(self) -> None:
        if self._futures:
            self.client.cancel(list(self._futures))
        self.close()

    def close(self) -> None:
        self.client.close()
        if self._cluster is not None:
            self._cluster.close()


def _connect(address: str):
    """A Dask client of the scheduler at ``address``, or one line saying why not within about CONNECT_SECONDS.

    The client is made on a thread of its own and waited for with a deadline: distributed's own timeout covers
    the connection only, and something that accepts it but never answers as a scheduler (a web server, the
    dashboard's port, a firewall's proxy) held ``Client()`` in its handshake for ever. What such a peer sends
    back fails in ways of its own (a length read from an HTTP reply asked for exabytes, a tls:// address
    without a certificate raised TypeError): every failure here is the address's, said in one line.
    """
    import threading

    from distributed import Client

    made: dict[str, Any] = {}

    def connect() -> None:
        try:
            made["client"] = Client(address, timeout=f"{CONNECT_SECONDS:g}s")
        except Exception as error:
            made["error"] = error

    allowed = "allowed: a running Dask scheduler's address (tcp://HOST:8786) or local:N"
    thread = threading.Thread(target=connect, name="livox-viz dask connect", daemon=True)
    thread.start()
    thread.join(CONNECT_SECONDS + 5.0)
    if thread.is_alive():
        raise UsageError(f"--dask {address}: no Dask scheduler answered within {CONNECT_SECONDS:g} s (something "
                         f"accepts connections there but does not answer as one); {allowed}")
    error = made.get("error")
    if error is None:
        return made["client"]
    line = (str(error).splitlines() or [""])[0]
    if isinstance(error, OSError | TimeoutError | ValueError):
        raise UsageError(f"--dask {address}: cannot reach the scheduler ({line:.120}); {allowed}")
    raise UsageError(f"--dask {address}: no Dask scheduler this can use there ({type(error).__name__}: {line:.120}); "
                     f"{allowed}")


def _lost(job: Job, error: BaseException) -> dict[str, Any]:
    """The record of a job whose worker went away (or whose task could not run)."""
    return {"job": job.name, **job.parameters(), "status": "failed", "frames": 0, "points": 0, "duration_s": 0.0,
            "files": {}, "error": f"its worker failed: {type(error).__name__}: {error}"}


# The command ------------------------------------------------------------------------------------------
def cmd_batch(args: argparse.Namespace) -> int:
    if args.example:
        print(EXAMPLE, end="")
        return 0
    if not args.spec or not args.out:
        raise UsageError("give SPEC and --out DIR (or --example for a spec to start from)")
    grid = read_spec(args.spec, force=args.force)
    spec = Path(args.spec).name
    root = _check_out(Path(args.out))
    lock = BatchLock(root)
    lock.refuse_if_held()
    manifest = Manifest(root, grid, spec)
    manifest.read()
    runner = DaskRunner(args.dask, args.jobs) if args.dask else None
    try:
        (root / "jobs").mkdir(parents=True, exist_ok=True)
        lock.acquire()
    except BaseException:
        if runner is not None:
            runner.close()
        raise
    try:
        return _run(args, grid, spec, root, lock, manifest, runner)
    finally:
        lock.release()


def _run(args: argparse.Namespace, grid: Grid, spec: str, root: Path, lock: BatchLock, manifest: Manifest,
         runner: LocalRunner | DaskRunner | None) -> int:
    """The batch, holding its folder's lock: the rows of jobs a killed run left in flight, then every job not
    finished taken from the grid as the runner has room for it."""
    manifest.open()
    try:
        for name in lock.left_running:
            if manifest.previous(name) is None:
                record = finished_record(root, name)
                if record is not None and grid.place_of(name, record) is not None:
                    manifest.append(record, again=True)
        kept = manifest.done + (0 if args.retry else manifest.failed)
        # A grid of at most MAX_JOBS is checked job by job before the first line: a job the manifest counts whose
        # files went or whose inputs changed runs again, and was counted as finished in the opening line, in the
        # size of the pool (24 such jobs ran on a pool of one process) and in the progress lines (issue 47).
        stale, stale_points = _no_longer_finished(grid, root, manifest, args.retry) if grid.total <= MAX_JOBS \
            else (None, 0)
        kept -= stale or 0
        to_run = grid.total - kept
        workers = dict(grid.options).get("workers_per_job")
        if runner is None:
            runner = LocalRunner(min(args.jobs or usable_cores(), max(1, to_run)))
        retried = f", {_count(manifest.failed, 'failed one')} again" if args.retry and manifest.failed else ""
        earlier = (f" ({manifest.failed:,} failed: --retry runs {'it' if manifest.failed == 1 else 'them'} again)"
                   if manifest.failed and not args.retry else "")
        print(f"batch: {_count(grid.total, 'job')} from {spec}: {kept:,} already finished{earlier}{retried}; "
              f"{to_run:,} to run on {runner.where}", file=sys.stderr)
        say = _Say(grid.total, kept, manifest.points - stale_points)
        failures: list[dict[str, Any]] = []
        stopped = None
        stopped_by_error = False
        try:
            with StopRequests() as stop:
                todo = _todo(grid, root, manifest, args.retry, say, failures, lock, stop, rechecked=stale is not None)
                for record in runner.run(todo, root, workers):
                    if record is not None:
                        lock.running.discard(record["job"])
                        if record["status"] != "stopped":  # a stopped job has not finished: it runs again
                            manifest.append(record)
                        if record["status"] == "failed" and len(failures) < SHOWN_FAILURES:
                            failures.append(record)
                        say.finished(record)
                    lock.save()
                    if stop.requested:
                        break
                if stop.requested:  # also when it came while finished jobs were being skipped
                    stopped = stop.signum
                    runner.stop()
                    if isinstance(runner, LocalRunner):
                        _remove_killed_temporaries(root, lock.running)
        except BaseException:
            # A failure of the batch itself (a full disk under the manifest): its workers are killed here, not
            # left to the pool's own finaliser at exit, whose SIGTERM a worker took as a scan takes one and which
            # then waited on it for ever (issue 47: the batch hung on a full disk).
            if stopped is None:
                stopped_by_error = True
                runner.stop()
                if isinstance(runner, LocalRunner):
                    _remove_killed_temporaries(root, lock.running)
            raise
        finally:
            if isinstance(runner, DaskRunner) and stopped is None and not stopped_by_error:
                runner.close()
            if stopped_by_error:  # the failure is what the user is told, not a tidy that failed after it
                with suppress(OSError, LivoxVizError):
                    manifest.tidy()
            else:
                manifest.tidy()
    finally:
        manifest.close()
    summary = (f"{manifest.done:,} of {_count(grid.total, 'job')} done, {manifest.failed:,} failed, "
               f"{_count(manifest.points, 'point')}; manifest {manifest.path}")
    if stopped is not None:
        print(f"{PROG}: batch stopped by {signal_name(stopped)}: {summary}; run it again to finish the rest",
              file=sys.stderr)
        return signal_status(stopped)
    print(f"batch: {summary}")
    for record in failures:
        print(f"{PROG}: batch: job {record['job']} failed: {record['error']}", file=sys.stderr)
    return 1 if manifest.failed else 0


def _remove_killed_temporaries(root: Path, names: set[str]) -> None:
    """The temporaries of the jobs the local pool's killed workers were writing (a work folder may hold gigabytes):
    stopped by Ctrl-C, the batch leaves no half-written file behind, not only until the next run. Their processes
    are gone, so :func:`remove_dead_leftovers` takes them; a Dask worker's (another host's) are not touched."""
    for name in names:
        remove_dead_leftovers(root / "jobs" / name)


def _no_longer_finished(grid: Grid, root: Path, manifest: Manifest, retry: bool) -> tuple[int, int]:
    """The jobs the manifest counts as finished whose own records no longer say so (files gone, inputs changed),
    and the points the manifest counts for them: they run again."""
    stale = points = 0
    for job in grid:
        previous = manifest.previous(job.name)
        if previous is None or not (previous[0] == "done" or not retry):
            continue
        record = finished_record(root, job.name)
        if record is None or (retry and record["status"] != "done"):
            stale += 1
            points += previous[1] if previous[0] == "done" else 0
    return stale, points


def _todo(grid: Grid, root: Path, manifest: Manifest, retry: bool, say: _Say, failures: list[dict[str, Any]],
          lock: BatchLock, stop: StopRequests, rechecked: bool = False) -> Iterator[Job]:
    """The grid's jobs to run, named one at a time as the runner takes them; a stop ends them.

    A job is finished when its own record says so (its files all there), whatever the manifest says: one whose
    files went is run again, one finished whose row a killed batch never wrote gets its row now. ``rechecked``:
    :func:`_no_longer_finished` has already taken the jobs that run again out of the count of finished ones.
    """
    for job in grid:
        if stop.requested:
            return
        name = job.name
        previous = manifest.previous(name)
        counted = previous is not None and (previous[0] == "done" or not retry)
        record = finished_record(root, name)
        if record is not None and (record["status"] == "done" or not retry):
            if previous is None or previous[0] != record["status"]:
                # Its points count in the progress lines too (they said fewer than the summary after a killed run).
                before = manifest.points
                manifest.append(record)
                say.points += manifest.points - before
            say.kept += not counted
            if record["status"] == "failed" and len(failures) < SHOWN_FAILURES:
                failures.append(record)
            continue
        if not rechecked:
            say.kept -= counted
        lock.running.add(name)
        yield job


def _check_out(out: Path) -> Path:
    """The batch's folder (made later, if needed): refused when it is a file or cannot be made or written, or
    when what the batch writes in it (``jobs/``, ``manifest.csv``) could not be written there.

    A folder with no write bit at all is refused even to root, as the files' own atomic writes refuse it
    (:func:`~livox_viz.core.atomic.resolve_destination`): checked here, or the jobs ran and the manifest was
    refused at the end.
    """
    if out.exists() and not out.is_dir():
        raise UsageError(f"--out {out}: is a file; allowed: a folder (made if needed) for the jobs and the manifest")
    existing = next(folder for folder in (out.absolute(), *out.absolute().parents) if folder.exists())
    if not existing.is_dir() or not os.access(existing, os.W_OK) or not existing.stat().st_mode & 0o222:
        raise UsageError(f"--out {out}: {existing} is not a writable folder; allowed: a folder this user can write")
    jobs = out / "jobs"
    if os.path.lexists(jobs) and not jobs.is_dir():
        raise UsageError(f"--out {out}: {jobs} is not a folder; allowed: a folder whose jobs/ (made if needed) is "
                         "the batch's folder of jobs")
    if out.is_dir():
        try:
            resolve_destination(out / MANIFEST)
        except LivoxVizError as error:
            raise UsageError(f"--out {out}: the manifest cannot be written there ({error})") from None
    return out


def _check_same_batch(out: Path, grid: Grid, spec: str) -> None:
    """Refuse a folder whose manifest is another batch's (it lists jobs this spec does not make) or not a batch
    manifest at all: the run would append to it, mixing two batches' records.

    A spec grown since (more seeds) keeps its folder: all the jobs its manifest lists are still the spec's.
    """
    Manifest(out, grid, spec).read()


class _Say:
    """A line on stderr as each job ends: how many are done of the grid's, the points, the time left."""

    def __init__(self, total: int, kept: int, points: int) -> None:
        self.total = total
        self.kept = kept
        self.ran = 0
        self.failed = 0
        self.points = points
        self.start = time.monotonic()

    def finished(self, record: dict[str, Any]) -> None:
        self.ran += 1
        ended = self.kept + self.ran
        if record["status"] == "done":
            self.points += int(record["points"])
            what = f"done {record['job']} ({_count(int(record['points']), 'point')}, {record['duration_s']:.1f} s)"
        elif record["status"] == "stopped":
            what = f"stopped {record['job']} (it runs again next time)"
        else:
            self.failed += 1
            what = f"FAILED {record['job']}: {record['error']}"
        elapsed = time.monotonic() - self.start
        left = elapsed / self.ran * max(0, self.total - ended)
        print(f"batch: [{ended:,}/{self.total:,}] {what}; {self.failed:,} failed, {_count(self.points, 'point')}, "
              f"about {_clock(left)} left", file=sys.stderr, flush=True)


def _count(number: int, noun: str) -> str:
    """``1 job``, ``2 jobs``, ``1,000 processes``."""
    if number == 1:
        return f"1 {noun}"
    return f"{number:,} {noun}{'es' if noun.endswith('ss') else 's'}"


def _clock(seconds: float) -> str:
    seconds = round(seconds)
    return f"{seconds // 3600}:{seconds // 60 % 60:02d}:{seconds % 60:02d}" if seconds >= 3600 else (
        f"{seconds // 60}:{seconds % 60:02d}")


def _batch_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("spec", nargs="?", help="the batch spec, TOML (or JSON named *.json)")
    parser.add_argument("--out", help="folder for the jobs (OUT/jobs/<job>/) and OUT/manifest.csv; made if needed")
    parser.add_argument("--dask", metavar="ADDRESS|local:N",
                        help="run on Dask distributed: a scheduler's address (tcp://HOST:8786) or local:N (a "
                             "LocalCluster of N processes); needs pip install 'livox-viz[cluster]'. Default: a "
                             "local pool of processes")
    parser.add_argument("--jobs", type=whole_number(1, 1024, "1 to 1024 jobs"),
                        help="jobs at once: the local pool's processes (default: one per core this process may "
                             "use); with --dask, the jobs handed to the cluster at once (default: enough for every "
                             "worker)")
    parser.add_argument("--retry", action="store_true", help="run the jobs that failed before again")
    parser.add_argument("--force", action="store_true",
                        help="allow more jobs than 10,000, and jobs of more points than a scan's budget")
    parser.add_argument("--example", action="store_true", help="print a small spec that runs as it is, and stop")


COMMANDS: tuple[Command, ...] = (
    Command("batch", cmd_batch, "run a grid of scans (sensors x scenes x trajectories x seeds x returns x outputs) "
            "as resumable jobs, locally or on Dask",
            "livox-viz batch --example > spec.toml && livox-viz batch spec.toml --out runs/", _batch_arguments),
)

__all__ = ["COMMANDS", "BatchLock", "DaskRunner", "LocalRunner", "Manifest", "SpecError", "cmd_batch",
           "finished_record", "run_job"]
