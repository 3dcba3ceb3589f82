"""Atomic file and directory writes, and an inter-process lock."""
from __future__ import annotations

import os
import shutil
import tempfile
from contextlib import contextmanager
from pathlib import Path

from filelock import FileLock

__all__ = ["atomic_write", "replace_dir", "locked", "recover_dir"]


def atomic_write(path: Path, data: bytes | str) -> None:
    """Write ``data`` to ``path`` through a temporary file and os.replace (never half-written)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if isinstance(data, str):
        data = data.encode()
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, 0o644)  # mkstemp makes it private; outputs are for everyone
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _backup_of(target: Path) -> Path:
    return target.with_name(f".{target.name}.previous")


def recover_dir(target: Path) -> None:
    """Finish an interrupted :func:`replace_dir`: restore the previous folder if the new one is missing."""
    target = Path(target)
    backup = _backup_of(target)
    if backup.exists():
        if target.exists():
            shutil.rmtree(backup, ignore_errors=True)
        else:
            os.replace(backup, target)


def replace_dir(staging: Path, target: Path) -> None:
    """Swap a fully written ``staging`` folder in place of ``target``.

    The old folder is kept as a hidden backup until the new one is in place, so
    an interruption at any point leaves either the old or the new folder
    (:func:`recover_dir` restores the old one if the swap was cut in half).
    """
    target, staging = Path(target), Path(staging)
    recover_dir(target)
    backup = _backup_of(target)
    if target.exists():
        os.replace(target, backup)
    os.replace(staging, target)
    shutil.rmtree(backup, ignore_errors=True)


@contextmanager
def locked(path: Path, timeout: float = 600.0):
    """Hold an exclusive inter-process lock on ``path`` (a ``.lock`` file beside it)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with FileLock(str(path.with_name(f".{path.name}.lock")), timeout=timeout):  # hidden, git-ignored
        yield
