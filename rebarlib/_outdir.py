"""Safe writing into a results folder: one run at a time, and every result whole.

- :func:`check_out_folder` refuses, before anything is computed, an output folder that cannot be
  one (it exists as a file, or lies below a file) and result folders that exist as files.
- :func:`locked` holds an exclusive lock on the folder while a run writes to it: a second run
  into the same folder stops at once with an error saying which process holds it. The lock is
  an ``fcntl`` lock on ``OUT/.rebar.lock``, released by the system when the process ends, so a
  crashed run leaves no stale lock behind.
- :func:`write_folder_atomically` writes a result's files into a temporary folder inside ``OUT``
  and renames it into place, so a result folder is always the whole output of one run; an
  earlier result is replaced only once the new one is complete. Left-overs of a run that was
  killed half-way are tidied up by the next run that takes the lock (:func:`tidy`).
"""

from __future__ import annotations

import contextlib
import os
import shutil
import socket
from pathlib import Path

from ._checks import RebarInputError

__all__ = [
    "LOCK_NAME",
    "check_out_folder",
    "locked",
    "write_folder_atomically",
    "write_file_atomically",
    "tidy",
    "reserved_name",
]

LOCK_NAME = ".rebar.lock"
_TMP, _OLD = ".tmp-", ".old-"


def reserved_name(name: str) -> bool:
    """Whether a result folder called ``name`` would collide with the folder's own files."""
    return name == LOCK_NAME or name.startswith((_TMP, _OLD))


def check_out_folder(out: Path, names=(), *, option: str = "--out") -> None:
    """Refuse an output folder that cannot hold the results, before anything is computed.

    ``out`` must be a folder or not exist, with no file among its parents; ``out/<name>`` for
    each of ``names`` must be a folder or not exist.
    """
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise RebarInputError(f"{option} {out}: exists and is not a folder")
    for parent in out.absolute().parents:
        if parent.exists() and not parent.is_dir():
            raise RebarInputError(f"{option} {out}: {parent} is a file, so no folder can be made below it")
    for name in names:
        target = out / name
        if reserved_name(name):
            raise RebarInputError(
                f"{option} {out}: a result folder cannot be called {name!r} "
                "(the name of the folder's lock or temporary files)"
            )
        if target.exists() and not target.is_dir():
            raise RebarInputError(
                f"{option} {out}: {target} exists and is not a folder; move it away or choose another --out"
            )


def _holder(path: Path) -> str:
    try:
        text = path.read_text(encoding="utf-8").strip()
    except OSError:
        return ""
    return f" ({text})" if text else ""


@contextlib.contextmanager
def locked(out: Path, *, option: str = "--out"):
    """Hold ``out``'s lock (creating ``out``) for the body; :class:`RebarInputError` if taken."""
    out = Path(out)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise RebarInputError(f"{option} {out}: cannot create the folder ({exc.strerror})") from None
    path = out / LOCK_NAME
    fd = _acquire(path, option=option, out=out)
    try:
        os.ftruncate(fd, 0)
        os.write(fd, f"pid {os.getpid()} on {socket.gethostname()}".encode())
        tidy(out)
        yield out
    finally:
        with contextlib.suppress(OSError):
            os.unlink(path)
        os.close(fd)


def _acquire(path: Path, *, option: str, out: Path) -> int:
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX: an exclusive create stands in
        return _acquire_by_create(path, option=option, out=out)
    while True:
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError as exc:
            raise RebarInputError(f"{option} {out}: cannot write into the folder ({exc.strerror})") from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(fd)
            raise RebarInputError(
                f"{option} {out}: another rebar run is writing into this "
                f"folder{_holder(path)}; wait for it to end or choose another "
                "--out"
            ) from None
        # the holder before us may have removed the file between our open and our lock: the
        # lock is only ours if it is on the file that is there now
        try:
            same = os.path.samestat(os.fstat(fd), os.stat(path))
        except FileNotFoundError:
            same = False
        if same:
            return fd
        os.close(fd)


def _acquire_by_create(path: Path, *, option: str, out: Path) -> int:  # pragma: no cover
    try:
        return os.open(path, os.O_RDWR | os.O_CREAT | os.O_EXCL, 0o644)
    except FileExistsError:
        raise RebarInputError(
            f"{option} {out}: another rebar run is writing into this folder{_holder(path)} (if none is, delete {path})"
        ) from None


def tidy(out: Path) -> None:
    """Remove what a killed run left in ``out``: temporary result folders, and put back an
    earlier result that was moved aside and never replaced. Call only while holding the lock."""
    for p in Path(out).iterdir():
        if p.name.startswith(_TMP):
            _remove(p)
        elif p.name.startswith(_OLD) and p.is_dir():
            name = p.name[len(_OLD) :].rsplit("-", 1)[0]
            if name and not (Path(out) / name).exists():
                os.rename(p, Path(out) / name)
            else:
                _remove(p)


def _remove(p: Path) -> None:
    if p.is_dir() and not p.is_symlink():
        shutil.rmtree(p, ignore_errors=True)
    else:
        with contextlib.suppress(OSError):
            p.unlink()


def write_folder_atomically(out: Path, name: str, files: dict) -> Path:
    """Write ``files`` (file name -> str) as the folder ``out/name``, whole or not at all.

    The files are written into ``out/.tmp-<name>-<pid>`` and the folder is renamed into place;
    an existing ``out/name`` is first renamed aside and removed once the new one is in place.
    """
    out = Path(out)
    final = out / name
    tmp = out / f"{_TMP}{name}-{os.getpid()}"
    _remove(tmp)
    tmp.mkdir()
    try:
        for fname, text in files.items():
            with open(tmp / fname, "w", encoding="utf-8", newline="") as f:
                f.write(text)
                f.flush()
                os.fsync(f.fileno())
        old = None
        if final.exists() or final.is_symlink():
            old = out / f"{_OLD}{name}-{os.getpid()}"
            _remove(old)
            os.rename(final, old)
        os.rename(tmp, final)
    except BaseException:
        _remove(tmp)
        raise
    if old is not None:
        _remove(old)
    return final


def write_file_atomically(path: Path, text: str) -> Path:
    """Write ``text`` to ``path`` through a temporary file beside it and a rename."""
    path = Path(path)
    tmp = path.with_name(f"{_TMP}{path.name}-{os.getpid()}")
    with open(tmp, "w", encoding="utf-8", newline="") as f:
        f.write(text)
    os.replace(tmp, path)
    return path
