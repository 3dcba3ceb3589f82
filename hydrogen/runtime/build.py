"""``hydrogen.build``: find or generate the C for a model, compile it if needed, load it."""
from __future__ import annotations

from pathlib import Path

from ..codegen.generate import check, derivation_hash, generate_locked, read_manifest
from ..errors import BuildCacheError
from ..model import Model, load_model
from .cachedir import cache_errors, check_cache_root, folder_lock, warm_library
from .compiler import Toolchain, build_key, cache_root, cached_library, compile_library
from .extension import attach_extension
from .library import GeneratedLibrary

__all__ = ["build", "repo_generated_dir", "generated_dir_for"]


def repo_generated_dir() -> Path:
    """The committed ``generated/`` folder (``hydrogen/_generated`` when installed from a wheel)."""
    from ..resources import committed_generated_dir
    return committed_generated_dir()


def generated_dir_for(model: Model, cache: Path | None = None) -> Path:
    """Where the C for ``model`` lives: the committed folder when current, else a cache folder.

    The committed ``generated/<name>`` is used as it is when it matches the model
    and the derivation code; otherwise code is generated into the cache, keyed by
    the model hash, and the committed files are never touched by a library call.
    """
    committed = repo_generated_dir() / model.name
    if committed.is_dir() and not check(model, committed):
        return committed
    # Keyed by the derivation too: two hydrogen versions sharing one cache never fight over a folder.
    key = f"{model.name}-{model.baked_hash()[:16]}-{derivation_hash()[:8]}"
    return Path(cache or cache_root()) / "generated" / key


def _drop_broken_entry(model: Model, folder: Path) -> None:
    """A generated folder of hydrogen's own cache that it would not replace (unreadable manifest, files
    not in it) is removed, with a one-line warning, to be generated again: nobody else writes there.
    (A folder the user gave, or the committed one, is refused instead, naming the file.)"""
    import shutil
    import warnings

    from ..codegen.generate import GENERATED_KEYS, MANIFEST
    from ..errors import OutputPathError
    from ..outputs import check_replaceable_dir

    if not folder.is_dir() or folder.is_symlink():
        return
    try:
        check_replaceable_dir(folder, MANIFEST, GENERATED_KEYS, "a hydrogen generated folder", probe=False)
    except OutputPathError as exc:
        reasons = check(model, folder)
        warnings.warn(f"hydrogen: cache entry {folder} is broken ({reasons[0] if reasons else exc}); "
                      "generating it again", RuntimeWarning, stacklevel=3)
        shutil.rmtree(folder)


def build(model: Model | str | Path | None = None, *, cc: str | None = None,
          cflags: tuple | None = None, cache: Path | None = None, generated: Path | None = None,
          backend: str = "auto", progress=None):
    """Generate if stale, compile if needed, load, and return a :class:`~hydrogen.dynamics.Dynamics`.

    Parameters
    ----------
    model : Model, path or None
        The model (default: the packaged one).
    cc, cflags : str, tuple of str
        C compiler and optimisation flags (default ``$CC`` or ``cc``; ``-O2 -fPIC -std=c99``).
    cache : path
        Cache root (default ``$HYDROGEN_CACHE_DIR`` or ``~/.cache/hydrogen``).
    generated : path
        Use (and regenerate if stale) this generated folder instead of the default.
    backend : "auto", "extension" or "ctypes"
        How Python calls the compiled functions: "auto" builds and caches a CPython extension
        for direct calls and falls back to ctypes (with a warning) when it cannot be built;
        "extension" makes that an error. ``Dynamics.backend`` tells which is in use.
    progress : callable, optional
        Called with a :class:`hydrogen.progress.BuildEvent` (stage, model, detail, elapsed_s) at each
        stage: "generating"/"generated" and "compiling"/"compiled" around the long steps, then
        "built"; a library already built gives "loaded" alone.
    """
    from ..dynamics import Dynamics
    from ..progress import Reporter, c_size, generation_reported

    if not isinstance(model, Model):
        model = load_model(model)
    report = Reporter(progress, model.name)
    root = check_cache_root(Path(cache or cache_root()))
    folder = Path(generated) if generated else generated_dir_for(model, cache)
    toolchain = Toolchain(**{k: v for k, v in (("cc", cc), ("cflags", cflags)) if v is not None})
    warm = warm_library(model, folder, toolchain, root)  # no lock, no write: a read-only cache works
    if warm is not None:
        attach_extension(warm, toolchain, cache=cache, backend=backend)
        report("loaded", f"already built: {warm.path}", report.total())
        return Dynamics(model, warm)
    committed = generated is None and folder == repo_generated_dir() / model.name
    # One lock from generation through compilation: the manifest read and the sources compiled
    # are the same generation even if another process regenerates the folder meanwhile.
    with cache_errors(root), folder_lock(folder, current=committed):
        if generated is None and not committed:
            _drop_broken_entry(model, folder)
        with generation_reported(report, model, folder):
            generate_locked(model, folder)  # no-op when current
        manifest = read_manifest(folder)
        if manifest is None:
            raise BuildCacheError(f"{folder}: generated folder has no readable manifest after generation")
        sources = [folder / e["source"] for e in manifest["functions"]] \
            + [folder / d for d in manifest.get("drivers", [])]
        # Progress around the compile call, not inside it: a build another process finished is no step.
        compiles = cached_library(root / "build" / build_key(sources, toolchain)) is None
        clock = report.start()
        if compiles:
            report("compiling", f"{len(sources)} files, {c_size(sources)} of C")
        lib_path = compile_library(sources, model.name, toolchain, cache=cache)
        if compiles:
            report("compiled", lib_path.name, clock())
        try:
            lib = GeneratedLibrary(lib_path, manifest, folder)
        except BuildCacheError:
            # A cached build that does not match this runtime (other CasADi, other ABI): rebuild once.
            lib_path = compile_library(sources, model.name, toolchain, cache=cache, force=True)
            lib = GeneratedLibrary(lib_path, manifest, folder)
    attach_extension(lib, toolchain, cache=cache, backend=backend)
    steps = [s for s, done in (("generated", "generated"), ("compiled", "compiled")) if done in report.stages]
    report("built" if steps else "loaded", " + ".join(steps) if steps else f"already built: {lib.path}",
           report.total())
    return Dynamics(model, lib)
