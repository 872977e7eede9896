"""An ``.npz`` written column by column as chunks arrive, so memory stays flat however long the stream.

Each column goes to its own raw file in a work folder while the stream runs;
:meth:`NpzColumns.finish` then writes every column as one ``.npy`` member
(header first, body copied in blocks) into the archive. ``numpy.load`` reads
the result like any ``numpy.savez`` file.
"""

from __future__ import annotations

import os
import shutil
import zipfile
from pathlib import Path
from typing import BinaryIO

import numpy as np

from livox_viz.core.errors import LivoxVizError


class NpzColumns:
    """Columns of equal length, appended chunk by chunk.

    Parameters
    ----------
    work : Path
        An existing folder for the raw column files (the caller removes it).
    columns : dict of str to (dtype, tail shape)
        E.g. ``{"xy_deg": ("<f8", (2,)), "t": ("<f8", ())}``.
    """

    def __init__(self, work: Path, columns: dict[str, tuple[str, tuple[int, ...]]]) -> None:
        self.columns = dict(columns)
        self.rows = 0
        self._files: dict[str, BinaryIO] = {name: open(work / f"{name}.raw", "wb") for name in self.columns}
        self._work = work

    def append(self, arrays: dict[str, np.ndarray]) -> None:
        """Append one chunk: every column, each ``(n, *tail)``, the same n."""
        lengths = {name: np.shape(arrays[name])[0] for name in self.columns}
        if len(set(lengths.values())) > 1:
            raise LivoxVizError(f"columns of different lengths {lengths}")
        for name, (dtype, tail) in self.columns.items():
            values = np.ascontiguousarray(arrays[name], dtype=dtype)
            if values.shape[1:] != tail:
                raise LivoxVizError(f"column {name} has shape {values.shape}; allowed: (n, {tail})")
            values.tofile(self._files[name])
        self.rows += next(iter(lengths.values()), 0)

    def chunk_bytes(self, arrays: dict[str, np.ndarray]) -> int:
        """Bytes :meth:`append` of ``arrays`` would write."""
        return sum(int(np.prod(np.shape(arrays[name]))) * np.dtype(dtype).itemsize
                   for name, (dtype, _) in self.columns.items())

    def cut_to_rows(self) -> None:
        """After a failed :meth:`append`: every column cut back to the rows appended whole (the files are closed;
        a failure to flush the rest of a buffer is what failed, and is not raised)."""
        self.discard()
        for name, (dtype, tail) in self.columns.items():
            row_bytes = int(np.prod(tail, dtype=np.int64)) * np.dtype(dtype).itemsize
            os.truncate(self._work / f"{name}.raw", self.rows * row_bytes)

    def finish(self, path: Path, extra: dict[str, np.ndarray] | None = None) -> None:
        """Write the archive to ``path`` (a temporary file the caller renames): the columns, then ``extra``."""
        self.close()
        with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_STORED, allowZip64=True) as archive:
            for name, (dtype, tail) in self.columns.items():
                header = {"descr": np.dtype(dtype).str, "fortran_order": False, "shape": (self.rows, *tail)}
                with archive.open(f"{name}.npy", "w", force_zip64=True) as member, \
                        open(self._work / f"{name}.raw", "rb") as body:
                    np.lib.format.write_array_header_2_0(member, header)
                    shutil.copyfileobj(body, member, 1 << 20)
            for name, value in (extra or {}).items():
                with archive.open(f"{name}.npy", "w", force_zip64=True) as member:
                    np.save(member, np.asarray(value), allow_pickle=False)

    def close(self) -> None:
        """Close the raw files (the archive is not written); a failure to flush one (a full disk) is raised."""
        for handle in self._files.values():
            if not handle.closed:
                handle.close()

    def discard(self) -> None:
        """Close every raw file whatever fails (the caller removes them): for giving up after an error."""
        for handle in self._files.values():
            try:
                handle.close()
            except OSError:  # the unwritten rest of its buffer, on a full disk: it is being thrown away
                pass
