"""What differs between Windows, macOS and Linux, in one place.

livox-viz runs where RflySim's users are, most of them on Windows. Every
platform-only name of the standard library is reached here, looked up where the
platform has it (``getattr`` or a ``sys.platform`` test, so a static check for
``--platform win32`` or ``darwin`` finds nothing missing), with a fallback
where it does not:

* :func:`at_fork_in_child`: ``os.register_at_fork`` exists only where ``fork``
  does (not on Windows); without fork there is no child to repair.
* :func:`free_disk_bytes`: ``os.statvfs`` and ``os.geteuid`` are POSIX;
  elsewhere :func:`shutil.disk_usage` says what this user may write.
* :func:`process_alive`: ``os.kill(pid, 0)`` probes a process on POSIX, but on
  Windows signal 0 is ``CTRL_C_EVENT`` and any other number terminates the
  process: there the process is opened and asked whether it still runs.
* :func:`process_start`: when a process started (Linux's ``/proc``, Windows' ``GetProcessTimes``), so that a
  process id reused by another process is not taken for the one that wrote it down; None elsewhere.
* :func:`write_at`: ``os.pwrite`` is POSIX; a seek and a write do the same on a
  file object everywhere.
* :func:`path_in_file`: a path written inside a file (a scene's mesh) may come from
  Windows (``meshes\\car.glb``, ``C:\\models\\car.glb``) or from Linux.
* :func:`usable_cores`: ``os.process_cpu_count`` is Python 3.13's, ``os.sched_getaffinity`` Linux's; else every
  CPU of the machine.
* :func:`copy_in_kernel`: ``os.copy_file_range`` is Linux's; elsewhere the caller copies the bytes itself.
"""

from __future__ import annotations

import io
import os
import re
import shutil
import sys
from collections.abc import Callable
from pathlib import Path, PureWindowsPath
from typing import BinaryIO

from livox_viz.core.errors import LivoxVizError


def at_fork_in_child(callback: Callable[[], None]) -> None:
    """Call ``callback`` in a forked child (``os.register_at_fork``), where the platform can fork at all."""
    register = getattr(os, "register_at_fork", None)
    if register is not None:
        register(after_in_child=callback)


def usable_cores() -> int:
    """The CPUs this process may run on, at least 1: the one count every pool of the model starts from.

    ``os.process_cpu_count()`` where Python has it (3.13: it honours ``-X cpu_count`` and ``PYTHON_CPU_COUNT``),
    else the scheduler's affinity mask (``taskset``, a batch system's CPU set), else every CPU of the machine.
    A container's CPU quota (``docker --cpus``) is not a mask and is not seen; ``--workers`` sets the count by
    hand there.
    """
    counted = getattr(os, "process_cpu_count", None)
    if counted is not None:
        return max(1, counted() or 1)
    affinity = getattr(os, "sched_getaffinity", None)
    if affinity is not None:
        try:
            return max(1, len(affinity(0)))
        except OSError:
            pass
    return max(1, os.cpu_count() or 1)


def copy_in_kernel(source: int, destination: int, count: int, source_at: int, destination_at: int) -> int:
    """Copy up to ``count`` bytes between two open files' descriptors at those offsets without passing them
    through this process (``os.copy_file_range``: a reflink where the file system shares extents); returns the
    bytes copied, 0 where the platform or the files cannot (the caller copies the rest itself)."""
    copy = getattr(os, "copy_file_range", None)
    if copy is None:
        return 0
    try:
        return int(copy(source, destination, count, source_at, destination_at))
    except OSError:  # not between these files (another file system, an old kernel): the caller copies
        return 0


def free_disk_bytes(folder: str | os.PathLike[str]) -> int:
    """Bytes this process may still write on the disk holding ``folder``.

    On POSIX root may also use the blocks the file system keeps for it, as its writes will.
    """
    statvfs = getattr(os, "statvfs", None)
    geteuid = getattr(os, "geteuid", None)
    if statvfs is None or geteuid is None:
        return int(shutil.disk_usage(folder).free)
    status = statvfs(folder)
    blocks = status.f_bfree if geteuid() == 0 else status.f_bavail
    return int(blocks * status.f_frsize)


def process_alive(pid: int) -> bool:
    """Whether the process ``pid`` still runs (one we may not signal counts as running)."""
    if sys.platform == "win32":
        return _windows_process_alive(pid)
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return not _ended_unreaped(pid)


