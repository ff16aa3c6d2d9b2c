"""Every file the project writes goes through here: written whole or not at all.

`atomic_write(path)` hands out a temporary file in the target's folder; when the block ends
without an error it is flushed, fsynced and renamed over the target (the folder is fsynced
too), so a reader, a concurrent writer or a crash mid-write never sees half a file, and a
failed write (a full disk, a killed process) leaves the previous file as it was. The temporary
file is hidden (a leading dot) and removed when the write fails.

`check_output_path(path)` refuses, before any work starts, a path that is a folder, a device or
in a folder that does not exist or cannot be written: one line, as an OutputPathError. Folders
are the caller's to make.
"""
from __future__ import annotations

import os
import stat
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import BinaryIO


class OutputPathError(OSError):
    """An output path that cannot take a file (one line, for the user)."""


def check_output_path(path: str | Path) -> Path:
    """The path, if a file can be written there; OutputPathError otherwise."""
    path = Path(path)
    if path.exists():
        mode = path.stat().st_mode
        if stat.S_ISDIR(mode):
            raise OutputPathError(f"{path}: is a folder; give a file name")
        if not stat.S_ISREG(mode):
            raise OutputPathError(f"{path}: is not a regular file (a device or a pipe); give a file name")
    folder = path.parent
    if not folder.exists():
        raise OutputPathError(f"{path}: the folder {folder} does not exist")
    if not folder.is_dir():
        raise OutputPathError(f"{path}: {folder} is not a folder")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise OutputPathError(f"{path}: the folder {folder} is not writable")
    return path


@contextmanager
def atomic_write(path: str | Path) -> Iterator[BinaryIO]:
    """with atomic_write(p) as f: f.write(...)  -- p holds all of it, or what it held before."""
    path = check_output_path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            yield f
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, 0o666 & ~_UMASK)   # mkstemp makes it private; a saved file is as any other
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    _fsync_folder(path.parent)


def write_bytes(path: str | Path, data: bytes) -> None:
    with atomic_write(path) as f:
        f.write(data)


def write_text(path: str | Path, text: str) -> None:
    write_bytes(path, text.encode("utf-8"))


def _read_umask() -> int:
    mask = os.umask(0)   # the only way to read it; done once, at import, before any thread writes
    os.umask(mask)
    return mask


_UMASK = _read_umask()


def _fsync_folder(folder: Path) -> None:
    """Make the rename itself durable (where the platform allows opening a folder)."""
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)
