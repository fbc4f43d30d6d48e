"""Output folders written whole: checked early, locked, filled aside, swapped in at once.

A command that writes a folder of results (``unseen run``, ``export``, ``synth``,
``demo``) goes through :func:`check_out` before any work (one line, exit 2, nothing
created) and then :func:`output_folder`:

1. the target folder is created if missing and locked with ``flock`` (a second command
   on the same folder fails at once with one line instead of mixing its files in);
2. the command writes its files into a fresh hidden sibling ``.<name>.tmp-*``;
3. ``manifest.json`` (every file with its size and SHA-256) is written there last;
4. the sibling is exchanged with the target in one ``renameat2(RENAME_EXCHANGE)`` call
   (two renames where the file system cannot), and the old folder is deleted.

A reader therefore sees the old complete set or the new complete set, never a mix;
files an earlier run wrote and this one does not (``urdf/body7.urdf``) are gone; a
killed command leaves only its hidden sibling, removed by the next command on that
folder.  An existing target must be empty or hold a ``manifest.json`` (a folder unseen
wrote) naming the same command, or none (written before manifests named it): a folder
of other files or of another command's results is refused rather than replaced, and so
is a target that contains one of the command's inputs or lies inside an input folder.
"""

from __future__ import annotations

import contextlib
import ctypes
import errno
import fcntl
import hashlib
import json
import os
import shutil
import tempfile
from collections.abc import Iterable, Iterator
from pathlib import Path

from .errors import InputError

MANIFEST = "manifest.json"
#: Folders no output may go under.
FORBIDDEN_ROOTS = (Path("/proc"), Path("/sys"), Path("/dev"))


