"""A JSON reader that turns every failure into one line naming the file and what is wrong.

Text is UTF-8, with or without Notepad's byte-order mark, or UTF-16 with its
mark, as PowerShell 5.1 writes (:mod:`~livox_viz.core.textfile`). NaN and
Infinity (which Python's parser accepts but JSON does not) are refused with
the key that holds them; so is nesting too deep to parse. At most
:data:`MAX_JSON_BYTES` (64 MiB) is ever read: the file is read to one byte past
the limit, so an endless source (``/dev/zero``, a pipe that never closes its
end, which ``stat`` calls empty) is refused as soon as it passes the limit.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from livox_viz.core.errors import ConfigError
from livox_viz.core.textfile import ENCODINGS, decode_text

# Files ------------------------------------------------------------------------------
MAX_JSON_BYTES = 64 << 20


class _NonFinite(float):
    """A NaN or Infinity the JSON held, or a number too large for a float, kept so the error can name its key."""

    word = ""
    reason = "which JSON does not allow"


class _Repeated(Exception):
    """A key given twice in one JSON object (its name is the argument)."""


def read_json_file(path: str | os.PathLike[str], what: str = "") -> Any:
    """Parse a JSON file, turning every failure into a one-line :class:`ConfigError`; with ``what`` (``"scene
    JSON"``), the line says the file is not a readable one of those, and why.
    """
    if not what:
        return _read_json_file(path)
    try:
        return _read_json_file(path)
    except ConfigError as exc:
        raise ConfigError(f"{path}: not a readable {what} ({str(exc).removeprefix(f'{path}: ')})") from None


def _read_json_file(path: str | os.PathLike[str]) -> Any:
    """See :func:`read_json_file`.

    NaN and Infinity (which Python's parser accepts but JSON does not) are
    refused with the key that holds them; so are inputs over 64 MiB (read no
    further than that, whatever ``stat`` says) and nesting too deep to parse.
    """
    path = Path(path)
    too_big = f"{path}: more than {MAX_JSON_BYTES:,} bytes; allowed: a JSON file of at most {MAX_JSON_BYTES >> 20} MiB"
    try:
        if path.is_dir():
            raise ConfigError(f"{path}: is a folder, expected a JSON file")
        if path.is_file() and path.stat().st_size > MAX_JSON_BYTES:
            raise ConfigError(too_big)
        with open(path, "rb") as handle:
            data = handle.read(MAX_JSON_BYTES + 1)
        if len(data) > MAX_JSON_BYTES:
            raise ConfigError(too_big)
        text = decode_text(data)
    except FileNotFoundError:
        raise ConfigError(f"{path}: no such file") from None
    except UnicodeDecodeError as exc:
        raise ConfigError(f"{path}: not text (byte {exc.start}: {exc.reason}); allowed: JSON in {ENCODINGS}") from None
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read ({exc})") from None
    if not text.strip():
        raise ConfigError(f"{path}: is empty, expected a JSON object")
    constants: list[str] = []

    def mark(word: str) -> _NonFinite:
        constants.append(word)
        return _mark_constant(word)

    def integer(word: str) -> int | float:
        # An integer past float's range (400 digits) would overflow every check of it (and one of 4300 digits,
        # Python's own parse). A float past it parses as Infinity, which every check refuses already.
        if len(word.lstrip("-")) < 309:
            return int(word)
        constants.append(word)
        marked = _mark_constant("-Infinity" if word.startswith("-") else "Infinity")
        marked.word = f"{word[:20]}... ({len(word.lstrip('-'))} digits)"
        marked.reason = "too large for a number"
        return marked

    def unique(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
        # Python keeps the last of a repeated key: a file saying CameraFOV twice would silently mean the second.
        made = dict(pairs)
        if len(made) != len(pairs):
            seen: set[str] = set()
            raise _Repeated(next(key for key, _ in pairs if key in seen or seen.add(key)))
        return made

    try:
        data = json.loads(text, parse_constant=mark, parse_int=integer, object_pairs_hook=unique)
    except _Repeated as exc:
        raise ConfigError(f"{path}: the key {exc.args[0]!r} appears twice in one object; allowed: each key once "
                          "(JSON readers differ on which one they keep)") from None
    except json.JSONDecodeError as exc:
        raise ConfigError(f"{path}: malformed JSON at line {exc.lineno} column {exc.colno}: {exc.msg}") from None
    except RecursionError:
        raise ConfigError(f"{path}: JSON nested too deeply; allowed: objects and lists a few levels deep") from None
    # The tree is searched for the key only when the parser met a NaN or Infinity: walking a track preset's
    # thousand coefficients cost 5-10 ms a file, and the window's reference key reads every preset.
    where = _find_non_finite(data, "") if constants else None
    if where is not None:
        key, word, reason = where
        raise ConfigError(f"{path}: {key or 'the top level'} = {word}, {reason}; allowed: finite numbers")
    return data


def _mark_constant(word: str) -> _NonFinite:
    value = _NonFinite(word.replace("Infinity", "inf"))
    value.word = word
    return value


def _find_non_finite(value: Any, where: str, depth: int = 0) -> tuple[str, str, str] | None:
    """The key path (``otherParams[1]``), word and what is wrong with it of the first NaN/Infinity (or number too
    large for a float) in parsed JSON, or None."""
    if isinstance(value, _NonFinite):
        return where, value.word, value.reason
    if depth > 200:
        return None
    items = value.items() if isinstance(value, dict) else enumerate(value) if isinstance(value, list) else ()
    for key, item in items:
        if isinstance(key, str):
            name = f"{where}.{key}" if where else key
        else:
            name = f"{where}[{key}]"
        found = _find_non_finite(item, name, depth + 1)
        if found is not None:
            return found
    return None


# Writing ----------------------------------------------------------------------------
def dumps_readable(data: Any, indent: int = 2) -> str:
    """JSON with objects indented but lists of plain values on one line each.

    A track preset holds hundreds of coefficient pairs: one number per line (``json.dumps(indent=2)``)
    makes files thousands of lines long; this keeps ``[re, im]`` pairs and short lists on a line.
    """
    return _dump(data, indent, 0) + "\n"


def _dump(value: Any, indent: int, level: int) -> str:
    pad, inner = " " * (indent * level), " " * (indent * (level + 1))
    if isinstance(value, dict):
        if not value:
            return "{}"
        items = [f"{inner}{json.dumps(str(key))}: {_dump(item, indent, level + 1)}" for key, item in value.items()]
        return "{\n" + ",\n".join(items) + "\n" + pad + "}"
    if isinstance(value, list) and any(isinstance(item, (dict, list)) for item in value):
        items = [f"{inner}{_dump(item, indent, level + 1)}" for item in value]
        return "[\n" + ",\n".join(items) + "\n" + pad + "]"
    return json.dumps(value, allow_nan=False)
