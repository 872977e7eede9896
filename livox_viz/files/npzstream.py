"""An ``.npz`` written column by column as chunks arrive, so memory stays flat however long the stream.

Each column goes to its own raw file in a work folder while the stream runs,
with its CRC-32 kept as it grows. :meth:`NpzColumns.finish` then writes the
archive (a stored ZIP64, as ``numpy.savez`` makes it, read by ``numpy.load``
and every unzip): for each column a local header, its ``.npy`` header padded
so that the data starts on a 4 KiB boundary, and the raw file's bytes handed
over by the kernel (``os.copy_file_range``: on a file system with shared
extents, btrfs or XFS, a reflink, so no byte is copied; elsewhere a copy in
the kernel, without passing through this process). The member's CRC-32 is the
header's joined to the column's (``crc32_combine``), so nothing is read again.
"""

from __future__ import annotations

import functools
import io
import os
import shutil
import struct
import zlib
from pathlib import Path
from typing import BinaryIO

import numpy as np

from livox_viz.core.errors import LivoxVizError
from livox_viz.core.portable import copy_in_kernel

#: Where a column's data starts in the archive: a multiple of this many bytes (a file system's block, so the
#: kernel can share the raw file's extents instead of copying them).
DATA_ALIGN = 4096
_ZIP64 = 0xFFFFFFFF


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
        #: Each column's CRC-32 over the rows appended whole.
        self._crc = dict.fromkeys(self.columns, 0)
        # Unbuffered: what append returns from is written (or failed there), so cut_to_rows keeps exactly the rows
        # counted and their CRC.
        self._files: dict[str, BinaryIO] = {name: open(work / f"{name}.raw", "wb", buffering=0)
                                            for name in self.columns}
        self._work = work

    def append(self, arrays: dict[str, np.ndarray]) -> None:
        """Append one chunk: every column, each ``(n, *tail)``, the same n."""
        lengths = {name: np.shape(arrays[name])[0] for name in self.columns}
        if len(set(lengths.values())) > 1:
            raise LivoxVizError(f"columns of different lengths {lengths}")
        crc = {}
        for name, (dtype, tail) in self.columns.items():
            values = np.ascontiguousarray(arrays[name], dtype=dtype)
            if values.shape[1:] != tail:
                raise LivoxVizError(f"column {name} has shape {values.shape}; allowed: (n, {tail})")
            data = values.reshape(-1).view(np.uint8)
            rest = memoryview(data)
            while rest.nbytes:  # an unbuffered file may take a write in pieces
                rest = rest[self._files[name].write(rest):]
            crc[name] = zlib.crc32(data, self._crc[name])
        self._crc = crc  # only once every column took the chunk (a failed one is cut back by cut_to_rows)
        self.rows += next(iter(lengths.values()), 0)

    def chunk_bytes(self, arrays: dict[str, np.ndarray]) -> int:
        """Bytes :meth:`append` of ``arrays`` would write."""
        return sum(int(np.prod(np.shape(arrays[name]))) * np.dtype(dtype).itemsize
                   for name, (dtype, _) in self.columns.items())

    def checkpoint(self) -> tuple[int, dict[str, int]]:
        """The rows appended so far and their CRCs, for :meth:`cut_to_rows` to come back to."""
        return self.rows, dict(self._crc)

    def cut_to_rows(self, checkpoint: tuple[int, dict[str, int]] | None = None) -> None:
        """After a failed :meth:`append`: every column cut back to the rows appended whole, or to ``checkpoint``
        (the files are closed; a failure to flush the rest of a buffer is what failed, and is not raised)."""
        if checkpoint is not None:
            self.rows, self._crc = checkpoint[0], dict(checkpoint[1])
        self.discard()
        for name, (dtype, tail) in self.columns.items():
            row_bytes = int(np.prod(tail, dtype=np.int64)) * np.dtype(dtype).itemsize
            os.truncate(self._work / f"{name}.raw", self.rows * row_bytes)

    def finish(self, path: Path, extra: dict[str, np.ndarray] | None = None,
               more: tuple[NpzColumns, ...] = ()) -> None:
        """Write the archive to ``path`` (a temporary file the caller renames): the columns, the columns of
        ``more`` (others of their own length, streamed from disk alike), then ``extra``."""
        self.close()
        for other in more:
            other.close()
        with open(path, "wb") as archive:
            members = _ZipMembers(archive)
            for columns in (self, *more):
                columns._write_members(archive, members)
            for name, value in (extra or {}).items():
                buffer = io.BytesIO()
                np.save(buffer, np.asarray(value), allow_pickle=False)
                data = buffer.getvalue()
                members.start(f"{name}.npy", len(data), zlib.crc32(data))
                archive.write(data)
            members.finish()

    def _write_members(self, archive: BinaryIO, members: _ZipMembers) -> None:
        """Each column as an ``.npy`` member of the archive, copied from its raw file."""
        for name, (dtype, tail) in self.columns.items():
            raw = self._work / f"{name}.raw"
            size = raw.stat().st_size
            description = {"descr": np.dtype(dtype).str, "fortran_order": False, "shape": (self.rows, *tail)}
            header_start = archive.tell() + members.local_header_size(f"{name}.npy")
            header = _npy_header(description, header_start)
            crc = _crc32_combine(zlib.crc32(header), self._crc[name], size)
            members.start(f"{name}.npy", len(header) + size, crc)
            archive.write(header)
            with open(raw, "rb") as body:
                _copy_in(body, archive, size)

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


