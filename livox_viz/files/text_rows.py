"""Rows of numbers as text, byte for byte as ``numpy.savetxt`` writes them (``%.Nf``, ``%d``), in a compiled loop.

``numpy.savetxt`` formats each row in Python (``fmt % tuple(row)``): about 5 us a
point for a CSV's ten columns, several times the whole scan of that point. Here
one compiled pass writes the digits: a number ``v`` with ``N`` decimals is
``round(|v| * 10^N)`` written with its point, which is what Python's correctly
rounded ``%.Nf`` gives. Where ``|v| * 10^N`` lies within a few ulps of a half,
the float product cannot tell which way the exact value rounds; the loop then
reads the exact fraction from the number's bits (an exact tie such as
0.0078125 to 6 decimals goes to even, as Python's does). Non-finite numbers,
and those too large or too small for that, are formatted by Python's own ``%``,
so every byte is the one ``savetxt`` writes (tested against it).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from livox_viz.core.compiled import LazyKernels

#: A column's decimals for a whole number (``%d``).
WHOLE = -1


class TextRows:
    """Formats rows of numbers as text lines, as ``numpy.savetxt(f, values, fmt=..., delimiter=delimiter)``.

    Parameters
    ----------
    decimals : sequence of int
        Per column: decimals of ``%.Nf``, or :data:`WHOLE` for ``%d``.
    delimiter : str
        One ASCII character between the columns.

    The text is made in a buffer kept from call to call (a frame's text without fresh page faults): what
    :meth:`format` returns is valid until its next call.
    """

    def __init__(self, decimals: Sequence[int], delimiter: str = ",") -> None:
        self.decimals = np.asarray(decimals, dtype=np.int64)
        self.delimiter = delimiter
        #: Bytes a row may take at most: per column a sign, 16 digits (scaled values stay below 2^52 and whole
        #: ones below 9e15; larger ones are Python's), the point, the decimals and a separator.
        self.row_bytes = int(np.sum(19 + np.maximum(self.decimals, 0))) + 1
        self._line = delimiter.join("%d" if n == WHOLE else f"%.{n}f" for n in self.decimals.tolist()) + "\n"
        self._buffer = np.empty(0, dtype=np.uint8)

    def format(self, values: np.ndarray) -> list[memoryview | bytes]:
        """The rows of ``values`` ``(n, k)`` float64 as text, in pieces to write one after the other (one piece
        unless a number the loop cannot write was formatted by Python's ``%``: non-finite, or of 2^52 and more
        once scaled)."""
        values = np.ascontiguousarray(values, dtype=np.float64)
        count, columns = values.shape
        if columns != self.decimals.size:
            raise ValueError(f"{columns} columns; allowed: {self.decimals.size}")
        if count == 0:
            return []
        if self._buffer.size < count * self.row_bytes:
            self._buffer = np.empty(count * self.row_bytes, dtype=np.uint8)
        row_end = np.empty(count, dtype=np.int64)
        unsure = np.zeros(count, dtype=np.bool_)
        length = _KERNELS("rows")(values, self.decimals, ord(self.delimiter), self._buffer, row_end, unsure)
        text = memoryview(self._buffer)[:length]
        redo = np.flatnonzero(unsure)
        if redo.size == 0:
            return [text]
        pieces: list[memoryview | bytes] = []
        start = 0
        for row in redo.tolist():
            begin = int(row_end[row - 1]) if row else 0
            pieces += [text[start:begin], (self._line % tuple(values[row].tolist())).encode("ascii")]
            start = int(row_end[row])
        pieces.append(text[start:])
        return pieces


def format_rows(values: np.ndarray, decimals: Sequence[int], delimiter: str = ",") -> bytes:
    """The rows of ``values`` ``(n, k)`` float64 as text lines, as :class:`TextRows` makes them, in one piece."""
    return b"".join(TextRows(decimals, delimiter).format(values))


def _put_whole(number, out, at, pairs):  # pragma: no cover - compiled
    """Write the digits of the whole number ``number`` >= 0 at ``out[at]``; returns the position after them.
    ``pairs`` ``(200,)`` uint8 holds "00" to "99": two digits a division."""
    digits = 1
    bound = np.int64(10)
    while digits < 19 and number >= bound:
        digits += 1
        bound *= 10
    position = at + digits
    while number >= 100:
        position -= 2
        _put_pair(number % 100, out, position, pairs)
        number //= 100
    if number >= 10:
        _put_pair(number, out, position - 2, pairs)
    else:
        out[position - 1] = 48 + number
    return at + digits


def _put_decimals(number, decimals, out, at, pairs):  # pragma: no cover - compiled
    """Write the whole number ``0 <= number < 10^decimals`` as exactly ``decimals`` digits (leading zeros)."""
    position = at + decimals
    left = decimals
    while left >= 2:
        position -= 2
        _put_pair(number % 100, out, position, pairs)
        number //= 100
        left -= 2
    if left:
        out[position - 1] = 48 + number % 10
    return at + decimals


def _put_pair(value, out, at, pairs):  # pragma: no cover - compiled
    """Write the two digits of ``0 <= value < 100`` at ``out[at]`` (``pairs`` holds "00" to "99")."""
    out[at] = pairs[2 * value]
    out[at + 1] = pairs[2 * value + 1]


def _side_of_half(magnitude, decimals):  # pragma: no cover - compiled
    """Where the exact fraction of ``magnitude * 10^decimals`` lies against one half: -1 below, 0 on it, 1 above;
    2 where this cannot tell (it needs more than 64 bits).

    ``magnitude = m 2^-k`` (m < 2^53 whole), so the product is ``m 5^d / 2^(k - d)``: its fraction is the low
    ``k - d`` bits of ``m 5^d``, which wrapping 64-bit arithmetic gives exactly while ``k - d < 64``.
    """
    mantissa, exponent = math.frexp(magnitude)
    shift = 53 - exponent - decimals
    if shift <= 0 or shift >= 64:
        return 2
    whole = np.uint64(mantissa * 9007199254740992.0)  # 2^53: m exactly
    five = np.uint64(1)
    for _ in range(decimals):
        five = five * np.uint64(5)
    low = (whole * five) & ((np.uint64(1) << np.uint64(shift)) - np.uint64(1))
    half = np.uint64(1) << np.uint64(shift - 1)
    if low > half:
        return 1
    if low < half:
        return -1
    return 0


def _rows(values, places, delimiter, out, row_end, unsure):  # pragma: no cover - compiled
    count, columns = values.shape
    pairs = np.empty(200, dtype=np.uint8)
    for k in range(100):
        pairs[2 * k] = 48 + k // 10
        pairs[2 * k + 1] = 48 + k % 10
    scales = np.empty(columns, dtype=np.float64)
    powers = np.empty(columns, dtype=np.int64)
    for column in range(columns):
        powers[column] = 1
        for _ in range(max(places[column], 0)):
            powers[column] *= 10
        scales[column] = float(powers[column])
    at = 0
    for row in range(count):
        for column in range(columns):
            if column:
                out[at] = delimiter
                at += 1
            value = values[row, column]
            decimals = places[column]
            if not math.isfinite(value):
                unsure[row] = True
                continue
            negative = value < 0.0 or (value == 0.0 and math.copysign(1.0, value) < 0.0)
            magnitude = abs(value)
            if decimals < 0:  # %d: towards zero, as int() does
                if magnitude >= 9.0e15:
                    unsure[row] = True
                    continue
                whole = np.int64(magnitude)
                if negative and whole != 0:
                    out[at] = 45
                    at += 1
                at = _put_whole(whole, out, at, pairs)
                continue
            scaled = magnitude * scales[column]
            if scaled >= 4503599627370496.0:  # 2^52: not an exact integer grid any more
                unsure[row] = True
                continue
            floor = math.floor(scaled)
            fraction = scaled - floor
            up = fraction > 0.5
            # The product's own rounding (half an ulp, an ulp at most scaled * 2^-52): within four ulps of a
            # half, the exact value may round either way; it decides (the float floor is exact there).
            if abs(fraction - 0.5) <= scaled * 8.9e-16:
                side = _side_of_half(magnitude, decimals)
                if side == 2:
                    unsure[row] = True
                    continue
                up = side > 0 or (side == 0 and np.int64(floor) % 2 == 1)  # an exact tie goes to even
            rounded = np.int64(floor) + (1 if up else 0)
            if negative:
                out[at] = 45
                at += 1
            # The usual decimals by constants (a multiplication each, where a divisor read from an array is a
            # division: a third of the loop's time).
            if decimals == 6:
                whole = rounded // 1000000
                at = _put_whole(whole, out, at, pairs)
                out[at] = 46
                at = _put_decimals(rounded - whole * 1000000, 6, out, at + 1, pairs)
            elif decimals == 9:
                whole = rounded // 1000000000
                at = _put_whole(whole, out, at, pairs)
                out[at] = 46
                at = _put_decimals(rounded - whole * 1000000000, 9, out, at + 1, pairs)
            else:
                power = powers[column]
                at = _put_whole(rounded // power, out, at, pairs)
                if decimals > 0:
                    out[at] = 46
                    at = _put_decimals(rounded % power, decimals, out, at + 1, pairs)
        out[at] = 10
        at += 1
        row_end[row] = at
    return at


_KERNELS = LazyKernels(globals(), helpers=("_put_pair", "_put_whole", "_put_decimals", "_side_of_half"))
