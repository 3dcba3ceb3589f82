"""Atomic file and directory writes, and an inter-process lock."""
from __future__ import annotations

import errno
import os
import shutil
import sys
import tempfile
from contextlib import contextmanager
from pathlib import Path

from filelock import FileLock

__all__ = ["atomic_write", "write_file", "writing", "replace_dir", "locked", "recover_dir", "remove_stale_staging",
           "lock_timeout", "DISK_FULL"]


#: errno values that mean "the disk is full" (no space, or the quota is used up)
DISK_FULL = (errno.ENOSPC, errno.EDQUOT)


@contextmanager
def writing(path: Path):
    """Turn a full disk met while writing ``path`` into one DiskFullError naming the file (the bare
    OSError says "[Errno 28] No space left on device" without saying where)."""
    from .errors import DiskFullError, HydrogenError

    try:
        yield
    except OSError as exc:
        if exc.errno not in DISK_FULL or isinstance(exc, HydrogenError):
            raise
        raise DiskFullError(f"{path}: cannot be written, the disk is full ({exc.strerror or 'no space left'} "
                            f"on the file system holding {Path(path).parent}); free some space there or write "
                            "elsewhere") from None


def _write_bytes(path, data: bytes, sync: bool = False) -> None:
    with open(path, "wb") as fh:
        fh.write(data)
        if sync:
            fh.flush()
            os.fsync(fh.fileno())


def write_file(path: Path, data: bytes | str) -> None:
    """Write ``data`` to a new file ``path`` (inside a staging folder: the folder swap is the atomic step)."""
    with writing(path):
        _write_bytes(path, data.encode() if isinstance(data, str) else data)


def atomic_write(path: Path, data: bytes | str) -> None:
    """Write ``data`` to ``path`` through a temporary file and os.replace (never half-written)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if isinstance(data, str):
        data = data.encode()
    with writing(path):
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
        os.close(fd)
        try:
            _write_bytes(tmp, data, sync=True)
            os.chmod(tmp, 0o644)  # mkstemp makes it private; outputs are for everyone
            os.replace(tmp, path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise


def _backup_of(target: Path) -> Path:
    return target.with_name(f".{target.name}.previous")


def remove_stale_staging(target: Path, keep: Path | None = None) -> list:
    """Remove the hidden staging folders ``.<name>.new-*`` that an interrupted writer of ``target``
    (killed before its swap) left beside it. Call with the lock of ``target`` held: a staging
    folder lives only while its writer holds that lock, so any found then is stale."""
    target = Path(target)
    removed = []
    try:
        stale = list(target.parent.glob(f".{target.name}.new-*"))
    except OSError:
        return removed
    for path in stale:
        if keep is not None and path.name == Path(keep).name:
            continue  # the staging folder being swapped in right now
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path, ignore_errors=True)
            removed.append(path)
    return removed


def recover_dir(target: Path, keep: Path | None = None) -> None:
    """Finish an interrupted :func:`replace_dir`: restore the previous folder if the new one is missing,
    and remove staging folders (but ``keep``) left by a writer that was killed (callers hold
    ``locked(target)``)."""
    target = Path(target)
    remove_stale_staging(target, keep)
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
    recover_dir(target, keep=staging)
    backup = _backup_of(target)
    if target.exists():
        os.replace(target, backup)
    os.replace(staging, target)
    shutil.rmtree(backup, ignore_errors=True)


#: Longest wait for a lock another process holds, s (``$HYDROGEN_LOCK_TIMEOUT`` overrides).
LOCK_TIMEOUT = 600.0
#: After this long waiting, say on stderr who holds the lock, s.
LOCK_NOTICE_AFTER = 1.0


def lock_timeout() -> float:
    """``$HYDROGEN_LOCK_TIMEOUT`` (seconds) if set to a number > 0, else :data:`LOCK_TIMEOUT`."""
    try:
        value = float(os.environ.get("HYDROGEN_LOCK_TIMEOUT", ""))
    except ValueError:
        return LOCK_TIMEOUT
    return value if value > 0 and value == value else LOCK_TIMEOUT


def _owner_file(lock_file: Path) -> Path:
    # Not "<lock>.pid": nothing but the lock itself may start with ".<name>." beside a folder.
    return lock_file.with_name(lock_file.name[:-len(".lock")] + "-lock.owner")


@contextmanager
def locked(path: Path, timeout: float | None = None):
    """Hold an exclusive inter-process lock on ``path`` (a ``.lock`` file beside it).

    The holder writes its PID into a hidden ``-lock.owner`` file beside the lock. A
    process that waits more than a second says so on stderr ("waiting for the build
    lock on FOLDER (held by PID n)"); after ``timeout`` s (default :func:`lock_timeout`)
    it gives up with a :class:`~hydrogen.errors.BuildCacheError`.
    """
    from filelock import Timeout

    from .errors import BuildCacheError

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    timeout = lock_timeout() if timeout is None else float(timeout)
    lock_file = path.with_name(f".{path.name}.lock")  # hidden, git-ignored
    owner = _owner_file(lock_file)
    lock = FileLock(str(lock_file))
    try:
        lock.acquire(timeout=min(LOCK_NOTICE_AFTER, timeout))
    except Timeout:
        try:
            holder = f"PID {int(owner.read_text().split()[0])}"
        except (OSError, ValueError, IndexError):
            holder = "another process"
        print(f"hydrogen: waiting for the build lock on {path} (held by {holder}; "
              f"giving up after {timeout:g} s)", file=sys.stderr, flush=True)
        try:
            lock.acquire(timeout=max(timeout - LOCK_NOTICE_AFTER, 0.0))
        except Timeout:
            raise BuildCacheError(
                f"{path}: gave up waiting {timeout:g} s for its lock {lock_file} (held by {holder}). "
                "Wait for that process to finish or stop it; set HYDROGEN_LOCK_TIMEOUT (seconds) to wait "
                "longer") from None
    try:
        try:
            owner.write_text(f"{os.getpid()}\n")
        except OSError:
            pass  # the PID is a courtesy for waiters; the lock itself is held
        yield
    finally:
        try:
            owner.unlink(missing_ok=True)
        except OSError:
            pass
        lock.release()