def _ended_unreaped(pid: int) -> bool:
    """Whether ``pid`` has ended but its parent has not reaped it yet (a zombie: state Z in Linux's /proc; False
    where there is no /proc). A batch killed with its workers leaves them so until init reaps them, and a rerun
    in the meantime kept their temporaries as a running process's (a CI run of the batch's kill test)."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as handle:
            stat = handle.read()
    except OSError:
        return False
    end = stat.rfind(b")")  # the command's name, in parentheses, may hold anything
    return stat[end + 2:end + 3] == b"Z"


def process_start(pid: int) -> str | None:
    """When process ``pid`` started, as a text that is the same for as long as it runs and differs for a later
    process given the same id; None where that cannot be told (no such process, macOS, no access).

    Linux: the boot's id and the start in clock ticks since boot (``/proc/PID/stat`` field 22). Windows: the
    creation time (``GetProcessTimes``, 100 ns since 1601).
    """
    if sys.platform == "win32":
        return _windows_process_start(pid)
    try:
        with open(f"/proc/{pid}/stat", "rb") as handle:
            stat = handle.read()
        with open("/proc/sys/kernel/random/boot_id", encoding="ascii") as handle:
            boot = handle.read().strip()
    except OSError:
        return None
    fields = stat[stat.rfind(b")") + 2:].split()  # fields 3 on (the name before them may hold anything)
    return f"{boot}:{int(fields[19])}" if len(fields) > 19 else None


if sys.platform == "win32":  # pragma: no cover - Windows only

    def _windows_process_start(pid: int) -> str | None:
        import ctypes

        query_limited_information = 0x1000
        kernel32 = ctypes.WinDLL("kernel32", use_last_error=True)
        handle = kernel32.OpenProcess(query_limited_information, False, pid)
        if not handle:
            return None
        try:
            times = [ctypes.c_ulonglong() for _ in range(4)]  # creation, exit, kernel, user (FILETIMEs)
            if not kernel32.GetProcessTimes(handle, *(ctypes.byref(t) for t in times)):
                return None
            return str(times[0].value)
        finally:
            kernel32.CloseHandle(handle)

    def _windows_process_alive(pid: int) -> bool:
        import ctypes

        query_limited_information, still_active, access_denied = 0x1000, 259, 5
        kernel32 = ctypes.WinDLL("kernel32", use_last_error=True)
        handle = kernel32.OpenProcess(query_limited_information, False, pid)
        if not handle:
            # Access denied: it exists and belongs to someone else; anything else (an invalid id): gone.
            return bool(ctypes.get_last_error() == access_denied)
        try:
            code = ctypes.c_ulong()
            if not kernel32.GetExitCodeProcess(handle, ctypes.byref(code)):
                return True
            return code.value == still_active
        finally:
            kernel32.CloseHandle(handle)


def write_at(file: BinaryIO | io.RawIOBase, data: bytes, offset: int) -> None:
    """Write ``data`` at byte ``offset`` of an open binary file and come back to where it was.

    ``os.pwrite`` does this on POSIX only; the file object's own seek flushes what it buffered first, so the
    bytes land exactly as pwrite's would.
    """
    position = file.tell()
    file.seek(offset)
    file.write(data)
    file.seek(position)


_WINDOWS_LOOKING = re.compile(r"^[A-Za-z]:|\\")


def path_in_file(text: str, folder: str | os.PathLike[str]) -> Path:
    """The file a path written inside a file means: relative to ``folder`` (the file's own), or absolute.

    On Windows both separators and drive letters are native. Elsewhere a Windows-style path (backslashes, a
    drive letter) written on Windows is read as Windows reads it: ``meshes\\car.glb`` is ``meshes/car.glb``
    beside the file; an absolute one (``C:\\models\\car.glb``) names a disk this system does not have and is
    refused in one line. A name that exists as written (a POSIX name may hold a backslash) is taken as written.

    Raises
    ------
    LivoxVizError
        For an absolute Windows path off Windows.
    """
    written = Path(folder) / text
    if sys.platform == "win32" or not _WINDOWS_LOOKING.search(text) or os.path.lexists(written):
        return written
    windows = PureWindowsPath(text)
    if windows.drive or windows.root:
        raise LivoxVizError(f"{text!r} is an absolute Windows path, which this system cannot open; allowed: a path "
                            "relative to the file that names it (e.g. meshes\\car.glb or meshes/car.glb), or one "
                            "absolute here")
    return Path(folder).joinpath(*windows.parts)
