"""``hydrogen.build``: find or generate the C for a model, compile it if needed, load it."""
from __future__ import annotations

import hashlib
import threading
from contextlib import contextmanager
from pathlib import Path

from ..codegen.generate import (DEFAULT_NUMBERS, check, check_numbers_mode, derivation_hash, generate_locked, model_kinds,
                                missing_controllers, read_manifest, structure_hash)
from ..errors import BuildCacheError
from ..model import Model, load_model
from .cachedir import build_lock_path, cache_errors, check_cache_root, folder_lock, warm_library
from .compiler import (Toolchain, build_key_of, cache_root, cached_library, cancel_precompiles, compile_libraries,
                       hand_off_precompiles, included_headers, objects_stored, precompile)
from .extension import attach_extension, build_extension, unavailable_reason
from .library import CORE, GeneratedLibrary, group_name, group_of, group_sources

__all__ = ["build", "default_dynamics", "dynamics_for", "DEFAULT_DYNAMICS", "as_model", "repo_generated_dir", "generated_dir_for", "library_name",
           "generation_reported"]


def repo_generated_dir() -> Path:
    """The committed ``generated/`` folder (``hydrogen/_generated`` when installed from a wheel)."""
    from ..resources import committed_generated_dir
    return committed_generated_dir()


def generated_dir_for(model: Model, cache: Path | None = None, numbers: str = DEFAULT_NUMBERS,
                      controllers=None) -> Path:
    """Where the C for ``model`` lives: the committed folder when current and holding
    ``controllers`` (names; None: those the model lists), else a cache folder.

    The committed ``generated/<name>`` is used as it is when it matches the model
    and the derivation code; otherwise code is generated into the cache, keyed by
    the model hash, and the committed files are never touched by a library call.
    With ``numbers="inputs"`` (``codegen.generate.NUMBERS_MODES``) the folder is keyed by the
    structure hash: every description that differs from ``model`` in numbers only shares it.
    """
    committed = repo_generated_dir() / model.name
    if committed.is_dir() and not check(model, committed, numbers) and not missing_controllers(
            read_manifest(committed), model.controllers if controllers is None else controllers):
        return committed
    # Keyed by the functions' derivation code too: two hydrogen versions that derive other functions never
    # share a folder; two that differ in a controller's module, the plant's blocks or the loop drivers'
    # code share it, each generating those parts again alone when it finds them another's.
    shape = model.baked_hash() if numbers == "constants" else "s" + structure_hash(model)
    key = f"{model.name}-{shape[:16]}-{derivation_hash(model_kinds(model))[:8]}"
    return Path(cache or cache_root()) / "generated" / key


@contextmanager
def generation_reported(report, model, folder, force: bool = False, controllers=None, numbers=None):
    """Around a generation call: "generating" and "generated" (to ``report``, a
    :class:`~hydrogen.progress.Reporter`) when ``folder`` is stale for ``model``, lacks one of
    ``controllers`` (names; None: those the model lists) or ``force`` regenerates it (a current
    folder is no step: nothing reported); ``numbers``: the mode the folder must be in (None: its own).
    Yields the callable a generation calls when what it meant to derive alone is derived whole after
    all (``generate(whole=...)``): a "generating" line then says so. Outside the generator, whose
    source is part of the derivation hash."""
    from ..codegen.generate import stale_parts
    from ..progress import c_size

    need = model.controllers if controllers is None else controllers
    parts = None if force else stale_parts(model, Path(folder), numbers, need)
    stale = parts is None or bool(parts)
    missing = parts.get("missing", ()) if parts else ()
    clock = report.start()
    if parts is None:
        report("generating", "deriving the model (SymPy) and writing C for each function")
    elif parts.get("controllers") or parts.get("plant") or missing:
        what = [*dict.fromkeys([*parts.get("controllers", ()), *missing]), *(["the plant"] if parts.get("plant") else [])]
        report("generating", f"deriving {', '.join(what)} (SymPy) and writing C for each function")
    elif parts.get("drivers"):
        report("generating", "rendering the loop drivers (their code changed)")
    before = {e["name"]: e for e in (read_manifest(Path(folder)) or {}).get("functions", ())} \
        if parts is not None else {}

    def whole():
        report("generating", "deriving the model (SymPy) and writing C for each function: the part derived "
                             "alone met other description numbers than the folder's")
    yield whole
    if stale:
        manifest = read_manifest(Path(folder)) or {}
        functions = manifest.get("functions", ())
        again = [e for e in functions if before.get(e["name"]) != e]  # all of them after a whole generation
        if before and len(again) < len(functions):  # a part generated alone: say which
            sources = [Path(folder) / e["source"] for e in again]
            done = [f"{len(again)} of {len(functions)} functions again, {c_size(sources)} of C"] if again else []
            done += ["the loop drivers rendered again"] if parts.get("drivers") else []
            report("generated", "; ".join(done) or "nothing written", clock())
        else:
            report("generated", f"{len(functions)} functions, {c_size(Path(folder).glob('*.c'))} of C", clock())


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


