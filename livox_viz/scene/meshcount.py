"""How many triangles a mesh file holds, read before trimesh parses it: from its header, or one pass over its text.

trimesh builds a whole file in memory (a 5-million-triangle STL took 5.6 GB to
scan), so the scene's triangle budget is checked first on what the file says:
a binary STL's count, a PLY's or an OFF's face count, an ASCII STL's facets, an
OBJ's face lines. Each is at least the triangles trimesh will make (a polygon
makes one or more); formats that say nothing cheaply (glTF) give None and are
counted once parsed.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

_BLOCK_BYTES = 1 << 20
#: Header lines of a PLY read at most (its header ends long before).
_PLY_HEADER_LINES = 10_000


def triangles_at_least(path: str | os.PathLike[str]) -> int | None:
    """At least how many triangles the mesh file at ``path`` makes, or None when its format does not say cheaply.

    Parameters
    ----------
    path : path-like
        A regular file (``.stl``, ``.ply``, ``.off``, ``.obj``; others give None).
    """
    path = Path(path)
    suffix = path.suffix.lower()
    with open(path, "rb") as handle:
        if suffix == ".stl":
            head = handle.read(84)
            if len(head) == 84:
                count = int.from_bytes(head[80:84], "little")
                if os.fstat(handle.fileno()).st_size == 84 + 50 * count:  # binary: the header's count is exact
                    return count
            handle.seek(0)
            return _count(handle, b"endfacet")
        if suffix == ".obj":
            return _count(handle, b"\nf ", b"\n") + _count(handle, b"\nf\t", b"\n", rewind=True)
        if suffix == ".ply":
            return _ply_faces(handle)
        if suffix == ".off":
            return _off_faces(handle)
    return None


def _count(handle, token: bytes, start: bytes = b"", rewind: bool = False) -> int:
    """Occurrences of ``token`` in the file (``start`` taken as written before its first byte), in blocks."""
    if rewind:
        handle.seek(0)
    count, tail = 0, start
    while block := handle.read(_BLOCK_BYTES):
        data = tail + block
        count += data.count(token)
        tail = data[-(len(token) - 1):]  # too short to hold a token: one across two blocks is counted in the second
    return count


def _ply_faces(handle) -> int | None:
    for _ in range(_PLY_HEADER_LINES):
        line = handle.readline(1000)
        if not line or line.strip() == b"end_header":
            return None
        words = line.split()
        if len(words) == 3 and words[0] == b"element" and words[1] == b"face" and words[2].isdigit():
            return int(words[2])
    return None


def _off_faces(handle) -> int | None:
    words: list[bytes] = []
    for _ in range(1000):
        line = handle.readline(1000)
        if not line:
            return None
        words += line.split(b"#", 1)[0].split()
        if words and re.fullmatch(rb"[A-Z]*OFF", words[0]):
            words = words[1:]
        if len(words) >= 2:
            return int(words[1]) if words[1].isdigit() else None
    return None
