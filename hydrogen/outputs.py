"""Output paths checked before any work: a run's results are never lost to a path that cannot be written.

Each check raises :class:`~hydrogen.errors.OutputPathError` (a ``FileExistsError`` and a
``HydrogenError``: the command line prints it as one message, exit status 2) naming the path.
"""
from __future__ import annotations

import os
import tempfile
from pathlib import Path

from .errors import OutputPathError

__all__ = ["check_output_file", "check_distinct", "check_output_dir", "check_replaceable_dir", "plot_formats", "check_plot_path",
           "require_matplotlib"]


def _nearest_existing(path: Path) -> Path:
    for p in (path, *path.parents):
        if p.exists() or p.is_symlink():
            return p
    return Path(".")


def _check_parent(path: Path, what: str) -> None:
    """The folder that will hold ``path`` exists or can be made, and a file can be created in it."""
    base = _nearest_existing(path.parent)
    if not base.is_dir():
        raise OutputPathError(f"{what} {path}: {base} is a file, so no folder can be made there")
    try:  # the honest test (permissions, read-only file systems, root): create a file there, remove it
        fd, probe = tempfile.mkstemp(dir=base, prefix=".hydrogen-probe-")
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise OutputPathError(f"{what} {path}: cannot write in {base} ({exc.strerror})") from None


def check_output_file(path, what: str = "output file") -> Path:
    """``path`` can be written as a file: not a folder, not under a file, in a writable folder."""
    path = Path(path)
    if str(path) == "" or path.name in ("", ".", ".."):
        raise OutputPathError(f"{what} {str(path)!r}: needs a file name")
    if path.is_dir():
        raise OutputPathError(f"{what} {path}: is a folder; give a file name")
    if path.exists() and not path.is_file():
        raise OutputPathError(f"{what} {path}: exists and is not a regular file")
    _check_parent(path, what)
    return path


def _same_file(a: Path, b: Path) -> bool:
    try:
        if a.exists() and b.exists():
            return os.path.samefile(a, b)
    except OSError:
        pass
    return Path(os.path.realpath(a)) == Path(os.path.realpath(b))  # through symlinked folders too


def check_distinct(outputs, inputs=()) -> None:
    """No output file is a file the command reads, nor another output's: ``outputs`` and ``inputs`` are
    ``(what, path)`` pairs (a path of None: not given). An output that would replace an input (the
    robot's description, its URDF, a log) or that two options name raises :class:`OutputPathError`
    naming both, before anything is written."""
    seen = [(what, Path(path), True) for what, path in inputs if path is not None]
    for what, path in outputs:
        if path is None:
            continue
        path = Path(path)
        for other, known, is_input in seen:
            if _same_file(path, known):
                whose = f"the {other} this command reads" if is_input else f"also {other}'s file"
                raise OutputPathError(f"{what} {path}: is {whose}; give another file name")
        seen.append((what, path, False))


def check_output_dir(path, what: str = "output folder") -> Path:
    """``path`` can be used as a folder hydrogen writes files into: not a file, not under a file, writable."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise OutputPathError(f"{what} {path}: is a file; give a folder")
    if path.is_dir():
        _check_parent(path / "x", what)
    else:
        _check_parent(path, what)
    return path


def check_replaceable_dir(path, marker: str, keys, kind: str, what: str = "output folder", *,
                          probe: bool = True, products=None, hashes: bool = False) -> Path:
    """``path`` may be replaced whole: missing, empty, or a ``kind`` folder holding only what hydrogen
    wrote there. A ``kind`` folder has a JSON ``marker`` file, an object holding every one of ``keys``;
    when it lists its files (``"files"``: name -> SHA-256), any other entry is refused (a file the user
    added would be deleted by the replacement), except the names ``products(marker data)`` returns
    (build products its own build files make, such as object files); with ``hashes``, a listed file
    edited since is refused too. A file, or a folder holding anything else, is refused: its files are
    never deleted. ``probe``: also check a file can be created beside it."""
    import hashlib
    import json

    path = Path(path)
    if path.is_symlink() or (path.exists() and not path.is_dir()):
        raise OutputPathError(f"{what} {path}: is a file (or a link), not a folder; nothing was written. "
                              "Give a new or empty folder")
    if path.is_dir():
        try:
            entries = [p.name for p in path.iterdir()]
        except OSError as exc:
            raise OutputPathError(f"{what} {path}: cannot be read ({exc.strerror})") from None
        if entries:
            broken = None
            try:
                data = json.loads((path / marker).read_text())
                ok = isinstance(data, dict) and all(k in data for k in keys)
                if not ok:
                    broken = f"{path / marker} is not {kind}'s (it lacks {', '.join(keys)})"
            except FileNotFoundError:
                ok = False
            except (OSError, ValueError) as exc:
                ok, broken = False, f"{path / marker} cannot be read ({getattr(exc, 'strerror', None) or exc})"
            if not ok:
                why = broken or f"no {marker}"
                raise OutputPathError(
                    f"{what} {path}: holds {len(entries)} entries and is not {kind} ({why}); "
                    "it would be replaced whole, so nothing was written. Give a new or empty folder")
            files = data.get("files")
            if isinstance(files, dict):
                known = set(files) | {marker} | set(products(data) if products else ())
                foreign = sorted(e for e in entries if e not in known)
                edited = sorted(n for n in files if hashes and (path / n).is_file()
                                and hashlib.sha256((path / n).read_bytes()).hexdigest() != files[n])
                if foreign:
                    fault = f"holds {_names(foreign)}, which hydrogen did not write (not listed in its {marker})"
                elif edited:
                    it = "it" if len(edited) == 1 else "them"
                    fault = f"holds {_names(edited)}, edited since hydrogen wrote {it} (hashes in its {marker})"
                if foreign or edited:
                    raise OutputPathError(f"{what} {path}: {fault}; the folder would be replaced whole, so "
                                          "nothing was written. Move those files away or give a new folder")
    if probe:
        _check_parent(path, what)
    return path


def require_matplotlib(what: str):
    """The matplotlib module; figures are an optional part of hydrogen (``pip install 'hydrogen[plot]'``),
    so without it one clear message names what needed it."""
    from .errors import HydrogenError
    try:
        import matplotlib
    except ImportError:
        raise HydrogenError(f"{what} needs matplotlib, which is not installed: pip install 'hydrogen[plot]' "
                            "(or pip install matplotlib)") from None
    return matplotlib


def _names(names: list, most: int = 5) -> str:
    shown = ", ".join(names[:most])
    return shown + (f" and {len(names) - most} more" if len(names) > most else "")


def plot_formats() -> dict:
    """File extensions matplotlib can write (without the dot) -> description."""
    require_matplotlib("--plot (a figure file)")
    from matplotlib.figure import Figure

    return dict(Figure().canvas.get_supported_filetypes())


def check_plot_path(path, what: str = "--plot") -> Path:
    """An output file whose extension names a format matplotlib writes (png, pdf, svg, ...)."""
    path = check_output_file(path, what)
    ext = path.suffix[1:].lower()
    formats = plot_formats()
    if ext not in formats:
        raise OutputPathError(f"{what} {path}: unknown figure format {path.suffix or '(no extension)'!r}; "
                              f"use one of {', '.join('.' + f for f in sorted(formats))}")
    return path