class _Loader:
    """The libraries of one generated folder: found in the cache or compiled, each on its first use.

    ``loader(group, force)`` is what :class:`~hydrogen.runtime.library.GeneratedLibrary` calls
    for a library it has not loaded: the cached build when there is an intact one (no lock taken:
    a read-only cache works once warm), else a compile under the folder's lock. The sources are
    checked against the manifest the library was loaded with, so a folder regenerated meanwhile
    is never compiled into it.
    """

    def __init__(self, model, folder, manifest, toolchain, root, cache, committed, report, quick=False):
        self.model, self.folder, self.manifest = model, Path(folder), manifest
        self.toolchain, self.root, self.cache, self.committed, self.report = \
            toolchain, Path(root), cache, committed, report
        self.lock = build_lock_path(self.folder, self.root, committed)
        self.quick = quick
        self.unoptimized = {}  # group -> the unoptimized library this process compiled for it (quick)

    def _contents(self, group: str) -> list:
        """``[(path, bytes)]`` of the group's sources, each read once and checked against the manifest,
        and so are the headers of the folder they include (which the library's key covers)."""
        recorded = self.manifest.get("files", {})
        out = []
        for name in group_sources(self.manifest, group):
            path = self.folder / name
            data = path.read_bytes() if path.is_file() else None
            self._check(path, data, recorded.get(name))
            for header, text in (included_headers(path, data) or [])[1:]:
                if header in recorded:
                    self._check(self.folder / header, text, recorded[header])
            out.append((path, data))
        return out

    @staticmethod
    def _check(path: Path, data, sha: str | None) -> None:
        if data is None or hashlib.sha256(data).hexdigest() != sha:
            raise BuildCacheError(f"{path}: differs from the generated folder this build loaded (generated "
                                  "again or edited since); build again (hydrogen.build) to use the new code")

    def sources(self, group: str) -> list:
        return [p for p, _ in self._contents(group)]

    def cached(self, group: str):
        """The intact cached library of ``group`` or None (nothing written, no lock)."""
        return cached_library(self.root / "build" / build_key_of(self._contents(group), self.toolchain))

    def __call__(self, group: str, force: bool = False) -> Path:
        if not force:
            with cache_errors(self.root):
                lib = self.cached(group)
            if lib is not None:
                return lib
            if group in self.unoptimized:
                return self.unoptimized[group]
        with cache_errors(self.root), folder_lock(self.lock, current=self.committed):
            return self.compile([group], force)[0]

    def compile(self, groups: list, force: bool = False) -> list:
        """The libraries of ``groups``, compiled in one pool where not cached (the caller holds the
        folder's lock); "compiling" and "compiled" reported around a compile. With ``quick``, a library
        whose optimized objects are not all in the store yet compiles unoptimized
        (:meth:`~hydrogen.runtime.compiler.Toolchain.unoptimized`), after the optimized compiles this
        process started are handed off to finish on their own for the next build."""
        from ..progress import c_size

        contents = {g: self._contents(g) for g in groups}  # each source read and checked once
        sources = {g: [path for path, _ in contents[g]] for g in groups}

        def cached(g, toolchain):
            return cached_library(self.root / "build" / build_key_of(contents[g], toolchain))

        new = [g for g in groups if force or cached(g, self.toolchain) is None]
        # unoptimized where the store can hold the optimized objects and lacks some (they are
        # compiled in the background)
        slow = [g for g in new if self.quick and not force
                and objects_stored(sources[g], self.toolchain, self.cache) is False]
        quick = self.toolchain.unoptimized()
        # what is compiled now: not an unoptimized library an earlier quick build left (loaded as it is)
        new = [g for g in new if g not in slow or cached(g, quick) is None]
        clock = self.report.start()
        if new:
            files = [s for g in new for s in sources[g]]
            what = "" if new == [CORE] else f"{', '.join(new)}: "
            now = [g for g in slow if g in new]
            self.report("compiling", f"{what}{len(files)} files, {c_size(files)} of C"
                        + (f"; unoptimized (-O0): {', '.join(now)}" if now else ""))
        if slow:  # the optimized objects: those not started yet start now, and all finish without this process
            precompile([s for g in slow for s in sources[g]], self.toolchain, self.cache)
            hand_off_precompiles(keep=quick)  # the unoptimized ones started early are this build's own
        tiers = [[g for g in groups if g not in slow], slow]
        made = {}
        for tier, toolchain, prefer in ((tiers[0], self.toolchain, None), (tiers[1], quick, self.toolchain)):
            if tier:  # an unoptimized library links the optimized objects already in the store
                made.update(zip(tier, compile_libraries([(sources[g], library_name(self.model.name, g)) for g in tier],
                                                        toolchain, cache=self.cache, force=force, prefer=prefer)))
        self.unoptimized.update({g: made[g] for g in slow})
        paths = [made[g] for g in groups]
        if new:
            self.report("compiled", ", ".join(p.name for g, p in zip(groups, paths) if g in new)
                        + ("; the optimized build goes on in the background for the next build"
                           if any(g in new for g in slow) else ""),
                        clock())
        return paths


