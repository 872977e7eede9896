"""``batch``: a grid of scans run as jobs, on a local pool of processes or a Dask cluster, resumable.

Every job (:mod:`~livox_viz.cli.batch_spec`) is a normal ``scan`` (:func:`run_job`)
into a folder of its own, ``OUT/jobs/<job>/``, whose files are written atomically
as ``scan`` writes them; its record (parameters, outputs with their sizes and
SHA-256, frames, points, duration, or its error) goes last into ``job.json``
beside them, and the records make ``OUT/manifest.csv``. A job whose record says
done and whose files are there is not run again, so a batch stopped half-way
(Ctrl-C, a killed process, a lost node) is finished by running it again; a
failed job is reported with its error, does not stop the others, and runs again
with ``--retry``.

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
import multiprocessing
import os
import shutil
import signal
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from livox_viz.core.atomic import resolve_destination, write_text_atomic
from livox_viz.core.errors import LivoxVizError
from livox_viz.core.portable import usable_cores
from livox_viz.files.export import sidecar_path

from .batch_spec import EXAMPLE, Job, SpecError, read_spec, scan_argv
from .common import PROG, Command, UsageError, whole_number
from .signals import StopRequests, signal_name, signal_status

#: The batch's record in its folder, and its columns, one row a job in the spec's order.
MANIFEST = "manifest.csv"
MANIFEST_COLUMNS = ("job", "status", "sensor", "scene", "trajectory", "seed", "returns", "outputs", "seconds",
                    "frames", "points", "duration_s", "files", "error")
#: Seconds a batch waits for a Dask scheduler to answer.
CONNECT_SECONDS = 10.0


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
                digest = hashlib.sha256()
                with open(file, "rb") as handle:
                    while block := handle.read(1 << 20):
                        digest.update(block)
                found[str(file.relative_to(folder))] = {"bytes": file.stat().st_size, "sha256": digest.hexdigest()}
    return found


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


# Records and the manifest ----------------------------------------------------------------------------
def finished_record(root: Path, job: Job) -> dict[str, Any] | None:
    """The job's record from an earlier run, when its files are all there with their sizes (else None)."""
    path = root / "jobs" / job.name / "job.json"
    try:
        record = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(record, dict) or record.get("job") != job.name:
        return None
    if record.get("status") == "done":
        for name, about in record.get("files", {}).items():
            file = root / "jobs" / job.name / name
            if not file.is_file() or file.stat().st_size != about.get("bytes"):
                return None
    return record


def write_manifest(root: Path, jobs: list[Job], records: dict[str, dict[str, Any]]) -> Path:
    """``root/manifest.csv``: one row a job, in the spec's order (``pending`` for one not run yet)."""
    text = io.StringIO()
    table = csv.writer(text, lineterminator="\n")
    table.writerow(MANIFEST_COLUMNS)
    for job in jobs:
        record = records.get(job.name) or {"job": job.name, **job.parameters(), "status": "pending"}
        files = " ".join(f"{name}:{about['sha256']}" for name, about in record.get("files", {}).items())
        table.writerow([record.get("job"), record.get("status"), record.get("sensor"), record.get("scene"),
                        record.get("trajectory"), record.get("seed"), record.get("returns"), record.get("outputs"),
                        record.get("seconds"), record.get("frames", ""), record.get("points", ""),
                        record.get("duration_s", ""), files, record.get("error", "")])
    path = root / MANIFEST
    write_text_atomic(path, text.getvalue())
    return path


