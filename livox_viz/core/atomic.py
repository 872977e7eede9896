"""Writing files so that a user's file is never lost or half-written.

Everything is written to a temporary file (or work folder) in the
destination's folder and renamed over the destination only once it is
complete; on any failure the temporary is removed and the old file, if any, is
untouched. Temporaries are named ``.<name>.livox-viz-<pid>.part`` (or
``.work``), so a later run recognises what a killed run left behind (its
process is gone) and removes it.

A destination that is a symbolic link is written through: the link's target
is replaced and the link stays. An existing file keeps its permissions.
"""

from __future__ import annotations

import os
import re
import shutil
import stat
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from livox_viz.core.errors import LivoxVizError

_TAG = "livox-viz"
_LEFTOVER = re.compile(rf"^\..+\.{_TAG}-(\d+)\.[A-Za-z0-9_]+\.(part|work)$")


def _current_umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def remove_dead_leftovers(folder: str | os.PathLike[str]) -> list[Path]:
    """Remove the temporaries of livox-viz runs that no longer exist; returns what was removed."""
    removed = []
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return removed
    for entry in entries:
        match = _LEFTOVER.match(entry.name)
        if match is None or int(match.group(1)) == os.getpid() or _pid_alive(int(match.group(1))):
            continue
        path = Path(entry.path)
        if entry.is_dir(follow_symlinks=False):
            shutil.rmtree(path, ignore_errors=True)
        else:
            path.unlink(missing_ok=True)
        removed.append(path)
    return removed


def resolve_destination(path: str | os.PathLike[str]) -> Path:
    """The file really written for ``path``: a symbolic link's target; checks the folder exists."""
    path = Path(path)
    if path.is_symlink():
        path = Path(os.path.realpath(path))
    if path.is_dir():
        raise LivoxVizError(f"{path}: is a folder; allowed: a file name")
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise LivoxVizError(f"{path}: the folder {folder} does not exist")
    return path


def _temporary_prefix(path: Path) -> str:
    return f".{path.name}.{_TAG}-{os.getpid()}."


@contextmanager
def atomic_path(path: str | os.PathLike[str]) -> Iterator[Path]:
    """Yield a temporary path to write; on success it replaces ``path`` in one rename.

    Raises
    ------
    LivoxVizError
        If the destination is a folder, or its folder does not exist or is not writable.
    """
    path = resolve_destination(path)
    folder = path.parent
    remove_dead_leftovers(folder)
    try:
        fd, tmp_name = tempfile.mkstemp(prefix=_temporary_prefix(path), suffix=".part", dir=folder)
    except OSError as exc:
        raise LivoxVizError(f"{path}: cannot write in {folder} ({exc.strerror})") from None
    os.close(fd)
    tmp = Path(tmp_name)
    try:
        yield tmp
        try:
            mode = stat.S_IMODE(path.stat().st_mode)
        except FileNotFoundError:
            mode = 0o666 & ~_current_umask()
        os.chmod(tmp, mode)
        os.replace(tmp, path)
    except OSError as exc:
        raise LivoxVizError(f"{path}: cannot write ({exc.strerror or exc}); the old file, if any, is kept") from exc
    finally:
        tmp.unlink(missing_ok=True)


def make_work_dir(path: str | os.PathLike[str]) -> Path:
    """A temporary folder beside ``path`` for a writer's parts (the caller removes it)."""
    path = resolve_destination(path)
    remove_dead_leftovers(path.parent)
    try:
        return Path(tempfile.mkdtemp(prefix=_temporary_prefix(path), suffix=".work", dir=path.parent))
    except OSError as exc:
        raise LivoxVizError(f"{path}: cannot write in {path.parent} ({exc.strerror})") from None


def write_bytes_atomic(path: str | os.PathLike[str], data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file and a rename."""
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as handle:
            handle.write(data)
            handle.flush()
            os.fsync(handle.fileno())


def write_text_atomic(path: str | os.PathLike[str], text: str) -> None:
    """Write UTF-8 ``text`` to ``path`` through a temporary file and a rename."""
    write_bytes_atomic(path, text.encode("utf-8"))