def library_name(model_name: str, group: str) -> str:
    """The file name stem of library ``group`` of a model: ``<model>`` for the core, ``<model>_<controller>``."""
    return model_name if group == CORE else f"{model_name}_{group.replace('-', '_')}"


def _check_controllers(controllers, model: Model) -> tuple:
    from ..controllers import CONTROLLERS
    from ..errors import ScenarioError

    if isinstance(controllers, str):
        controllers = (controllers,)
    controllers = tuple(dict.fromkeys(controllers))
    unknown = [c for c in controllers if c not in CONTROLLERS]
    if unknown:
        raise ScenarioError(f"unknown controller '{unknown[0]}'; choose one of {', '.join(CONTROLLERS)}")
    unlisted = [c for c in controllers if c not in model.controllers]
    if unlisted:
        raise ScenarioError(model.not_listed(unlisted[0]))
    return controllers



def build(model: Model | str | Path | None = None, *, cc: str | None = None,
          cflags: tuple | None = None, cache: Path | None = None, generated: Path | None = None,
          backend: str = "auto", progress=None, controllers=None, numbers: str = DEFAULT_NUMBERS,
          gains=None, quick: bool = False):
    """Generate if stale, compile if needed, load, and return a :class:`~hydrogen.dynamics.Dynamics`.

    The compiled code is one core library (kinematics, rigid body, hydraulics, plant, the C loop)
    and per controller one library for each variant a run calls on its own (the full controller
    with its step; the lean one; each variant's rates in a library of their own, which only the Python
    engine calls: :func:`~hydrogen.runtime.library.function_groups`). A
    build compiles the core and, of each of ``controllers``, the variant the description's gains run;
    any other library (the other variant, another controller) is compiled (or found in the cache)
    the first time one of its functions is used, e.g. by a run with other gains.

    Parameters
    ----------
    model : Model, path or None
        The model (default: the packaged one).
    cc, cflags : str, tuple of str
        C compiler and flags (default ``$CC`` or ``cc``; the flags of
        :meth:`~hydrogen.runtime.compiler.Toolchain.flags`); ``cflags`` replaces them.
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
        "built"; a library already built gives "loaded" alone. A controller's library compiled
        later, on its first use, gives "compiling"/"compiled" then.
    controllers : sequence of str, optional
        Controllers (names, as ``simulate`` takes them) whose library is compiled with the core, in
        the same pool of compilers, and loaded now: the variant the description's own gains run (the
        lean one when they set no composite rate, else the full one). Where the C is generated now
        (a new structure), only these controllers are derived, and a folder that lacks one gets it
        added (derived alone); a controller the build does not hold is an error naming the build's
        controllers when it is run. None (the default): the folder holds every controller the
        description lists (a folder that lacks one gets it), none compiled before its first use.
        An empty sequence: the core alone (kinematics, rigid body, hydraulics, plant).
    gains : dict, optional
        By controller, gains a run will set over the description's (a scenario's own): they decide
        which variant of the controller is compiled with the core.
    numbers : "inputs" (default) or "constants"
        "inputs" generates every function with the description's numbers as an input the runtime
        fills from the description (``Model.numbers()``), as the committed code is: a description
        that differs in numbers only (a mass, a pin point, an area, a pressure) loads the same
        compiled libraries, with no generation and no compile; the C loop, the export and the
        FMU take the numbers as parameters. "constants" folds them into the C (a library per
        set of numbers).
    quick : bool
        For a first run right after a structural edit: a library this build must compile whose
        optimized objects are not ready is compiled unoptimized (-O0: a controller's long step compiles
        several times faster; the same numbers bit for bit; each call slower), and the optimized
        compiles go on in the background, outliving this process, so that the next build links them.
        Only with hydrogen's own compiler flags (``cflags`` None: other flags may round otherwise at
        -O0) and where the cache's object store can hold the objects; else the build is optimized.
        The returned dynamics keep the unoptimized libraries (``dyn.library.unoptimized()`` names
        them): for many runs, build again once the optimized objects are in.
    """
    from ..dynamics import Dynamics
    from ..progress import Reporter

    import os

    from ..errors import InputError

    for name, folder_arg in (("cache", cache), ("generated", generated)):
        if folder_arg is not None and not isinstance(folder_arg, (str, os.PathLike)):
            raise InputError(f"build: {name} must be a folder's path (str or pathlib.Path) or None, got "
                             f"{type(folder_arg).__name__} {folder_arg!r}"[:300])
    if not isinstance(model, Model):
        model = load_model(model)
    report = Reporter(progress, model.name)
    # what the folder must hold (None: every controller the description lists; (): the core only),
    # and the controllers whose library is compiled now
    need = model.controllers if controllers is None else _check_controllers(controllers, model)
    controllers = () if controllers is None else need
    check_numbers_mode(numbers)
    root = check_cache_root(Path(cache or cache_root()))
    folder = Path(generated) if generated else generated_dir_for(model, cache, numbers, need)
    toolchain = Toolchain(**{k: v for k, v in (("cc", cc), ("cflags", cflags)) if v is not None})
    quick = quick and toolchain.default_flags()  # other flags may round otherwise at -O0: built as given
    committed = generated is None and folder == repo_generated_dir() / model.name

    made = []  # the loader the warm library was given (this build compiles through it)

    def loader(manifest):
        made.append(_Loader(model, folder, manifest, toolchain, root, cache, committed, report, quick))
        return made[-1]

    groups = _own_variants(model, controllers, gains)
    extension = None  # the extension's compile, started beside the libraries' where they compile
    lib = warm_library(model, folder, toolchain, root, loader, numbers)  # no lock, no write: a read-only cache works
    if lib is not None and missing_controllers(lib.manifest, need):
        lib = None  # the folder holds other controllers: theirs are added under the lock
    if lib is not None:
        missing = [g for g in groups if _cached_or_none(made[-1], g) is None]
        if missing:
            with cache_errors(root), folder_lock(made[-1].lock, current=committed):
                made[-1].compile(missing)
    else:
        try:
            lib, extension = _generate_and_compile(model, folder, root, committed, generated, need, numbers, groups,
                                                   toolchain, cache, backend, report, loader, quick)
        finally:
            cancel_precompiles()  # whatever this build started and did not use (it failed): not run at exit
    if extension is not None:
        extension.join()  # built (or failed: attach_extension meets the failure again and reports it)
    ext_toolchain, prefer = _extension_toolchains(toolchain, quick)
    attach_extension(lib, ext_toolchain, cache=cache, backend=backend, prefer=prefer)
    for g in groups:
        lib.load(g)
    steps = [s for s, done in (("generated", "generated"), ("compiled", "compiled")) if done in report.stages]
    report("built" if steps else "loaded", " + ".join(steps) if steps else f"already built: {lib.path}",
           report.total())
    return Dynamics(model, lib)


