"""Saved viewpoints of the scene view (View > Viewpoints), kept between sessions in one JSON file, without Qt.

ParaView's camera bookmarks, CloudCompare's saved viewports and RViz's saved
views: a name and a camera (:class:`~livox_viz.widgets.cameras.CameraState`,
the form a screenshot's sidecar writes too). The file is the user's
(``viewpoints.json`` in the ``viewpoints`` folder beside the user presets;
``$LIVOX_VIZ_VIEWPOINTS`` names another folder) and may have been edited by
hand, so reading it never fails: what cannot be read is said in one line and
kept. An entry that cannot be read is written back as it was; a file that is
not a viewpoints file at all is renamed aside, never overwritten, before a new
one is written; every write is a whole new file renamed into place.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path
from typing import Any

from livox_viz.config.presets import user_config_dir
from livox_viz.core.atomic import write_text_atomic
from livox_viz.core.errors import ConfigError, LivoxVizError
from livox_viz.core.jsonfile import read_json_file

from .cameras import CameraState

#: The file's format, its first key: a file of a newer format is read where it can be but never written over.
FORMAT_KEY = "livox_viz_viewpoints"
FORMAT_VERSION = 1
FILE_NAME = "viewpoints.json"
#: The longest name a viewpoint takes: a menu entry, not a paragraph.
NAME_CHARS = 60


def viewpoints_path() -> Path:
    """The user's viewpoints file: ``viewpoints.json`` in ``$LIVOX_VIZ_VIEWPOINTS``, else in the ``viewpoints``
    folder of the user's configuration folder (beside ``presets``, which ``livox-viz presets`` names)."""
    return user_config_dir("viewpoints") / FILE_NAME


@dataclass(frozen=True)
class Viewpoint:
    """A named camera of the scene view."""

    name: str
    camera: CameraState


@dataclass
class ViewpointBook:
    """What a viewpoints file holds, as far as it could be read.

    Parameters
    ----------
    path : Path
    viewpoints : list of Viewpoint
        The entries read, in the file's order.
    kept : list
        The entries that could not be read, as the file holds them (written back unchanged).
    problem : str
        One line saying what could not be read ("" when everything could).
    unreadable : bool
        The file as a whole is no viewpoints file (not JSON, not an object, no list of viewpoints): it is
        renamed aside before a new one is written.
    newer : bool
        Written by a newer livox-viz: read where possible, never written over.
    """

    path: Path
    viewpoints: list[Viewpoint] = field(default_factory=list)
    kept: list[Any] = field(default_factory=list)
    problem: str = ""
    unreadable: bool = False
    newer: bool = False

    def names(self) -> list[str]:
        return [viewpoint.name for viewpoint in self.viewpoints]

    def find(self, name: str) -> Viewpoint:
        """The viewpoint called ``name``.

        Raises
        ------
        LivoxVizError
            None is (the names there are said).
        """
        for viewpoint in self.viewpoints:
            if viewpoint.name == name:
                return viewpoint
        raise LivoxVizError(f"no viewpoint {name!r} in {self.path}; allowed: {', '.join(self.names()) or 'none saved'}")


def check_name(name: str) -> str:
    """A viewpoint's name as a user typed it, trimmed.

    Raises
    ------
    LivoxVizError
        An empty name, one longer than :data:`NAME_CHARS` or with a control character (a line break).
    """
    text = name.strip()
    if not text or len(text) > NAME_CHARS or not text.isprintable():
        shown = text if len(text) <= 20 else text[:20] + "..."
        raise LivoxVizError(f"viewpoint name {shown!r} refused; allowed: 1 to {NAME_CHARS} printable characters")
    return text


def read_viewpoints(path: Path | None = None) -> ViewpointBook:
    """Read the viewpoints file (default :func:`viewpoints_path`); no file is an empty book. Never raises for what
    the file holds: see :class:`ViewpointBook`."""
    path = viewpoints_path() if path is None else Path(path)
    book = ViewpointBook(path)
    if not os.path.lexists(path):
        return book
    # The file's name first and its folder last: a status bar too narrow for the line cuts the folder, not why.
    try:
        data = read_json_file(path, "viewpoints file")
    except ConfigError as exc:
        book.unreadable = True
        book.problem = (f"{path.name}: {str(exc).removeprefix(f'{path}: ')}; it is kept, and set aside when a "
                        f"viewpoint is saved ({path.parent})")
        return book
    entries = data.get("viewpoints") if isinstance(data, dict) else None
    version = data.get(FORMAT_KEY) if isinstance(data, dict) else None
    if not isinstance(entries, list) or not isinstance(version, int) or isinstance(version, bool):
        book.unreadable = True
        book.problem = (f"{path.name}: not a viewpoints file (allowed: an object with \"{FORMAT_KEY}\": "
                        f"{FORMAT_VERSION} and a list \"viewpoints\"); it is kept, and set aside when a viewpoint is "
                        f"saved ({path.parent})")
        return book
    book.newer = version > FORMAT_VERSION
    bad: list[str] = []
    for number, entry in enumerate(entries, 1):
        try:
            viewpoint = _viewpoint(entry, number)
            if viewpoint.name in book.names():
                raise LivoxVizError(f"viewpoint {number}: the name {viewpoint.name!r} is taken by an earlier one")
        except LivoxVizError as exc:
            book.kept.append(entry)
            bad.append(str(exc))
            continue
        book.viewpoints.append(viewpoint)
    if bad:
        book.problem = (f"{path.name}: {len(bad)} of {len(entries)} viewpoints could not be read and are kept as they "
                        f"are ({bad[0]}) ({path.parent})")
    elif book.newer:
        book.problem = (f"{path.name}: written by a newer livox-viz (format {version}); it is read but not written "
                        f"over ({path.parent})")
    return book


