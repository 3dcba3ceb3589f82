"""Cache folder trouble as one message naming the folder, and the lock-free load of a warm build.

* :func:`check_cache_root` refuses a cache root that is a file or sits under one.
* :func:`cache_errors` turns an ``OSError`` met while generating or compiling into the cache
  (read-only folder, folder removed meanwhile) into a :class:`~hydrogen.errors.BuildCacheError`
  that names the folder and how to fix it.
* :func:`warm_library` loads a library that is already built, for a generated folder that is
  current, without taking any lock or writing anything: a read-only cache (or a read-only
  installed package) stays usable once warm.
* :func:`folder_lock` takes a generated folder's lock, or none for a current folder that
  cannot be written (the committed code of a read-only installation: nobody regenerates it).
* :func:`build_lock_path` is what a build locks: the generated folder, or for the committed one a
  path in the cache, so builds into separate caches never wait for each other.
"""
from __future__ import annotations

import errno
import hashlib
from contextlib import ExitStack, contextmanager
from pathlib import Path

from ..codegen.generate import DEFAULT_NUMBERS
from ..errors import BuildCacheError, CompilerError, DiskFullError, HydrogenError
from ..fileio import DISK_FULL

__all__ = ["check_cache_root", "cache_errors", "warm_library", "folder_lock", "build_lock_path"]

_HINT = "set HYDROGEN_CACHE_DIR (or build(cache=...)) to a folder you can write"
_READ_ONLY = (errno.EACCES, errno.EPERM, errno.EROFS)


def check_cache_root(root: Path) -> Path:
    """``root`` if it can be a cache folder (it may not exist yet), else a BuildCacheError naming it."""
    root = Path(root)
    for p in (root, *root.parents):
        try:
            if p.exists() and not p.is_dir():
                what = "is a file" if p == root else f"sits under the file {p}"
                raise BuildCacheError(f"cache folder {root} {what}; {_HINT}")
        except OSError as exc:
            raise BuildCacheError(f"cache folder {root}: cannot inspect {p} ({exc.strerror}); {_HINT}") from None
    return root


@contextmanager
def cache_errors(root: Path):
    """Report an ``OSError`` (or a compiler failing because the cache vanished) as one message."""
    root = Path(root)
    try:
        yield
    except OSError as exc:
        if isinstance(exc, DiskFullError):  # names the file already; say where else the cache can go
            raise BuildCacheError(f"{exc} (the cache: set HYDROGEN_CACHE_DIR to a folder on another disk)") from None
        if isinstance(exc, HydrogenError):
            raise
        where = f" ({exc.filename})" if exc.filename else ""
        if exc.errno in DISK_FULL:
            raise BuildCacheError(f"cache folder {root}: the disk is full{where} ({exc.strerror}); free some space "
                                  "there or set HYDROGEN_CACHE_DIR to a folder on another disk") from None
        if not root.exists():
            raise _missing(root, where) from None
        if exc.errno in _READ_ONLY:
            raise BuildCacheError(f"cache folder {root} cannot be written{where}: {exc.strerror}; {_HINT} "
                                  "(a cache that already holds this build is used read-only)") from None
        raise BuildCacheError(f"cache folder {root}: {exc.strerror or exc}{where}; {_HINT}") from None
    except CompilerError:
        if not root.exists():
            raise _missing(root, "") from None
        raise


def _missing(root: Path, where: str) -> BuildCacheError:
    """The error for a cache folder that is not there after a failure: one that cannot be made at all
    (under /proc, say: making it again fails) is named as such, else it was removed during the build."""
    try:
        root.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        return BuildCacheError(f"cache folder {root} cannot be created ({exc.strerror or exc}); {_HINT}")
    return BuildCacheError(f"cache folder {root} was removed during the build{where}; run again (it is recreated)")


def warm_library(model, folder: Path, toolchain, cache_root: Path, loader, numbers: str = DEFAULT_NUMBERS):
    """The loaded core library already built for the current ``folder``, or None; takes no lock, writes
    nothing. ``loader(manifest)`` makes the library's loader of the other libraries (controllers);
    ``numbers``: the mode the folder must have been generated in (``codegen.generate.NUMBERS_MODES``)."""
    from ..codegen.generate import check, read_manifest
    from .compiler import build_key, cached_library
    from .library import CORE, GeneratedLibrary, group_sources

    try:
        folder = Path(folder)
        if not folder.is_dir() or check(model, folder, numbers):
            return None
        manifest = read_manifest(folder)
        sources = [folder / n for n in group_sources(manifest, CORE)]
        lib_path = cached_library(Path(cache_root) / "build" / build_key(sources, toolchain))
        if lib_path is None:
            return None
        return GeneratedLibrary(lib_path, manifest, folder, loader(manifest), numbers=model.numbers,
                                cache_root=cache_root)
    except (OSError, KeyError, TypeError, BuildCacheError):
        return None  # anything odd: the locked path decides (and reports)


def build_lock_path(folder: Path, cache_root: Path, committed: bool) -> Path:
    """The path whose lock (:func:`folder_lock`) a build of generated ``folder`` into ``cache_root``
    holds: the folder itself when the build may write it (a cache entry, a folder given by
    ``generated=``); for the committed folder, which a build only reads, a path in the cache root
    (keyed by the folder's path): each cache builds under its own lock, and the checkout's
    ``generated/`` gets no lock file."""
    folder = Path(folder)
    if not committed:
        return folder
    key = hashlib.sha256(str(folder.resolve()).encode()).hexdigest()[:16]
    return Path(cache_root) / "locks" / f"{folder.name}-{key}"


@contextmanager
def folder_lock(folder: Path, current: bool):
    """``locked(folder)``; for a ``current`` folder whose lock file cannot be created (read-only), no lock."""
    from ..fileio import locked

    with ExitStack() as stack:
        try:
            stack.enter_context(locked(folder))
        except OSError as exc:
            if not (current and exc.errno in _READ_ONLY):
                raise
        yield