def _generate_and_compile(model, folder, root, committed, generated, need, numbers, groups, toolchain, cache, backend,
                          report, loader, quick=False):
    """:func:`build`'s generation and compile where no warm library serves: ``(library, the extension's
    compile thread or None)``."""
    # One lock from generation through compilation: the manifest read and the sources compiled
    # are the same generation even if another process regenerates the folder meanwhile. The
    # committed folder is only read (under this cache's lock, not the folder's: no generation).
    with cache_errors(root), folder_lock(build_lock_path(folder, root, committed), current=committed):
        if generated is None and not committed:
            _drop_broken_entry(model, folder)
            _start_from_committed(model, folder, numbers)
        if committed:  # whole (generate --check): it holds every controller
            _still_current(model, folder, numbers)
        else:
            # each source of a library this build compiles starts compiling as soon as it is
            # written, on the cores the derivation leaves (the core while controllers derive)
            early = _Precompile({CORE, *groups}, toolchain, cache, quick)
            with generation_reported(report, model, folder, controllers=need, numbers=numbers) as whole:
                # no-op when current; a build for some controllers derives only theirs
                generate_locked(model, folder, numbers=numbers, controllers=need, written=early, first=early.wanted,
                                whole=whole)
        manifest = read_manifest(folder)
        if manifest is None:
            raise BuildCacheError(f"{folder}: generated folder has no readable manifest after generation")
        load = loader(manifest)
        extension = _extension_started(manifest, *_extension_toolchains(toolchain, quick), cache, backend)
        try:
            # Progress around the compile call, not inside it: a build another process finished is no step.
            core = load.compile([CORE, *groups])[0]
            try:
                lib = GeneratedLibrary(core, manifest, folder, load, numbers=model.numbers, cache_root=root)
            except BuildCacheError:
                # A cached build that does not match this runtime (other CasADi, other ABI): rebuild once.
                lib = GeneratedLibrary(load.compile([CORE], force=True)[0], manifest, folder, load,
                                       numbers=model.numbers, cache_root=root)
        except BaseException:
            if extension is not None:
                extension.join()  # not left to be killed mid-compile at exit
            raise
    return lib, extension


