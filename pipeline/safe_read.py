"""Reading user files without trusting them: regular files only, bounded size, bounded JSON.

Every reader of a user-named file goes through here, so a hostile path fails with one
:class:`~pipeline.errors.InputError` line instead of hanging or exhausting memory:

- :func:`regular_file` looks at the path with ``stat`` *before* opening it: a named pipe
  would block ``open`` forever and ``/dev/zero`` never ends, so anything that is not a
  regular file is refused;
- :func:`read_bytes` reads at most a stated number of bytes;
- :func:`load_json` bounds the size, the nesting depth (measured on the text before
  ``json.loads``, which would otherwise recurse until ``RecursionError``) and the number
  of digits of an integer (a 400-digit integer overflows every float conversion).
"""

from __future__ import annotations

import json
import os
import re
import stat
from pathlib import Path
from typing import Any

import numpy as np

from .errors import InputError

#: Largest JSON file read (arrangement, scene truth, intrinsics), bytes.  A 10,000-cuboid
#: arrangement is about 5 MB; parsing 64 MiB of numbers stays well under 1 GB of memory.
MAX_JSON_BYTES = 64 * 2**20
#: Deepest nesting of arrays/objects accepted in a JSON file (an arrangement needs 5).
MAX_JSON_DEPTH = 64
#: Most digits of a JSON integer (a float64 holds 15-17 significant digits).
MAX_INT_DIGITS = 20

_STRINGS = re.compile(rb'"(?:[^"\\]|\\.)*"', re.DOTALL)


def special_kind(mode: int) -> str:
    """What a non-regular file of ``os.stat`` mode ``mode`` is, for a message: ``a named
    pipe``, ``a device``, ``a socket`` or ``not a regular file``."""
    return ("a named pipe" if stat.S_ISFIFO(mode) else
            "a device" if stat.S_ISCHR(mode) or stat.S_ISBLK(mode) else
            "a socket" if stat.S_ISSOCK(mode) else "not a regular file")


def regular_file(path: str | os.PathLike, what: str = "file") -> Path:
    """``path`` when it names an existing regular file (symlinks followed); else InputError.

    Uses ``stat`` only, so a FIFO, a device (``/dev/zero``), a socket or a folder is
    refused without being opened.
    """
    p = Path(path)
    if str(path) == "":
        raise InputError(f"empty path given for the {what}")
    try:
        st = os.stat(p)
    except FileNotFoundError:
        article = "an" if what[:1].lower() in "aeiou" else "a"
        raise InputError(f"{p}: no such file (expected {article} {what})") from None
    except OSError as exc:
        raise InputError(f"{p}: cannot read the {what} ({exc.strerror})") from None
    if stat.S_ISDIR(st.st_mode):
        raise InputError(f"{p}: is a folder, expected a {what}")
    if not stat.S_ISREG(st.st_mode):
        raise InputError(f"{p}: is {special_kind(st.st_mode)}; the {what} must be a regular "
                         "file")
    return p


def read_bytes(path: str | os.PathLike, limit: int, what: str = "file") -> bytes:
    """The bytes of a regular file of at most ``limit`` bytes (InputError otherwise)."""
    p = regular_file(path, what)
    size = p.stat().st_size
    if size > limit:
        raise InputError(f"{p}: {size} bytes is larger than the {limit // 2**20} MiB accepted "
                         f"for a {what}")
    try:
        fd = os.open(p, os.O_RDONLY | os.O_NONBLOCK)
        with os.fdopen(fd, "rb") as fh:
            data = fh.read(limit + 1)
    except OSError as exc:
        raise InputError(f"{p}: cannot read the {what} ({exc.strerror})") from None
    if len(data) > limit:  # grew while we read it
        raise InputError(f"{p}: larger than the {limit // 2**20} MiB accepted for a {what}")
    return data


def json_depth(data: bytes) -> int:
    """Deepest nesting of ``[``/``{`` in JSON text (brackets inside strings not counted)."""
    bare = np.frombuffer(_STRINGS.sub(b'""', data), dtype=np.uint8)
    step = ((bare == ord("[")) | (bare == ord("{"))).astype(np.int64) \
        - ((bare == ord("]")) | (bare == ord("}"))).astype(np.int64)
    return int(np.cumsum(step).max(initial=0))


def _int(text: str) -> int:
    if len(text.lstrip("-")) > MAX_INT_DIGITS:
        raise InputError(f"an integer of {len(text.lstrip('-'))} digits; numbers must fit a "
                         f"64-bit float (at most {MAX_INT_DIGITS} digits)")
    return int(text)


def _constant(name: str) -> Any:
    """``NaN``/``Infinity`` (Python's JSON extension) parse to floats, so that the
    validators reject them naming the field."""
    return float(name.replace("Infinity", "inf"))


def parse_json(data: bytes, where: str) -> Any:
    """Parse JSON bytes with the depth and integer bounds; InputError names ``where``."""
    depth = json_depth(data)
    if depth > MAX_JSON_DEPTH:
        raise InputError(f"{where}: JSON nested {depth} levels deep (at most {MAX_JSON_DEPTH})")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise InputError(f"{where}: not UTF-8 text (byte {exc.start})") from None
    try:
        return json.loads(text, parse_int=_int, parse_constant=_constant)
    except InputError as exc:
        raise InputError(f"{where}: {exc}") from None
    except json.JSONDecodeError as exc:
        raise InputError(f"{where}: not valid JSON ({exc.msg} at line {exc.lineno})") from None
    except RecursionError:  # cannot happen below MAX_JSON_DEPTH; kept as a last guard
        raise InputError(f"{where}: JSON nested too deeply") from None


def load_json(path: str | os.PathLike, what: str = "JSON file",
              limit: int = MAX_JSON_BYTES) -> Any:
    """Read and parse a JSON file with every bound above."""
    return parse_json(read_bytes(path, limit, what), str(path))