def written_by(folder: Path) -> str | None:
    """The command whose results ``folder`` holds (its ``manifest.json``'s ``command``;
    None when unknown: no manifest, or one written before manifests named it)."""
    try:
        data = json.loads((Path(folder) / MANIFEST).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    cmd = data.get("command") if isinstance(data, dict) else None
    return cmd if isinstance(cmd, str) else None


def _refuse_other_results(p: Path, command: str | None, flag: str) -> None:
    """InputError when the folder ``p`` holds another command's results."""
    other = written_by(p) if command is not None and p.is_dir() else None
    if other is not None and other != command:
        raise InputError(f"{flag} {p}: holds the results of unseen {other}, which unseen "
                         f"{command} would replace; choose another folder (or remove it)")


def check_out(out: str | os.PathLike | None, flag: str = "--out",
              command: str | None = None) -> Path:
    """Validate an output folder path before any work; returns it as a :class:`Path`.

    Refused: an empty path, a path under ``/proc``, ``/sys`` or ``/dev``, an existing
    file, an existing folder that is not writable, a missing folder whose nearest
    existing parent is not a writable folder, and (with ``command``) a folder holding
    the results of another command.
    """
    if out is None or str(out).strip() == "":
        raise InputError(f"{flag}: empty path; give the folder to write, e.g. {flag} result")
    p = Path(out)
    full = Path(os.path.abspath(p))
    real = Path(os.path.realpath(p))
    for root in FORBIDDEN_ROOTS:
        if full.is_relative_to(root) or real.is_relative_to(root):
            raise InputError(f"{flag} {p}: cannot write results under {root}; choose a folder "
                             "on a disk")
    if p.exists() or p.is_symlink():
        if not p.is_dir():
            raise InputError(f"{flag} {p}: exists and is not a folder; choose another path")
        if not os.access(p, os.W_OK | os.X_OK) or not os.access(real.parent, os.W_OK | os.X_OK):
            raise InputError(f"{flag} {p}: the folder (or the folder holding it) is not writable")
        _refuse_other_results(p, command, flag)
        return p
    parent = full.parent
    while not parent.exists():
        parent = parent.parent
    if not parent.is_dir():
        raise InputError(f"{flag} {p}: {parent} is not a folder")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise InputError(f"{flag} {p}: cannot create it, {parent} is not writable")
    return p


def _refuse_inputs(p: Path, inputs: Iterable[str | os.PathLike | None], flag: str) -> None:
    """InputError when the output folder ``p`` contains one of ``inputs``, or lies inside
    an input folder (writing there would change the input)."""
    target = Path(os.path.realpath(p))
    for i in inputs:
        if i is None or not str(i):
            continue
        src = Path(os.path.realpath(i))
        if src.is_relative_to(target):
            raise InputError(f"{flag} {p}: contains the input {i}; write the results to "
                             "another folder")
        if src.is_dir() and target.is_relative_to(src):
            raise InputError(f"{flag} {p}: lies inside the input {i}, which is never "
                             "changed; write the results to another folder")


def check_results_folder(out: str | os.PathLike | None, *, marker: str, what: str,
                         same=None, inputs: Iterable[str | os.PathLike | None] = (),
                         flag: str = "--out") -> Path:
    """Validate the folder of a resumable command (``unseen eval``, ``bench``), which
    writes into ``out`` as it goes rather than swapping it in whole: :func:`check_out`,
    then an existing ``out`` must be empty or hold ``marker`` (a file only that command
    writes) for which ``same(path)`` is true; and no input may lie inside it.  A folder
    of other files, or another command's results, is refused rather than mixed into."""
    p = check_out(out, flag)
    if p.is_dir() and any(not e.name.startswith(".") for e in p.iterdir()):
        m = p / marker
        if not m.is_file():
            raise InputError(f"{flag} {p}: holds files that {what} did not write (no {marker}); "
                             "give a new or empty folder")
        if same is not None and not same(m):
            raise InputError(f"{flag} {p}: holds the results of another command ({marker}); "
                             "give a new or empty folder")
    _refuse_inputs(p, inputs, flag)
    return p


def _files(folder: Path) -> list[Path]:
    return sorted(p for p in folder.rglob("*") if p.is_file())


def manifest_text(folder: Path, command: str | None = None) -> str:
    """``manifest.json`` of a folder: the command that wrote it (when given) and every
    file (relative path, bytes, SHA-256), sorted."""
    entries = []
    for p in _files(folder):
        rel = p.relative_to(folder).as_posix()
        if rel == MANIFEST:
            continue
        h = hashlib.sha256()
        with open(p, "rb") as fh:
            for block in iter(lambda: fh.read(1 << 20), b""):
                h.update(block)
        entries.append({"path": rel, "bytes": p.stat().st_size, "sha256": h.hexdigest()})
    head = {"format": "unseen.manifest", "version": 1}
    if command is not None:
        head["command"] = command
    return json.dumps({**head, "files": entries}, indent=1) + "\n"


_RENAME_EXCHANGE = 2
_AT_FDCWD = -100


def _exchange(a: Path, b: Path) -> bool:
    """Atomically swap two paths (Linux ``renameat2``); False where unsupported."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        fn = libc.renameat2
    except (OSError, AttributeError):
        return False
    fn.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
    if fn(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE) == 0:
        return True
    err = ctypes.get_errno()
    if err in (errno.EINVAL, errno.ENOSYS, errno.ENOTSUP, errno.EXDEV):
        return False
    raise OSError(err, os.strerror(err), str(b))


@contextlib.contextmanager
def output_folder(out: str | os.PathLike, *, inputs: Iterable[str | os.PathLike] = (),
                  flag: str = "--out", command: str | None = None) -> Iterator[Path]:
    """Lock ``out``, yield a fresh sibling folder to write into, swap it in on success.

    Parameters
    ----------
    out : the output folder (validated again by :func:`check_out`)
    inputs : paths the command reads; none may lie inside ``out``
    flag : the option name used in messages
    command : the command writing (``run``, ``synth``, ...): recorded in the manifest;
        a folder holding another command's results is refused, not replaced

    Yields
    ------
    Path
        The temporary folder; write every output there.  On an exception nothing of it
        is kept and ``out`` is left as it was.
    """
    p = check_out(out, flag, command)
    target = Path(os.path.realpath(p))
    _refuse_inputs(p, inputs, flag)
    created = not target.exists()
    try:
        target.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"{flag} {p}: cannot create the folder ({exc.strerror})") from None
    fd = os.open(target, os.O_RDONLY | os.O_DIRECTORY)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            created = False  # the other command's folder: not ours to remove
            raise InputError(f"{flag} {p}: another unseen command is writing this folder now; "
                             "wait for it to finish or choose another folder") from None
        if not created and any(target.iterdir()) and not (target / MANIFEST).is_file():
            raise InputError(f"{flag} {p}: the folder holds files unseen did not write (no "
                             f"{MANIFEST}); choose a new or empty folder")
        _refuse_other_results(target, command, flag)
        name, parent = target.name, target.parent
        for stale in parent.glob(f".{name}.tmp-*"):  # left by a killed run; we hold the lock
            shutil.rmtree(stale, ignore_errors=True)
        try:
            tmp = Path(tempfile.mkdtemp(prefix=f".{name}.tmp-", dir=parent))
        except OSError as exc:
            raise InputError(f"{flag} {p}: cannot write beside it in {parent} "
                             f"({exc.strerror})") from None
        try:
            umask = os.umask(0)
            os.umask(umask)
            os.chmod(tmp, 0o777 & ~umask)
            yield tmp
            (tmp / MANIFEST).write_text(manifest_text(tmp, command), encoding="utf-8")
            if not _exchange(tmp, target):
                old = Path(tempfile.mkdtemp(prefix=f".{name}.tmp-", dir=parent))
                os.rename(target, old / "old")
                os.rename(tmp, target)
                tmp = old
            created = False
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
    finally:
        os.close(fd)
        if created and target.is_dir() and not any(target.iterdir()):
            with contextlib.suppress(OSError):
                target.rmdir()


def out_arg(text: str) -> Path:
    """``argparse`` type of an ``--out`` option: a path, refusing the empty string (which
    ``Path("")`` would silently turn into the working folder)."""
    import argparse

    if not text.strip():
        raise argparse.ArgumentTypeError("empty path; give the folder to write, e.g. --out result")
    return Path(text)