def _start_from_committed(model, folder: Path, numbers: str) -> None:
    """A cache folder not generated yet starts as a copy of the committed folder of the same
    description where that is current but for what a generation derives alone (a controller's
    functions, the plant's, the loop drivers: an edit of those blocks' code): the generation then
    derives only those. The caller holds the folder's lock."""
    import shutil
    import tempfile

    from ..codegen.generate import stale_parts
    from ..fileio import replace_dir

    committed = repo_generated_dir() / model.name
    if folder.exists() or not committed.is_dir() or stale_parts(model, committed, numbers) is None:
        return
    folder.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=f".{folder.name}.new-", dir=folder.parent))
    try:
        for p in committed.iterdir():
            if not p.name.startswith("."):
                shutil.copy2(p, staging / p.name)
        staging.chmod(0o755)
        replace_dir(staging, folder)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise


def _still_current(model, folder: Path, numbers: str) -> None:
    """The committed ``folder`` found current a moment ago is still so, else a BuildCacheError (it was
    regenerated meanwhile, by ``hydrogen generate``): a build never writes it."""
    reasons = check(model, folder, numbers)
    if reasons:
        raise BuildCacheError(f"{folder}: changed since this build chose it ({reasons[0]}); build again")


def _own_variants(model: Model, controllers: tuple, gains=None) -> list:
    """The library each controller runs with the description's own gains (and ``gains[c]`` over
    them, a scenario's): its lean variant where it has one and no composite rate is set (the
    default, the paper's laws), else its full one. A run with other gains compiles the other
    variant on its first use."""
    from ..controllers import LEAN, has_lean
    from ..controllers.common import COMPOSITE_RATES, runs_lean

    out = []
    for c in controllers:
        g = {**{r: 0.0 for r in COMPOSITE_RATES}, **((model.gains or {}).get(c) or {}), **((gains or {}).get(c) or {})}
        out.append(group_name(c, LEAN if has_lean(c, model) and runs_lean(g) else None))
    return out


class _Precompile:
    """What a generation calls with each C source it writes (``written(name, path)``; ``wanted``, its
    ``first``: these are written first): the sources of ``groups`` (libraries) start compiling into
    the object store at once
    (:func:`~hydrogen.runtime.compiler.precompile`). An optimisation only: a failure to start
    (no compiler) stops it quietly, and the library's compile meets the failure and reports it."""

    def __init__(self, groups, toolchain, cache, quick=False):
        self.groups, self.toolchain, self.cache, self.on = set(groups), toolchain, cache, True
        # a quick build: a controller's sources also unoptimized, before any other compile waiting (its
        # library is compiled so when the derivation ends; the core's optimized objects are ready by then)
        self.quick = toolchain.unoptimized() if quick else None

    def wanted(self, name) -> bool:
        """Whether function ``name`` (None: a loop driver) is in one of the libraries compiled."""
        return (CORE if name is None else group_of(name)) in self.groups

    def __call__(self, name, path) -> None:
        if self.on and self.wanted(name):
            try:
                if self.quick is not None and name is not None and group_of(name) != CORE:
                    precompile([path], self.quick, self.cache, first=True)
                precompile([path], self.toolchain, self.cache)
            except Exception:  # noqa: BLE001 - see the class docstring
                self.on = False


