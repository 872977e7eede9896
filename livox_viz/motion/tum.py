"""TUM trajectory files: ``t x y z qx qy qz qw`` per line, ``#`` comments.

Poses are the vehicle's (body FRD in world NED, metres; the quaternion rotates body
vectors into the world), t in seconds from the scan start.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from livox_viz.core.errors import LivoxVizError, require_file
from livox_viz.motion.trajectory import Trajectory


def load_tum(path: str | os.PathLike[str]) -> Trajectory:
    """Read a TUM trajectory: ``t x y z qx qy qz qw`` per line, ``#`` comments, world NED, t from the scan start.

    Raises
    ------
    LivoxVizError
        Naming the file and the line of what is wrong.
    """
    path = Path(path)
    require_file(path, "TUM trajectory (t x y z qx qy qz qw per line)")
    rows = []
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise LivoxVizError(f"{path}: not UTF-8 text; allowed: a TUM trajectory (t x y z qx qy qz qw)") from None
    for number, line in enumerate(text.splitlines(), start=1):
        words = line.split("#", 1)[0].replace(",", " ").split()
        if not words:
            continue
        if len(words) != 8:
            raise LivoxVizError(f"{path}: line {number} has {len(words)} values; allowed: 8 (t x y z qx qy qz qw)")
        try:
            rows.append([float(w) for w in words])
        except ValueError:
            raise LivoxVizError(f"{path}: line {number} is not numeric: {line.strip()[:60]!r}") from None
    if len(rows) < 2:
        raise LivoxVizError(f"{path}: {len(rows)} poses; allowed: at least 2")
    table = np.array(rows)
    return Trajectory(path.name, table[:, 0], table[:, 1:4], table[:, 4:8])


def save_tum(trajectory: Trajectory, path: str | os.PathLike[str]) -> None:
    """Write a trajectory as TUM text, atomically."""
    from livox_viz.core.atomic import write_text_atomic

    lines = ["# livox-viz trajectory: t (s from the scan start) x y z (m, world NED) qx qy qz qw (body FRD -> NED)"]
    for t, p, q in zip(trajectory.t, trajectory.position, trajectory.quaternion, strict=True):
        lines.append(" ".join(f"{v:.9f}" for v in (t, *p, *q)))
    write_text_atomic(path, "\n".join(lines) + "\n")