# Where the jobs run ------------------------------------------------------------------------------------
class LocalRunner:
    """Jobs on a pool of ``processes`` local processes, each job's scan on ``cores // processes`` workers."""

    def __init__(self, processes: int) -> None:
        self.processes = processes
        self.where = f"a local pool of {processes} process" + ("" if processes == 1 else "es")
        self._pool = None

    def run(self, jobs: list[Job], root: Path, workers: int | None) -> Iterator[dict[str, Any]]:
        import queue

        per_job = workers or max(1, usable_cores() // self.processes)
        done: queue.Queue = queue.Queue()
        # spawn: workers start from a clean interpreter (the batch's own threads are not forked half-held).
        self._pool = multiprocessing.get_context("spawn").Pool(self.processes, initializer=_ignore_interrupts)
        for job in jobs:
            self._pool.apply_async(run_job, (job, str(root), per_job), callback=done.put,
                                   error_callback=lambda error, job=job: done.put(_lost(job, error)))
        self._pool.close()
        for _ in jobs:
            while True:
                try:
                    yield done.get(timeout=0.2)
                    break
                except queue.Empty:
                    yield None  # a chance to notice a stop
        self._pool.join()

    def stop(self) -> None:
        """Kill the workers (their jobs' temporaries go at the next run in those folders) and the pool."""
        if self._pool is not None:
            for worker in multiprocessing.active_children():
                worker.kill()
            self._pool.terminate()
            self._pool.join()


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

    def __init__(self, address: str) -> None:
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
                    self._cluster = LocalCluster(n_workers=self.processes, threads_per_worker=1, processes=True,
                                                 dashboard_address=None)
            finally:
                _restore_environment(saved)
            self.client = Client(self._cluster)
            self.where = f"a Dask LocalCluster of {self.processes} process" + ("" if self.processes == 1 else "es")
        else:
            self.client = _connect(address)
            self.processes = max(1, len(self.client.scheduler_info().get("workers", {})))
            self.where = f"the Dask scheduler at {address}"
        self._futures: list = []

    def run(self, jobs: list[Job], root: Path, workers: int | None) -> Iterator[dict[str, Any]]:
        from distributed import wait

        per_job = workers
        if per_job is None and self._cluster is not None:
            per_job = max(1, usable_cores() // self.processes)
        self._futures = [self.client.submit(run_job, job, str(root), per_job, key=f"livox-viz-{job.name}",
                                            pure=False) for job in jobs]
        by_key = {future.key: job for future, job in zip(self._futures, jobs, strict=True)}
        remaining = set(self._futures)
        while remaining:
            try:
                finished, remaining = wait(remaining, timeout=0.2, return_when="FIRST_COMPLETED")
            except TimeoutError:
                yield None  # a chance to notice a stop
                continue
            for future in finished:
                try:
                    yield future.result()
                except Exception as error:  # a worker lost: the job failed, the others go on
                    yield _lost(by_key[future.key], error)

    def stop(self) -> None:
        if self._futures:
            self.client.cancel(self._futures)
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
    jobs = read_spec(args.spec, force=args.force)
    root = _check_out(Path(args.out))
    _check_same_batch(root, jobs, Path(args.spec).name)
    runner = DaskRunner(args.dask) if args.dask else None
    (root / "jobs").mkdir(parents=True, exist_ok=True)
    records: dict[str, dict[str, Any]] = {}
    todo: list[Job] = []
    kept = retried = 0
    for job in jobs:
        record = finished_record(root, job)
        if record is not None and (record["status"] == "done" or not args.retry):
            records[job.name] = record
            kept += 1
        else:
            retried += record is not None
            todo.append(job)
    workers = dict(jobs[0].options).get("workers_per_job") if jobs else None
    runner = runner or LocalRunner(min(args.jobs or usable_cores(), max(1, len(todo))))
    earlier_failed = sum(1 for r in records.values() if r["status"] == "failed")
    say = _Say(len(jobs), kept, records)
    print(f"batch: {len(jobs)} jobs from {Path(args.spec).name}: {kept} already finished"
          + (f" ({earlier_failed} failed: --retry runs them again)" if earlier_failed else "")
          + (f", {retried} failed ones again" if retried else "") + f"; {len(todo)} to run on {runner.where}",
          file=sys.stderr)
    stopped = None
    last_manifest = time.monotonic()
    try:
        with StopRequests() as stop:
            for record in runner.run(todo, root, workers) if todo else ():
                if record is not None:
                    records[record["job"]] = record
                    say.finished(record)
                    if time.monotonic() - last_manifest > 2.0:
                        write_manifest(root, jobs, records)
                        last_manifest = time.monotonic()
                if stop.requested:
                    stopped = stop.signum
                    runner.stop()
                    break
    finally:
        if isinstance(runner, DaskRunner) and stopped is None:
            runner.close()
        manifest = write_manifest(root, jobs, records)
    done = sum(1 for r in records.values() if r["status"] == "done")
    failed = [r for r in records.values() if r["status"] == "failed"]
    points = sum(int(r.get("points") or 0) for r in records.values() if r["status"] == "done")
    summary = (f"{done} of {len(jobs)} jobs done, {len(failed)} failed, {points:,} points; manifest {manifest}")
    if stopped is not None:
        print(f"{PROG}: batch stopped by {signal_name(stopped)}: {summary}; run it again to finish the rest",
              file=sys.stderr)
        return signal_status(stopped)
    print(f"batch: {summary}")
    for record in failed[:20]:
        print(f"{PROG}: batch: job {record['job']} failed: {record['error']}", file=sys.stderr)
    return 1 if failed else 0


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


def _check_same_batch(out: Path, jobs: list[Job], spec: str) -> None:
    """Refuse a folder whose manifest is another batch's (it lists jobs this spec does not make) or not a batch
    manifest at all: the run would replace it with this spec's, and that batch's record of its jobs was lost.

    A spec grown since (more seeds) keeps its folder: all the jobs its manifest lists are still the spec's.
    """
    path = out / MANIFEST
    if not path.is_file():
        return
    try:
        with open(path, newline="", encoding="utf-8") as handle:
            rows = csv.reader(handle)
            header = next(rows, None)
            if header is None or "job" not in header:
                raise ValueError("no job column")
            column = header.index("job")
            listed = [row[column] for row in rows if len(row) > column]
    except (OSError, UnicodeDecodeError, csv.Error, ValueError):
        raise UsageError(f"--out {out}: holds a manifest.csv that is not a batch's manifest; allowed: a folder of "
                         "this spec's batch (to finish it) or a new one (it is not replaced)") from None
    names = {job.name for job in jobs}
    others = [name for name in listed if name not in names]
    if others:
        raise UsageError(f"--out {out}: holds another batch's manifest ({len(others):,} of its jobs, e.g. "
                         f"{others[0]}, are not jobs of {spec}); allowed: this spec's own folder (to finish it) or a "
                         "new one (it is not replaced)")


class _Say:
    """A line on stderr as each job ends: how many are done, the points, the time left."""

    def __init__(self, total: int, kept: int, records: dict[str, dict[str, Any]]) -> None:
        self.total = total
        self.kept = kept
        self.ran = 0
        self.failed = 0
        self.points = sum(int(r.get("points") or 0) for r in records.values() if r["status"] == "done")
        self.start = time.monotonic()

    def finished(self, record: dict[str, Any]) -> None:
        self.ran += 1
        ended = self.kept + self.ran
        if record["status"] == "done":
            self.points += int(record["points"])
            what = f"done {record['job']} ({int(record['points']):,} points, {record['duration_s']:.1f} s)"
        elif record["status"] == "stopped":
            what = f"stopped {record['job']} (it runs again next time)"
        else:
            self.failed += 1
            what = f"FAILED {record['job']}: {record['error']}"
        elapsed = time.monotonic() - self.start
        left = elapsed / self.ran * (self.total - ended)
        print(f"batch: [{ended}/{self.total}] {what}; {self.failed} failed, {self.points:,} points, about "
              f"{_clock(left)} left", file=sys.stderr, flush=True)


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
    parser.add_argument("--jobs", type=whole_number(1, 1024, "1 to 1024 processes"),
                        help="jobs at once on the local pool (default: one per core this process may use)")
    parser.add_argument("--retry", action="store_true", help="run the jobs that failed before again")
    parser.add_argument("--force", action="store_true",
                        help="allow more jobs than 10,000, and jobs of more points than a scan's budget")
    parser.add_argument("--example", action="store_true", help="print a small spec that runs as it is, and stop")


COMMANDS: tuple[Command, ...] = (
    Command("batch", cmd_batch, "run a grid of scans (sensors x scenes x trajectories x seeds x returns x outputs) "
            "as resumable jobs, locally or on Dask",
            "livox-viz batch --example > spec.toml && livox-viz batch spec.toml --out runs/", _batch_arguments),
)

__all__ = ["COMMANDS", "DaskRunner", "LocalRunner", "SpecError", "cmd_batch", "finished_record", "run_job",
           "write_manifest"]
