"""Writing files so that a user's file is never lost or half-written.

Everything is written to a temporary file (or work folder) in the
destination's folder and renamed over the destination only once it is
complete; on any failure the temporary is removed and the old file, if any, is
untouched. Temporaries are named ``.<name>.livox-viz-<pid>.part`` (or
``.work``), so a later run recognises what a killed run left behind (its
process is gone) and removes it.

A destination that is a symbolic link is written through: the link's target
is replaced and the link stays. An existing file keeps its permissions; a
read-only one (no write permission for us, or no write bit at all, which even
root respects here) and anything that is not a regular file are refused,
never replaced.

A temporary's name is recorded before it is created (:class:`WorkDir`,
:func:`atomic_path`) in this process's list of unfinished temporaries, and
struck off when it is removed or renamed into place. A signal can land between
any two bytecodes, even after a writer's constructor has finished and before
its caller holds the writer; :func:`remove_unfinished` (which the command line
calls when a signal stops it, and which runs at exit) removes whatever such a
moment left.
"""

from __future__ import annotations

import atexit
import errno
import os
import re
import secrets
import shutil
import stat
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from livox_viz.core.errors import LivoxVizError
from livox_viz.core.portable import process_alive

_TAG = "livox-viz"
_LEFTOVER = re.compile(rf"^\..+\.{_TAG}-(\d+)\.[A-Za-z0-9_]+\.(part|work)$")
#: Temporaries (files and folders) this process has named, maybe made, and not yet removed or renamed.
_UNFINISHED: set[Path] = set()


def remove_unfinished() -> list[Path]:
    """Remove every temporary this process made and has not finished with; returns those that existed.

    For the end of a run a signal stopped: the writers have aborted what they knew of, and this takes
    what a signal landing between a temporary's creation and its writer's knowing of it left.
    """
    removed = []
    for path in sorted(_UNFINISHED):
        if os.path.lexists(path):
            if path.is_dir() and not path.is_symlink():
                shutil.rmtree(path, ignore_errors=True)
            else:
                path.unlink(missing_ok=True)
            removed.append(path)
        _UNFINISHED.discard(path)
    return removed


atexit.register(remove_unfinished)


def _current_umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def remove_dead_leftovers(folder: str | os.PathLike[str]) -> list[Path]:
    """Remove the temporaries of livox-viz runs that no longer exist; returns what was removed."""
    removed = []
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return removed
    for entry in entries:
        match = _LEFTOVER.match(entry.name)
        if match is None or int(match.group(1)) == os.getpid() or process_alive(int(match.group(1))):
            continue
        path = Path(entry.path)
        if entry.is_dir(follow_symlinks=False):
            shutil.rmtree(path, ignore_errors=True)
        else:
            path.unlink(missing_ok=True)
        removed.append(path)
    return removed


def resolve_destination(path: str | os.PathLike[str]) -> Path:
    """The file really written for ``path`` (a symbolic link's target), checked before any work.

    Raises
    ------
    LivoxVizError
        If ``path`` is a folder, a loop of symbolic links, something other than a regular file
        (a device, a pipe), a read-only file, or its folder does not exist or has no write bit at all.
    """
    path = Path(path)
    if path.is_symlink():
        try:
            path = Path(os.path.realpath(path, strict=True))
        except FileNotFoundError:  # a dangling link: writing creates its target
            path = Path(os.path.realpath(path))
        except OSError as exc:
            if exc.errno != errno.ELOOP:
                raise LivoxVizError(f"{path}: cannot follow the link ({exc.strerror})") from None
            raise LivoxVizError(f"{path}: is a loop of symbolic links; allowed: a file or a link to one") from None
    if path.is_dir():
        raise LivoxVizError(f"{path}: is a folder; allowed: a file name")
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise LivoxVizError(f"{path}: the folder {folder} does not exist")
    # A folder with no write bit at all is refused even to root, who could write there, as a read-only file is
    # (below): its owner marked it so.
    if not folder.stat().st_mode & 0o222:
        raise LivoxVizError(f"{path}: the folder {folder} is read-only; allowed: a file in a writable folder")
    try:
        status = path.stat()
    except FileNotFoundError:
        return path
    except OSError as exc:
        raise LivoxVizError(f"{path}: cannot check it ({exc.strerror})") from None
    if not stat.S_ISREG(status.st_mode):
        raise LivoxVizError(f"{path}: is not a regular file (a device or a pipe); allowed: a file name")
    if not status.st_mode & 0o222 or not os.access(path, os.W_OK):
        raise LivoxVizError(f"{path}: is read-only; allowed: a writable file or another name (it is not replaced)")
    return path


def _temporary_name(path: Path, suffix: str) -> Path:
    return path.parent / f".{path.name}.{_TAG}-{os.getpid()}.{secrets.token_hex(4)}.{suffix}"


@contextmanager
def atomic_path(path: str | os.PathLike[str]) -> Iterator[Path]:
    """Yield a temporary path to write; on success it replaces ``path`` in one rename.

    Raises
    ------
    LivoxVizError
        If the destination is refused by :func:`resolve_destination`, its folder is not writable,
        or writing fails (the message names the file; the old file, if any, is kept).
    """
    path = resolve_destination(path)
    folder = path.parent
    remove_dead_leftovers(folder)
    made: list[Path] = []  # the name is known here before the file exists, so the finally always removes it
    try:
        for _ in range(100):
            made[:] = [_temporary_name(path, "part")]
            _UNFINISHED.add(made[0])
            try:
                os.close(os.open(made[0], os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600))
                break
            except FileExistsError:
                _UNFINISHED.discard(made[0])
                continue
            except OSError as exc:
                _UNFINISHED.discard(made.pop())
                raise LivoxVizError(f"{path}: cannot write in {folder} ({exc.strerror})") from None
        tmp = made[0]
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
        for leftover in made:
            leftover.unlink(missing_ok=True)
            _UNFINISHED.discard(leftover)


class WorkDir:
    """A temporary folder beside a destination, for a writer's parts.

    The folder's name is chosen and recorded by the constructor, which creates nothing; :meth:`create`
    makes it and :meth:`remove` removes it (whatever is inside). A writer assigns the object first and
    creates the folder inside its ``try``, so no signal can land between the folder's creation and
    the writer's knowing of it.

    Parameters
    ----------
    path : path-like
        The destination the parts are for (checked with :func:`resolve_destination`).
    """

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.destination = resolve_destination(path)
        self.path = _temporary_name(self.destination, "work")

    def create(self) -> Path:
        """Make the folder (removing dead runs' leftovers first); returns its path."""
        remove_dead_leftovers(self.destination.parent)
        for _ in range(100):
            _UNFINISHED.add(self.path)
            try:
                os.mkdir(self.path, 0o700)
                return self.path
            except FileExistsError:
                _UNFINISHED.discard(self.path)
                self.path = _temporary_name(self.destination, "work")
            except OSError as exc:
                _UNFINISHED.discard(self.path)
                raise LivoxVizError(f"{self.destination}: cannot write in {self.destination.parent} "
                                    f"({exc.strerror})") from None
        raise LivoxVizError(f"{self.destination}: no free temporary name in {self.destination.parent}")

    def remove(self) -> None:
        """Remove the folder and everything in it (nothing happens if it was never made)."""
        shutil.rmtree(self.path, ignore_errors=True)
        _UNFINISHED.discard(self.path)


def make_work_dir(path: str | os.PathLike[str]) -> Path:
    """A temporary folder beside ``path`` for a writer's parts (the caller removes it); see :class:`WorkDir`."""
    return WorkDir(path).create()


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
