"""Atomic file output: write to a temporary file beside the target, then rename.

A reader never sees a half-written file, and a crash leaves the old file intact.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path


def _refuse_special(path: Path) -> None:
    """InputError when ``path`` exists and is not a regular file: renaming onto it would
    replace a device (``/dev/null``), a named pipe or a socket with a regular file."""
    import stat

    from .errors import InputError
    from .safe_read import special_kind

    try:
        mode = os.stat(path).st_mode
    except OSError:
        return  # nothing there yet (or unreadable: the write will say so)
    if stat.S_ISREG(mode) or stat.S_ISDIR(mode):
        return  # a folder: the rename fails and says so
    raise InputError(f"{path}: is {special_kind(mode)}; outputs are written to regular files "
                     "(give a file name)")


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path in the target's folder; rename it onto ``path`` on success.

    Use it for writers that insist on a file name (``cv2.imwrite``, ``trimesh.export``).
    The temporary name keeps the target's suffix so format detection still works.
    """
    path = Path(path)
    _refuse_special(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=path.suffix, dir=path.parent)
    os.close(fd)
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes 0600; outputs get the usual permissions
    try:
        yield Path(tmp)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def write_bytes(path: str | os.PathLike, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically."""
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())


def write_text(path: str | os.PathLike, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    write_bytes(path, text.encode("utf-8"))