def _npy_header(description: dict, start: int) -> bytes:
    """An ``.npy`` version 2.0 header of ``description`` beginning at byte ``start`` of the archive, padded with
    spaces so the data after it starts on a :data:`DATA_ALIGN` boundary (numpy reads any header length)."""
    text = repr(description).encode("latin1")
    prefix = len(np.lib.format.MAGIC_PREFIX) + 2 + 4  # magic, version, the header's length
    length = prefix + len(text) + 1
    padded = length + (-(start + length) % DATA_ALIGN)
    body = text + b" " * (padded - length) + b"\n"
    return np.lib.format.MAGIC_PREFIX + bytes([2, 0]) + struct.pack("<I", len(body)) + body


def _copy_in(source: BinaryIO, archive: BinaryIO, size: int) -> None:
    """``size`` bytes of ``source`` appended to ``archive``: by the kernel where it can, else through a buffer."""
    archive.flush()
    done = 0
    at = archive.tell()
    while done < size:
        moved = copy_in_kernel(source.fileno(), archive.fileno(), size - done, done, at + done)
        if moved == 0:  # not here, or not between these files: the rest through a buffer
            break
        done += moved
    archive.seek(at + done)
    if done < size:
        source.seek(done)
        shutil.copyfileobj(source, archive, 1 << 20)
    if archive.tell() != at + size:
        raise LivoxVizError(f"a column file changed while the archive was written ({archive.tell() - at} of "
                            f"{size} bytes)")


class _ZipMembers:
    """The ZIP64 structure around stored members written one after the other (what ``zipfile`` makes with
    ``force_zip64``): a local header before each, the central directory and the ZIP64 end records after them."""

    def __init__(self, archive: BinaryIO) -> None:
        self.archive = archive
        self.entries: list[tuple[bytes, int, int, int]] = []  # name, size, CRC, offset of its local header
        # Every member dated 1980-01-01 00:00, ZIP's first day: the same arrays make the same file, byte for byte.
        self._time, self._date = 0, (1 << 5) | 1

    @staticmethod
    def local_header_size(name: str) -> int:
        return 30 + len(name.encode()) + 20

    def start(self, name: str, size: int, crc: int) -> None:
        """The local header of a member of ``size`` bytes and CRC-32 ``crc``; its data follows."""
        encoded = name.encode()
        self.entries.append((encoded, size, crc, self.archive.tell()))
        extra = struct.pack("<HHQQ", 1, 16, size, size)
        self.archive.write(struct.pack("<IHHHHHIIIHH", 0x04034B50, 45, 0, 0, self._time, self._date, crc, _ZIP64,
                                       _ZIP64, len(encoded), len(extra)) + encoded + extra)

    def finish(self) -> None:
        """The central directory and the end records."""
        start = self.archive.tell()
        for name, size, crc, offset in self.entries:
            extra = struct.pack("<HHQQQ", 1, 24, size, size, offset)
            self.archive.write(struct.pack("<IHHHHHHIIIHHHHHII", 0x02014B50, 45 | (3 << 8), 45, 0, 0, self._time,
                                           self._date, crc, _ZIP64, _ZIP64, len(name), len(extra), 0, 0, 0,
                                           0o100644 << 16, _ZIP64) + name + extra)
        end = self.archive.tell()
        count = len(self.entries)
        self.archive.write(struct.pack("<IQHHIIQQQQ", 0x06064B50, 44, 45 | (3 << 8), 45, 0, 0, count, count,
                                       end - start, start))
        self.archive.write(struct.pack("<IIQI", 0x07064B50, 0, end, 1))
        self.archive.write(struct.pack("<IHHHHIIH", 0x06054B50, 0, 0, min(count, 0xFFFF), min(count, 0xFFFF),
                                       min(end - start, _ZIP64), min(start, _ZIP64), 0))


def _gf2_times(matrix: tuple[int, ...], vector: int) -> int:
    """A 32 x 32 matrix over GF(2) (its columns as ints) times a 32-bit vector."""
    total = 0
    row = 0
    while vector:
        if vector & 1:
            total ^= matrix[row]
        vector >>= 1
        row += 1
    return total


@functools.cache
def _zero_bytes_operator(power: int) -> tuple[int, ...]:
    """The operator that moves a CRC-32 over ``2^power`` zero bytes: the one-zero-bit operator (the polynomial,
    then the shift) squared three times for one byte, once more for each doubling."""
    if power == 0:
        one_bit = (0xEDB88320, *(1 << row for row in range(31)))
        return _square(_square(_square(one_bit)))
    return _square(_zero_bytes_operator(power - 1))


def _square(matrix: tuple[int, ...]) -> tuple[int, ...]:
    return tuple(_gf2_times(matrix, column) for column in matrix)


def _crc32_combine(first: int, second: int, second_length: int) -> int:
    """The CRC-32 of two byte strings joined, from each one's CRC-32 and the second's length (zlib's
    ``crc32_combine``, which Python's zlib does not offer): the first CRC moved over ``second_length`` zero
    bytes, one power of two of them at a time, then XORed with the second."""
    power = 0
    while second_length > 0:
        if second_length & 1:
            first = _gf2_times(_zero_bytes_operator(power), first)
        second_length >>= 1
        power += 1
    return first ^ second