def _viewpoint(entry: Any, number: int) -> Viewpoint:
    if not isinstance(entry, dict) or not isinstance(entry.get("name"), str):
        raise LivoxVizError(f"viewpoint {number}: no name; allowed: an object with a \"name\" and a \"camera\"")
    try:
        name = check_name(entry["name"])
    except LivoxVizError as exc:
        raise LivoxVizError(f"viewpoint {number}: {exc}") from None
    return Viewpoint(name, CameraState.from_json(entry.get("camera"), f"viewpoint {name!r}'s camera"))


def write_viewpoints(book: ViewpointBook) -> Path | None:
    """Write ``book`` over its file, whole, through a temporary file and a rename (the entries it could not read
    as they were). A file that was no viewpoints file is first renamed aside; returns that new name, else None.

    Raises
    ------
    LivoxVizError
        The file was written by a newer livox-viz, or cannot be written (the old one is kept).
    """
    if book.newer:
        raise LivoxVizError(f"{book.path}: written by a newer livox-viz; allowed: saving viewpoints with that "
                            "version, or moving the file away")
    try:
        book.path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise LivoxVizError(f"{book.path}: cannot make its folder ({exc.strerror or exc})") from None
    aside = None
    if book.unreadable and os.path.lexists(book.path):
        aside = _aside_name(book.path)
        try:
            os.replace(book.path, aside)
        except OSError as exc:
            raise LivoxVizError(f"{book.path}: cannot move the unreadable file aside ({exc.strerror or exc}); it is "
                                "kept, nothing saved") from None
        book.unreadable = False
    entries = [{"name": viewpoint.name, "camera": viewpoint.camera.to_json()} for viewpoint in book.viewpoints]
    text = json.dumps({FORMAT_KEY: FORMAT_VERSION, "viewpoints": [*entries, *book.kept]}, indent=2) + "\n"
    write_text_atomic(book.path, text)
    return aside


def _aside_name(path: Path) -> Path:
    """A free name beside ``path`` for the file that could not be read: ``viewpoints.unreadable-<time>.json``."""
    stamp = datetime.now().strftime("%Y%m%d-%H%M%S")
    candidate = path.with_name(f"{path.stem}.unreadable-{stamp}{path.suffix}")
    number = 1
    while os.path.lexists(candidate):
        candidate = path.with_name(f"{path.stem}.unreadable-{stamp}-{number}{path.suffix}")
        number += 1
    return candidate


def save_viewpoint(name: str, camera: CameraState, path: Path | None = None) -> str:
    """Add (or replace) the viewpoint ``name`` in the file, read afresh (another window may have saved one
    meanwhile); returns the line the window says.

    Raises
    ------
    LivoxVizError
        A refused name, a newer file, or a file that cannot be written.
    """
    name = check_name(name)
    book = read_viewpoints(path)
    replaced = name in book.names()
    book.viewpoints = [v for v in book.viewpoints if v.name != name] if replaced else book.viewpoints
    book.viewpoints.append(Viewpoint(name, camera))
    aside = write_viewpoints(book)
    said = f"viewpoint {name!r} {'replaced' if replaced else 'saved'} ({camera.projection}) in {book.path}"
    if aside is not None:
        said += f"; the unreadable file before it is kept as {aside.name}"
    elif book.kept:
        said += f"; {len(book.kept)} unreadable entries kept as they were"
    return said


def delete_viewpoint(name: str, path: Path | None = None) -> str:
    """Take the viewpoint ``name`` out of the file; returns the line the window says.

    Raises
    ------
    LivoxVizError
        No such viewpoint, a newer file, or a file that cannot be written.
    """
    book = read_viewpoints(path)
    book.find(name)
    book.viewpoints = [v for v in book.viewpoints if v.name != name]
    write_viewpoints(book)
    return f"viewpoint {name!r} deleted from {book.path}"