def _extension_toolchains(toolchain, quick: bool) -> tuple:
    """``(toolchain, prefer)`` of the Python extension: a quick build takes the optimized one where it
    is cached, else compiles it unoptimized (a small source; the C loop does not call it)."""
    return (toolchain.unoptimized(), toolchain) if quick else (toolchain, None)


def _extension_started(manifest, toolchain, prefer, cache, backend):
    """The Python extension's compile started on a thread of its own (it needs no library), or None
    where it will not be built; its failure is left to attach_extension, which reports it."""
    if backend == "ctypes" or unavailable_reason() is not None:
        return None

    def build():
        try:
            build_extension(manifest, toolchain, cache, prefer=prefer)
        except Exception:  # noqa: BLE001 - see the docstring
            pass

    thread = threading.Thread(target=build, name="hydrogen-extension", daemon=True)
    thread.start()
    return thread


def _cached_or_none(load, group):
    try:
        return load.cached(group)
    except (OSError, BuildCacheError):
        return None


def as_model(model) -> Model:
    """``model`` itself (a Model), or the description it names (a built-in name, a path; None: the
    default robot), loaded; anything else is a ScenarioError naming what was given."""
    import os

    from ..errors import ScenarioError

    if isinstance(model, Model):
        return model
    if model is None or isinstance(model, (str, os.PathLike)):
        return load_model(model)
    raise ScenarioError(f"model must be a hydrogen.Model, a path to a model TOML file or None, "
                        f"got {type(model).__name__} {model!r}"[:300])


#: The libraries :func:`default_dynamics` built in this process, by (baked model hash, numbers mode).
DEFAULT_DYNAMICS = {}


def default_dynamics(model=None, progress=None, controller=None, numbers=None, gains=None):
    """Compiled dynamics for ``model`` (a Model, a built-in name, a path or None for the default):
    the library is built once per process, baked model and ``numbers`` mode (:func:`build`'s; None:
    its default); the returned Dynamics carries this very model, so its runtime parameters (θ, γ,
    bounds) are used. ``progress``: the build's callback (called only when this process builds or
    loads it). ``controller``: the controller a run needs: the first build derives and compiles it
    with the core; one the library does not hold yet is added to it (a build for it and those it
    holds). ``gains``: the run's own over the description's (as for :func:`build`)."""
    from ..controllers import CONTROLLERS, function_name

    m = as_model(model)
    numbers = DEFAULT_NUMBERS if numbers is None else numbers
    key = (m.baked_hash(), numbers)
    wanted = tuple(c for c in (controller,) if c in CONTROLLERS)
    lib = DEFAULT_DYNAMICS.get(key)
    if lib is None or any(function_name(c) not in lib.group_of for c in wanted):
        # a new structure derives only the controller run; another one later is added to it
        held = () if lib is None else tuple(c for c in CONTROLLERS if function_name(c) in lib.group_of)
        DEFAULT_DYNAMICS[key] = build(m, progress=progress, numbers=numbers, gains=gains,
                                      controllers=(*held, *wanted) if wanted else None).library
    from ..dynamics import Dynamics
    return Dynamics(m, DEFAULT_DYNAMICS[key])


def dynamics_for(what: str, model=None, dyn=None, **build_options):
    """The compiled dynamics a call ``what`` ("simulate", "identify", "export") runs on: ``dyn`` when
    given (a ``model`` given too must be the same description, else a ModelError: the call would
    silently run on one of the two), else :func:`default_dynamics` of ``model`` with ``build_options``."""
    from ..errors import ModelError

    if dyn is None:
        return default_dynamics(model, **build_options)
    if not hasattr(dyn, "model") or not hasattr(dyn, "library"):
        raise ModelError(f"{what}: dyn must be the compiled dynamics hydrogen.build() returns, got "
                         f"{type(dyn).__name__} {dyn!r}"[:300])
    if model is not None and as_model(model).baked_hash() != dyn.model.baked_hash():
        raise ModelError(f"{what}: 'model' and 'dyn' describe different models ({as_model(model).name} and "
                         f"{dyn.model.name}, or two versions of one); pass one of them")
    return dyn
