"""TUM trajectory files: ``t x y z qx qy qz qw`` per line, ``#`` comments (commas also separate).

Poses are the vehicle's (body FRD in world NED, metres; the quaternion rotates body
vectors into the world), t in seconds from the scan start.

**Limits.** A file of any size is read as a stream, in blocks, and only as far as
the scan needs: the poses from :data:`MARGIN_POSES` before the scan's start to
:data:`MARGIN_POSES` after its end are kept (the motion spline inside the scan is
then the same as the whole file's to 2^-64, see
:mod:`~livox_viz.motion.trajectory`), and reading stops there. At most
:data:`MAX_POSES` poses are kept (about 150 MB of spline; 83 minutes at 100 Hz),
and a line may be at most :data:`MAX_LINE_CHARS` characters.
"""

from __future__ import annotations

import io
import os
import re
import warnings
from pathlib import Path

import numpy as np

from livox_viz.core.errors import LivoxVizError, quoted, require_file
from livox_viz.core.textfile import ENCODINGS, utf8_blocks
from livox_viz.motion.trajectory import Trajectory

#: Poses kept for the scan's span, at most.
MAX_POSES = 500_000
#: Poses kept beyond each end of the scan's span (the spline's reach, see the module docstring).
MARGIN_POSES = 64
#: Characters in one line, at most.
MAX_LINE_CHARS = 1000
_BLOCK_BYTES = 1 << 20
#: A number as numpy's text parser reads it (no digit separators, no hexadecimal).
_NUMBER = re.compile(r"[+-]?(?:(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?|inf(?:inity)?|nan)", re.IGNORECASE)


def load_tum(path: str | os.PathLike[str], start: float | None = None, stop: float | None = None) -> Trajectory:
    """Read a TUM trajectory, or only the part a scan from ``start`` to ``stop`` seconds needs.

    Parameters
    ----------
    path : path-like
        ``t x y z qx qy qz qw`` per line, ``#`` comments, world NED, t from the scan start.
    start, stop : float, optional
        Seconds; default the whole file. Poses further than :data:`MARGIN_POSES` outside are skipped and
        the file is read no further than that.

    Raises
    ------
    LivoxVizError
        Naming the file and the line of what is wrong, or the limit exceeded.
    """
    path = Path(path)
    require_file(path, "TUM trajectory (t x y z qx qy qz qw per line)")
    low = -np.inf if start is None else float(start)
    high = np.inf if stop is None else float(stop)
    before = np.zeros((0, 8))  # the last MARGIN_POSES poses before `low`
    kept: list[np.ndarray] = []
    inside = after = 0
    line_number = 0
    rest = b""
    with open(path, "rb") as handle:
        blocks = utf8_blocks(handle, _BLOCK_BYTES)
        while after < MARGIN_POSES:
            try:
                block = next(blocks, b"")
            except UnicodeDecodeError as exc:
                raise LivoxVizError(f"{path}: not text ({exc.reason}); allowed: a TUM trajectory (t x y z qx qy qz "
                                    f"qw per line) in {ENCODINGS}") from None
            if not block and not rest:
                break
            lines = (rest + block).split(b"\n")
            rest = lines.pop() if block else b""
            if len(rest) > MAX_LINE_CHARS:
                raise LivoxVizError(f"{path}: line {line_number + len(lines) + 1} is longer than {MAX_LINE_CHARS} "
                                    "characters; allowed: a TUM trajectory (t x y z qx qy qz qw per line)")
            rows = _parse_lines(path, lines, line_number)
            line_number += len(lines)
            if rows.size == 0:
                continue
            early = rows[:, 0] < low
            if early.any():
                before = np.concatenate([before, rows[early]])[-MARGIN_POSES:]
                rows = rows[~early]
            late = np.flatnonzero(rows[:, 0] > high)
            inside += late[0] if late.size else rows.shape[0]
            if late.size:
                take = min(late[0] + MARGIN_POSES - after, rows.shape[0])
                after += take - late[0]
                rows = rows[:take]
            kept.append(rows)
            if inside > MAX_POSES:
                where = "the file" if start is None else "the scan's span"
                raise LivoxVizError(f"{path}: more than {MAX_POSES:,} poses in {where}; allowed: at most "
                                    f"{MAX_POSES:,} (thin the file or scan a shorter time)")
    table = np.concatenate([before, *kept]) if kept else before
    if table.shape[0] < 2:
        raise LivoxVizError(f"{path}: {table.shape[0]} poses" + ("" if start is None else " near the scan's span")
                            + "; allowed: at least 2")
    return Trajectory(path.name, table[:, 0], table[:, 1:4], table[:, 4:8])


def _parse_lines(path: Path, lines: list[bytes], first_line: int) -> np.ndarray:
    """``(m, 8)`` the poses of ``lines`` (numbered from ``first_line + 1``): numpy's parser, or an exact message."""
    if lines and max(map(len, lines)) > MAX_LINE_CHARS:
        offset = next(k for k, line in enumerate(lines) if len(line) > MAX_LINE_CHARS)
        raise LivoxVizError(f"{path}: line {first_line + offset + 1} is longer than {MAX_LINE_CHARS} characters; "
                            "allowed: a TUM trajectory (t x y z qx qy qz qw per line)")
    try:
        text = b"\n".join(lines).decode("utf-8")
    except UnicodeDecodeError:
        raise LivoxVizError(f"{path}: not UTF-8 text; allowed: a TUM trajectory (t x y z qx qy qz qw) in "
                            f"{ENCODINGS}") from None
    text = text.replace(",", " ")
    if not text.strip():
        return np.zeros((0, 8))
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # "input contained no data": a block of comments
            table = np.loadtxt(io.StringIO(text), comments="#", ndmin=2, dtype=np.float64)
        if table.size == 0 or table.shape[1] == 8:
            return table.reshape(-1, 8)
    except ValueError:
        pass
    # Something is wrong: find the first bad line and say what.
    for offset, line in enumerate(text.split("\n")):
        words = line.split("#", 1)[0].split()
        if not words:
            continue
        number = first_line + offset + 1
        if len(words) != 8:
            raise LivoxVizError(f"{path}: line {number} has {len(words)} values; allowed: 8 (t x y z qx qy qz qw)")
        bad = next((word for word in words if not _NUMBER.fullmatch(word)), None)
        if bad is not None:  # Python's float() takes "1_5" and " 1e5 ", numpy's parser neither: say which word
            raise LivoxVizError(f"{path}: line {number}: {quoted(bad)} is not a number; allowed: 8 decimal numbers "
                                "t x y z qx qy qz qw")
    raise LivoxVizError(f"{path}: lines {first_line + 1} to {first_line + len(lines)} do not parse as TUM poses "
                        "(t x y z qx qy qz qw per line)")


def save_tum(trajectory: Trajectory, path: str | os.PathLike[str]) -> None:
    """Write a trajectory as TUM text, atomically."""
    from livox_viz.core.atomic import write_text_atomic

    lines = ["# livox-viz trajectory: t (s from the scan start) x y z (m, world NED) qx qy qz qw (body FRD -> NED)"]
    for t, p, q in zip(trajectory.t, trajectory.position, trajectory.quaternion, strict=True):
        lines.append(" ".join(f"{v:.9f}" for v in (t, *p, *q)))
    write_text_atomic(path, "\n".join(lines) + "\n")
