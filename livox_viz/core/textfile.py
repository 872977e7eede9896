"""Text files as Windows tools save them, for every reader of a user's text (JSON, TOML, CSV, TUM).

Notepad writes UTF-8 with a byte-order mark; Windows PowerShell 5.1 writes UTF-16 (little-endian, with its
mark) for ``>`` and ``Out-File``, so ``livox-viz batch --example > spec.toml`` or a config saved through a
PowerShell pipe is UTF-16. Both are read here as the plain UTF-8 file would be. Text without a mark is UTF-8
(UTF-16 without a mark is not guessed: a Latin-1 file would pass for it).
"""

from __future__ import annotations

import codecs
from collections.abc import Iterator
from typing import BinaryIO

#: Byte-order marks of UTF-16, little- and big-endian.
UTF16_MARKS = (codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)
#: What the readers accept, for their refusals.
ENCODINGS = "UTF-8 (with or without a byte-order mark) or UTF-16 with its mark"


def decode_text(data: bytes) -> str:
    """A file's text: UTF-16 when it starts with that mark, else UTF-8 with Notepad's mark, if any, removed.

    Raises
    ------
    UnicodeDecodeError
        Bytes that are not text in that encoding (``start`` is the offset of the first, in ``data``).
    """
    if data.startswith(UTF16_MARKS):
        return data.decode("utf-16")
    return data.decode("utf-8-sig")


def utf8_blocks(handle: BinaryIO, block_bytes: int) -> Iterator[bytes]:
    """A file read from its start in blocks of about ``block_bytes``, as UTF-8 bytes without a byte-order mark.

    A UTF-8 file's blocks come as they are (a character may be cut between two blocks, as for any byte
    reader: split lines on ``b"\\n"``, which UTF-8 never holds inside a character); a UTF-16 file's are decoded
    as they come, so a file of any size is still read as a stream.

    Raises
    ------
    UnicodeDecodeError
        UTF-16 that is not (an odd byte at its end, a lone surrogate).
    """
    first = handle.read(max(block_bytes, len(codecs.BOM_UTF8)))  # a whole mark to tell the encoding by
    if not first.startswith(UTF16_MARKS):
        block = first.removeprefix(codecs.BOM_UTF8)
        while first:
            if block:
                yield block
            first = block = handle.read(block_bytes)
        return
    decoder = codecs.getincrementaldecoder("utf-16")()
    block = first
    while block:
        text = decoder.decode(block)
        if text:
            yield text.encode("utf-8")
        block = handle.read(block_bytes)
    tail = decoder.decode(b"", final=True)
    if tail:
        yield tail.encode("utf-8")
