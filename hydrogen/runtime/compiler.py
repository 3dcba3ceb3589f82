"""Compile generated C into a shared library, cached by a key over source, compiler and flags.

Cache layout: ``<cache>/build/<key>/`` holds ``build.json`` and one library
named ``lib<model>_<key16>_<nonce>.so``. The nonce makes every build's file
name new, so a rebuild inside a running process never gets the already
loaded (possibly stale) library back from the dynamic loader. ``build.json``
records the library's SHA-256, so a truncated or corrupt file is detected
and rebuilt instead of crashing the loader.

``<cache>/objects/<key>.o`` holds each translation unit's object, keyed by its bytes, the local
headers it includes, the compiler and the flags: a library whose sources changed in part compiles
only the changed ones (an edit of a robot's mechanics leaves its valve functions' objects as they
were), and :func:`precompile` can start a source's compile in the background as soon as it is
written (a build compiles the core while the controllers are still being derived).
"""
from __future__ import annotations

import atexit
import hashlib
import itertools
import json
import math
import os
import queue
import re
import secrets
import shlex
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from concurrent.futures import Future, ThreadPoolExecutor, as_completed
from contextlib import ExitStack
from dataclasses import dataclass, field, replace
from pathlib import Path

from ..errors import CompilerError
from ..fileio import atomic_write, locked, write_file

__all__ = ["Toolchain", "cache_root", "compile_library", "compile_libraries", "compile_extension", "run_compiler",
           "precompile", "cancel_precompiles", "hand_off_precompiles", "objects_stored", "pending_compiles",
           "link_shared", "object_store", "included_headers", "DEFAULT_CFLAGS", "GCC_CFLAGS",
           "WARNING_FLAGS", "OBJECTS"]

#: Chosen by benchmarks/bench_flags.py (docs/benchmarks.md "Compiler flags"). -fno-semantic-interposition lets gcc
#: and clang inline CasADi's exported one-line helpers (casadi_sq, casadi_fmin, ...) inside the shared
#: library, where each was a call through the PLT: the paper-sim loop 12 % faster. -O3 adds little;
#: -march=native ties the cache to one CPU, so it is left to the user (cflags=...). -ffp-contract=off:
#: no fused multiply-adds the source does not write (GCC in C99 mode contracts none already; clang's
#: default does), so the C loop, the Python engine and the exported programs round alike everywhere.
DEFAULT_CFLAGS = ("-O2", "-fPIC", "-std=c99", "-fno-semantic-interposition", "-ffp-contract=off")
#: Added to the default flags where the compiler is GCC (:meth:`Toolchain.flags`). GCC's
#: full-redundancy elimination (tree FRE) finds next to nothing in CasADi's code, whose common
#: subexpressions are shared already, and its cost grows faster than a function's size: most of the
#: compile of a long chain's semi-implicit step. Without it that compile takes about half the time
#: and the loops of the shipped robots cost the same (benchmarks/bench_flags.py). Clang has neither
#: the pass nor the flag.
GCC_CFLAGS = ("-fno-tree-fre",)
WARNING_FLAGS = ("-Wall", "-Wextra", "-Werror")
#: The object store's folder under the cache root.
OBJECTS = "objects"
_IDENTITIES: dict = {}  # (compiler path, mtime, size) -> its --version text


def cache_root() -> Path:
    """``$HYDROGEN_CACHE_DIR``, else ``$XDG_CACHE_HOME/hydrogen``, else ``~/.cache/hydrogen``."""
    env = os.environ.get("HYDROGEN_CACHE_DIR")
    if env:
        return Path(env)
    xdg = os.environ.get("XDG_CACHE_HOME")
    return (Path(xdg) if xdg else Path.home() / ".cache") / "hydrogen"


#: Longest one compiler call may take, s (``$HYDROGEN_CC_TIMEOUT`` or ``Toolchain(timeout=...)`` overrides).
COMPILE_TIMEOUT = 600.0


def _default_timeout() -> float:
    text = os.environ.get("HYDROGEN_CC_TIMEOUT")
    if text is None:
        return COMPILE_TIMEOUT
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not (value > 0 and value < float("inf")):
        raise CompilerError(f"HYDROGEN_CC_TIMEOUT must be a number of seconds > 0, got {text!r}")
    return value


def _flags(value, what: str) -> tuple:
    """Compiler flags as a tuple of strings: a string is split as a shell would split it."""
    if isinstance(value, str):
        return tuple(shlex.split(value))
    try:
        flags = tuple(value)
    except TypeError:
        raise CompilerError(f"{what} must be a string or a sequence of strings, got {value!r}") from None
    if not all(isinstance(f, str) for f in flags):
        raise CompilerError(f"{what} must hold strings only, got {value!r}")
    return flags


@dataclass(frozen=True)
class Toolchain:
    """A C compiler and its flags. ``cc`` defaults to ``$CC`` or ``cc``.

    ``cflags`` and ``warnings`` may be sequences of strings or one string (split like a shell
    would: ``"-O2 -fPIC"``); ``cflags`` None (the default) is :meth:`flags`' defaults. ``timeout`` bounds each compiler call (default 600 s, or
    ``$HYDROGEN_CC_TIMEOUT``); a compiler that takes longer is stopped with a :class:`CompilerError`.
    """

    cc: str = field(default_factory=lambda: os.environ.get("CC", "cc"))
    cflags: tuple | None = None
    warnings: tuple = WARNING_FLAGS
    timeout: float = field(default_factory=_default_timeout, compare=False)

    def __post_init__(self):
        if not isinstance(self.cc, str) or not self.cc.strip():
            raise CompilerError(f"cc must be the compiler's name or path (a string), got {self.cc!r}")
        if self.cflags is not None:
            object.__setattr__(self, "cflags", _flags(self.cflags, "cflags"))
        object.__setattr__(self, "warnings", _flags(self.warnings, "warnings"))
        t = self.timeout
        if isinstance(t, bool) or not isinstance(t, (int, float)) or not (0 < t < float("inf")):
            raise CompilerError(f"timeout must be a number of seconds > 0, got {t!r}")

    def executable(self) -> str:
        argv = shlex.split(self.cc)
        path = shutil.which(argv[0]) if argv else None
        if path is None:
            raise CompilerError(
                f"no C compiler found: '{self.cc}' is not on PATH. Install one (e.g. "
                "'apt-get install gcc') or name it with CC=... or build(..., cc='...').")
        return path

    def identity(self) -> str:
        """The compiler's own version text, part of the cache key (asked once per process and
        compiler file: a compiler replaced on disk is asked again)."""
        exe = self.executable()
        try:
            st = os.stat(exe)
            stamp = (exe, st.st_mtime_ns, st.st_size)
        except OSError:
            stamp = None
        if stamp is not None and stamp in _IDENTITIES:
            return _IDENTITIES[stamp]
        text = self._ask_identity(exe)
        if stamp is not None:
            _IDENTITIES[stamp] = text
        return text

    def _ask_identity(self, exe: str) -> str:
        try:
            out = subprocess.run([exe, "--version"], capture_output=True, text=True,
                                 timeout=min(30.0, self.timeout))
        except OSError as exc:
            raise CompilerError(f"C compiler '{exe}' cannot be run: {exc}") from None
        except subprocess.TimeoutExpired:
            raise CompilerError(f"C compiler '{exe} --version' did not answer within "
                                f"{min(30.0, self.timeout):g} s") from None
        return f"{exe}\n{out.stdout}"

    def is_gcc(self) -> bool:
        """Whether the compiler is GCC: its ``--version`` text (not its path) names the Free Software
        Foundation and not clang (which some systems install as gcc). A wrapper that answers with its
        own text (ccache) counts as not GCC: the build is then only without :data:`GCC_CFLAGS`."""
        text = self.identity().partition("\n")[2]  # the identity's first line is the compiler's path
        return "Free Software Foundation" in text and "clang" not in text.lower()

    def flags(self) -> tuple:
        """The flags the code compiles with: ``cflags`` where given (exactly those), else
        :data:`DEFAULT_CFLAGS`, and with GCC also :data:`GCC_CFLAGS`."""
        if self.cflags is not None:
            return self.cflags
        return (*DEFAULT_CFLAGS, *GCC_CFLAGS) if self.is_gcc() else DEFAULT_CFLAGS

    def argv(self) -> list:
        return [self.executable(), *shlex.split(self.cc)[1:], *self.flags(), *self.warnings]

    def default_flags(self) -> bool:
        """Whether the code compiles with hydrogen's own flags (no ``cflags``, no flags in ``cc``):
        the flags whose numbers an unoptimized build is known to give alike."""
        return self.cflags is None and len(shlex.split(self.cc)) == 1

    def unoptimized(self) -> "Toolchain":
        """This toolchain at ``-O0`` (its optimisation flags replaced): a long generated function
        compiles several times faster and each call costs more. With the default flags the numbers
        are the same bit for bit (IEEE operations in the source's order either way: no fast math, no
        contraction); a build's quick tier (``build(..., quick=True)``) uses it."""
        return replace(self, cflags=("-O0", *(f for f in self.flags() if not _OPTIMISE.fullmatch(f))))


#: A flag that sets the optimisation level.
_OPTIMISE = re.compile(r"-O(\d*|s|z|g|fast)")


def build_key(sources: list, toolchain: Toolchain) -> str:
    """SHA-256 over the sources' names and bytes, the headers they include (``"..."``, beside them),
    the compiler identity and the flags."""
    return build_key_of([(Path(s), Path(s).read_bytes()) for s in sources], toolchain)


def build_key_of(contents: list, toolchain: Toolchain) -> str:
    """:func:`build_key` of sources already read: ``[(path, bytes)]`` (one read serves a check of the
    bytes and the key, so the two cannot see different files). The headers each includes are read
    now (:func:`included_headers`): a header that changed alone (a field added to a struct the source
    uses) is another library, never one compiled against the old layout. A source one of whose
    ``"..."`` headers is not beside it (found through a search path, or absent) is keyed by its own
    bytes alone: generated sources include only the headers of their own folder."""
    h = hashlib.sha256()
    for src, data in sorted(((Path(s), d) for s, d in contents), key=lambda t: t[0]):
        h.update(src.name.encode() + b"\0" + data + b"\0")
        for name, header in (included_headers(src, data) or [])[1:]:
            h.update(b"header\0" + name.encode() + b"\0" + header + b"\0")
    h.update(toolchain.identity().encode())
    h.update(json.dumps([toolchain.cc, list(toolchain.flags()), list(toolchain.warnings)]).encode())
    return h.hexdigest()


def _sha256(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def run_compiler(argv: list, what: str, timeout: float, cwd=None):
    """Run one compiler call, stopped after ``timeout`` s; any failure is one CompilerError."""
    try:
        proc = subprocess.run(argv, capture_output=True, text=True, timeout=timeout, cwd=cwd)
    except OSError as exc:
        raise CompilerError(f"cannot run the C compiler for {what}: {exc}") from None
    except subprocess.TimeoutExpired:
        raise CompilerError(
            f"C compiler did not finish {what} within {timeout:g} s and was stopped:\n$ {shlex.join(argv)}\n"
            "Set HYDROGEN_CC_TIMEOUT (seconds) or Toolchain(timeout=...) to allow longer.") from None
    if proc.returncode != 0:
        raise CompilerError(
            f"C compiler failed on {what} (exit {proc.returncode}):\n$ {shlex.join(argv)}\n"
            f"{proc.stderr.strip() or proc.stdout.strip()}")


def cached_library(build_dir: Path) -> Path | None:
    """The library recorded in ``build_dir/build.json`` if present and intact, else None."""
    try:
        info = json.loads((build_dir / "build.json").read_text())
        lib = build_dir / info["library"]
        if lib.is_file() and _sha256(lib) == info["sha256"]:
            return lib
    except (OSError, ValueError, KeyError, TypeError):
        pass
    return None


def usable_cores() -> int:
    """The cores this process may run on (its CPU affinity, e.g. a container's share), at least 1."""
    if hasattr(os, "process_cpu_count"):  # Python 3.13
        return os.process_cpu_count() or 1
    if hasattr(os, "sched_getaffinity"):
        return len(os.sched_getaffinity(0)) or 1
    return os.cpu_count() or 1


def compile_objects(sources: list, out_dir: Path, argv: list, timeout: float, jobs: int | None = None,
                    store: Path | None = None, force: bool = False, identity: str = "", prefer: list | None = None) -> list:
    """Compile each source to an object file, ``jobs`` compilers at a time; the objects.

    ``jobs`` defaults to :func:`usable_cores`. The largest sources start first, so that one long
    compile (a controller's semi-implicit step) does not begin last and run alone. Each compiler
    call has its own ``timeout``. The first failure stops the compiles not yet started and is
    raised (the compiles already running end within their timeout). ``argv``: the compiler and
    its flags; ``identity``: its identity text (:meth:`Toolchain.identity`), part of a stored object's key.

    Objects go to ``out_dir``, or with ``store`` (an object store, :data:`OBJECTS`) to the store
    under their content key: an object found there (or being compiled there by :func:`precompile`
    in this process) is used as it is, unless ``force``. ``prefer``: other compiler flags (a full
    argv) whose object of a source, where the store holds it now, is used instead (no waiting).
    """
    if jobs is None:
        jobs = usable_cores()
    if isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1:
        raise CompilerError(f"jobs must be a whole number of compilers >= 1, got {jobs!r}")
    sources = [Path(s) for s in sources]
    # A numbered object per source: two sources of one name (in two folders) never share an object.
    objects = [Path(out_dir) / f"{i:03d}_{s.stem}.o" for i, s in enumerate(sources)]
    inputs = [None] * len(sources)  # what a stored object is compiled from: the bytes its key covers
    if store is not None:
        for i, s in enumerate(sources):
            better = _store_entry(store, s, prefer, identity) if prefer else None
            entry = better if better is not None and better[1].is_file() else _store_entry(store, s, argv, identity)
            if entry is not None:
                inputs[i], objects[i] = entry
    order = sorted(range(len(sources)), key=lambda i: -sources[i].stat().st_size)
    failed = threading.Event()  # set by the failing compile itself: no queued compile starts after it

    def one(i):
        if failed.is_set():
            return
        try:
            if inputs[i] is None:
                _compile_to(sources[i], objects[i], argv, timeout)
            elif force or not _ready(objects[i], timeout):
                _compile_copy(inputs[i], objects[i], argv, timeout, shown=sources[i].parent)
        except BaseException:
            failed.set()
            raise

    with ThreadPoolExecutor(max_workers=min(jobs, max(len(sources), 1))) as pool:
        futures = [pool.submit(one, i) for i in order]
        try:
            for done in as_completed(futures):
                done.result()
        except BaseException:
            failed.set()  # also on KeyboardInterrupt in this thread
            for f in futures:
                f.cancel()
            raise
    return objects


def _compile_to(source: Path, obj: Path, argv: list, timeout: float) -> None:
    """Compile ``source`` into ``obj``, written whole (a new name, then renamed): a process reading
    the store never sees half an object."""
    obj.parent.mkdir(parents=True, exist_ok=True)
    tmp = obj.with_name(f".{obj.stem}-{secrets.token_hex(4)}.o")
    try:
        run_compiler([*argv, "-c", str(source), "-o", str(tmp)], source.name, timeout)
        os.replace(tmp, obj)
    finally:
        tmp.unlink(missing_ok=True)


def _store_step(source: Path, obj: Path, argv: list, timeout: float) -> tuple:
    """``(shell command, its temporary object)``: compile ``source`` (in its private folder) into the
    store's ``obj``, renamed into place by the shell itself, so that the object lands whole even where
    the process that started it has ended; each of its processes stopped after ``timeout`` s of CPU
    (``ulimit -t``: the bound that holds once nobody waits for it; ``timeout(1)`` would leave the
    process group the build stops); the private folder touched first (``_sweep`` goes by its age)
    and removed after."""
    tmp = obj.with_name(f".{obj.stem}-{secrets.token_hex(4)}.o")
    folder, q = source.parent, shlex.quote
    compile_ = shlex.join([*argv, "-c", str(source), "-o", str(tmp)])
    return (f"touch {q(str(folder))}; (ulimit -t {max(1, math.ceil(timeout))} 2>/dev/null; exec {compile_}) && "
            f"mv -f {q(str(tmp))} {q(str(obj))}; rm -f {q(str(tmp))}; rm -rf {q(str(folder))}"), tmp


def _private_copy(files: list, obj: Path) -> Path:
    """The bytes ``files`` (source first, then its headers) written to a new private folder of the
    store beside ``obj`` (``.tmp-<object>-*``, named for the object it compiles: see
    :func:`_compiling_elsewhere`; :func:`_sweep` removes one left behind); the source's path there."""
    folder = Path(tempfile.mkdtemp(dir=obj.parent, prefix=f"{_PENDING}{obj.stem[:32]}-"))
    for name, data in files:
        Path(folder, name).parent.mkdir(parents=True, exist_ok=True)
        Path(folder, name).write_bytes(data)
    return folder / files[0][0]


def _shell() -> str | None:
    """The POSIX shell the background compiles run under (they rename their objects themselves and
    outlive a process that hands them off), or None: then they are plain compiles of this process."""
    return shutil.which("sh") if os.name == "posix" else None


def _store_in_background(files: list, obj: Path, argv: list, timeout: float) -> None:
    """:func:`precompile`'s job: compile ``files`` into the store's ``obj`` in a process group of its
    own that renames the object into place itself (see :func:`hand_off_precompiles`). Where there is
    no POSIX shell, a plain compile (:func:`_compile_copy`)."""
    sh = _shell()
    if sh is None:
        return _compile_copy(files, obj, argv, timeout)
    obj.parent.mkdir(parents=True, exist_ok=True)
    source = _private_copy(files, obj)
    script, tmp = _store_step(source, obj, argv, timeout)
    proc = subprocess.Popen([sh, "-c", script], stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, start_new_session=True)
    _mark(source.parent, proc.pid)
    with _STARTED_LOCK:
        _GROUPS[obj] = proc.pid
    try:
        proc.wait(timeout=timeout)
    except subprocess.TimeoutExpired:
        _kill_group(proc.pid)
        proc.wait()
        tmp.unlink(missing_ok=True)
        shutil.rmtree(source.parent, ignore_errors=True)
    finally:
        with _STARTED_LOCK:
            _GROUPS.pop(obj, None)


def _kill_group(pgid: int) -> None:
    try:
        os.killpg(pgid, signal.SIGKILL)
    except OSError:
        pass


def _compile_copy(files: list, obj: Path, argv: list, timeout: float, shown: Path | None = None) -> None:
    """Compile the bytes ``files`` (the source first, then the headers it includes, by their names
    relative to it) from a private copy into ``obj``: the object is of exactly the bytes its key
    covers, even if the source is rewritten meanwhile. A compiler's message names ``shown`` (the
    source's own folder) where the copy was."""
    obj.parent.mkdir(parents=True, exist_ok=True)
    source = _private_copy(files, obj)
    try:
        _compile_to(source, obj, argv, timeout)
    except CompilerError as exc:
        if shown is None:
            raise
        raise CompilerError(str(exc).replace(str(source.parent), str(shown))) from None
    finally:
        shutil.rmtree(source.parent, ignore_errors=True)


#: Flags that let the compiler find a header elsewhere than beside the file that includes it: with
#: them the store's key cannot cover every header an object depends on, so objects stay the build's.
_SEARCH_FLAGS = ("-I", "-iquote", "-isystem", "-idirafter", "-include", "-imacros", "--include")


def _storable_flags(argv: list) -> bool:
    return not any(str(a).startswith(_SEARCH_FLAGS) for a in argv)


_LOCAL_INCLUDE = re.compile(rb'^[ \t]*#[ \t]*include[ \t]*"([^"]+)"', re.MULTILINE)


def included_headers(source: Path, data: bytes) -> list | None:
    """``[(name, bytes)]``: the source, then the headers it includes (and they include) with ``"..."``,
    each found beside the file that includes it, named relative to the source's folder, read now.
    None when one is not there, or lies outside that folder: the compiler finds it by its own search,
    which a key cannot follow."""
    root = source.parent.resolve()
    out, todo, seen = [(source.name, data)], [(root, data)], {source.name}
    while todo:
        folder, text = todo.pop()
        for raw in _LOCAL_INCLUDE.findall(text):
            path = (folder / raw.decode(errors="replace")).resolve()
            try:
                name = path.relative_to(root).as_posix()
            except ValueError:
                return None
            if name in seen:
                continue
            seen.add(name)
            try:
                header = path.read_bytes()
            except OSError:
                return None
            out.append((name, header))
            todo.append((path.parent, header))
    return out


def _store_entry(store: Path, source: Path, argv: list, identity: str):
    """``(files, object path)`` of ``source`` in the object ``store``: the bytes its key covers (read
    now) and where its object is kept; None where the key cannot cover every header it includes."""
    files = included_headers(source, source.read_bytes()) if _storable_flags(argv) else None
    if files is None:
        return None
    return files, Path(store) / f"{_object_key(files, argv, identity)}.o"


def _object_key(files: list, argv: list, identity: str) -> str:
    """SHA-256 of an object's inputs: the source and its local headers (names and bytes), the
    compiler's identity and its flags."""
    h = hashlib.sha256(b"object\0" + identity.encode() + b"\0" + json.dumps(list(argv)).encode())
    for name, data in files:
        h.update(b"\0" + name.encode() + b"\0" + data)
    return h.hexdigest()


# Compiles started by precompile() in this process, by object path: their futures, what each compiles
# ((files, argv, timeout)), the process group of each one running; and the one worker pool they run in.
_STARTED: dict = {}
_JOBS: dict = {}
_GROUPS: dict = {}
_HANDED: set = set()  # process groups handed off: left to finish after this process
_CHAINS: list = []  # the handed-off chains' processes, reaped when they have ended
_STARTED_LOCK = threading.Lock()
_BACKGROUND: list = []
_POOL_LOCK = threading.Lock()


class _DaemonPool:
    """Worker threads that never hold the process at its exit (a ThreadPoolExecutor's are joined
    then): a compile handed off (:func:`hand_off_precompiles`) finishes on its own in its process
    group; the others are stopped at exit (:func:`cancel_precompiles`)."""

    def __init__(self, workers: int, prefix: str):
        self._queue, self._count = queue.PriorityQueue(), itertools.count()
        for i in range(workers):
            threading.Thread(target=self._work, name=f"{prefix}-{i}", daemon=True).start()

    def submit(self, fn, *args, first: bool = False) -> Future:
        """Queue ``fn(*args)``: after those queued before it, or (``first``) before every one not
        queued ``first``."""
        future = Future()
        self._queue.put((0 if first else 1, next(self._count), (future, fn, args)))
        return future

    def _work(self) -> None:
        while True:
            future, fn, args = self._queue.get()[2]
            if not future.set_running_or_notify_cancel():
                continue
            try:
                future.set_result(fn(*args))
            except BaseException as exc:  # noqa: BLE001 - handed to whoever waits on the future
                future.set_exception(exc)


def _forget_after_fork() -> None:
    """In a forked child: none of the parent's compiles or threads exist there (a future that never
    ends, a lock held by a thread that is gone), so it starts with none."""
    global _STARTED_LOCK, _POOL_LOCK
    _STARTED.clear()
    _JOBS.clear()
    _GROUPS.clear()
    _HANDED.clear()
    _CHAINS.clear()
    _BACKGROUND.clear()
    _STARTED_LOCK, _POOL_LOCK = threading.Lock(), threading.Lock()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_forget_after_fork)


#: The first bytes of an object file: ELF, Mach-O (32 and 64 bit, either byte order), COFF (x86-64,
#: arm64), LLVM bitcode (clang -flto) bare and wrapped.
_OBJECT_MAGIC = (b"\x7fELF", b"\xfe\xed\xfa\xce", b"\xfe\xed\xfa\xcf", b"\xce\xfa\xed\xfe", b"\xcf\xfa\xed\xfe",
                 b"\x64\x86", b"\x64\xaa", b"BC\xc0\xde", b"\xde\xc0\x17\x0b")


def _looks_like_an_object(path: Path) -> bool:
    """Whether ``path`` starts as an object file does (a damaged store entry does not)."""
    try:
        with open(path, "rb") as f:
            head = f.read(4)
    except OSError:
        return False
    return head.startswith(_OBJECT_MAGIC)


def _sweep(store: Path, older_than: float) -> None:
    """Remove what compiles that were stopped left in the object store (their private copies and
    half-written objects), once older than any compile still running can be."""
    try:
        entries = list(Path(store).glob(".*"))
    except OSError:
        return
    for p in entries:
        try:
            if time.time() - p.stat().st_mtime > older_than:
                shutil.rmtree(p, ignore_errors=True) if p.is_dir() else p.unlink(missing_ok=True)
        except OSError:
            pass


def _in_background(fn, *args, first: bool = False):
    """Run ``fn(*args)`` on this process's background pool (as many workers as usable cores less one,
    at least one: the derivation keeps a core), ``first``: before the others waiting; its future."""
    with _POOL_LOCK:
        if not _BACKGROUND:
            _BACKGROUND.append(_DaemonPool(max(1, usable_cores() - 1), "hydrogen-cc"))
        return _BACKGROUND[0].submit(fn, *args, first=first)


def _ready(obj: Path, timeout: float) -> bool:
    """Whether ``obj`` is in the store, after waiting for a background compile of it if one runs, in
    this process or in a process of its own (a failed one leaves it absent: the caller compiles it
    and reports the error itself; at most ``timeout`` s for another process's). One still queued in
    this process is taken back: the caller's own pool compiles it now."""
    with _STARTED_LOCK:
        started = _STARTED.get(obj)
    if started is not None and not started.cancel():
        try:
            started.result()
        except Exception:  # noqa: BLE001 - compiled again in the foreground, which names the error
            pass
    _wait_elsewhere(obj, timeout)
    return obj.is_file()


def precompile(sources: list, toolchain: Toolchain | None = None, cache: Path | None = None,
               first: bool = False) -> None:
    """Start compiling ``sources`` into the object store of ``cache`` in the background and return at
    once; a later :func:`compile_libraries` of the same bytes uses the objects (waiting for those still
    compiling). The bytes are read now and compiled from a copy, so the source's folder may be renamed
    or removed meanwhile (a generated folder is written in a staging folder, then swapped in).
    Failures are not raised here: the library's own compile meets them again and names them."""
    toolchain = toolchain or Toolchain()
    store = object_store(cache)
    argv, identity = toolchain.argv(), toolchain.identity()
    if store is None or not _storable_flags(argv):
        return
    for source in map(Path, sources):
        entry = _store_entry(store, source, argv, identity)
        if entry is None:
            continue  # a header the key cannot follow: left to the library's compile
        files, obj = entry
        with _STARTED_LOCK:
            if obj not in _STARTED and not obj.is_file() and not _compiling_elsewhere(obj):
                _JOBS[obj] = (files, argv, toolchain.timeout)
                _STARTED[obj] = _in_background(_store_in_background, files, obj, argv, toolchain.timeout, first=first)


def _settle(limit_s: float = 10.0) -> None:
    """Wait until every compile that has just started has its process group and the mark other
    processes see (a worker between taking a job and starting its process): the callers then
    stop or hand off every running compile, none left behind unnoticed."""
    if _shell() is None:
        return  # plain compiles: no process group to wait for
    deadline = time.monotonic() + limit_s
    while time.monotonic() < deadline:
        with _STARTED_LOCK:
            if all(f.done() or obj in _GROUPS for obj, f in _STARTED.items()):
                return
        time.sleep(0.005)


def cancel_precompiles() -> None:
    """Take back the background compiles not started yet (a build that failed, or whose library
    compiled them itself), stop those running that were not handed off (a build interrupted or
    failed: nothing it started outlives it unasked) and forget the finished ones."""
    with _STARTED_LOCK:
        for obj, started in list(_STARTED.items()):
            if started.cancel() or started.done():
                del _STARTED[obj]
                _JOBS.pop(obj, None)
    _settle()
    with _STARTED_LOCK:
        running = [pgid for pgid in _GROUPS.values() if pgid not in _HANDED]
    for pgid in running:
        _kill_group(pgid)
    _CHAINS[:] = [p for p in _CHAINS if p.poll() is None]  # the ended ones reaped


atexit.register(cancel_precompiles)


def hand_off_precompiles(keep: Toolchain | None = None) -> None:
    """Leave this process's background compiles to finish without it, at a lower priority: those
    running go on in their process groups, those not started yet run one after another in one
    process of their own; each renames its object into the store itself. A quick build
    (``build(..., quick=True)``) calls it before compiling its unoptimized libraries: the optimized
    objects are then in the store for the next build, whether or not this process is still there.
    Without a POSIX shell nothing is handed off (the next build compiles what this one did not).
    ``keep``: a toolchain whose compiles stay this process's (those a quick build waits for)."""
    sh = _shell()
    if sh is None:
        return
    kept = None if keep is None else keep.argv()
    with _STARTED_LOCK:
        queued = [(obj, _JOBS.pop(obj)) for obj, started in list(_STARTED.items())
                  if _JOBS[obj][1] != kept and started.cancel()]
        for obj, _ in queued:
            del _STARTED[obj]
    _settle()
    with _STARTED_LOCK:
        running = [pgid for obj, pgid in _GROUPS.items() if _JOBS.get(obj, (None, None))[1] != kept]
        _HANDED.update(running)
    for pgid in running:
        _lower_priority(pgid)
    steps, folders = [], []
    for obj, (files, argv, timeout) in queued:
        if obj.is_file() or _compiling_elsewhere(obj):
            continue
        source = _private_copy(files, obj)
        folders.append(source.parent)
        steps.append(_store_step(source, obj, argv, timeout)[0])
    _CHAINS[:] = [p for p in _CHAINS if p.poll() is None]  # the ended ones reaped
    if steps:
        proc = subprocess.Popen([sh, "-c", "\n".join(steps)], stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                stderr=subprocess.DEVNULL, start_new_session=True)
        _CHAINS.append(proc)  # kept: polled (reaped) by the next hand-off, never waited for
        _lower_priority(proc.pid)
        for folder in folders:
            _mark(folder, proc.pid)


#: The prefix of a compile's private folder in the object store, named for the object it makes.
_PENDING = ".tmp-"


def pending_compiles(cache: Path | None = None) -> int:
    """How many compiles into the object store of ``cache`` are under way now (their private copies:
    in any process, handed-off ones included; a copy a killed compile left counts until the store is
    swept)."""
    store = object_store(cache)
    return 0 if store is None else sum(1 for _ in store.glob(f"{_PENDING}*"))


def _mark(folder: Path, pid: int) -> None:
    """Record in a compile's private ``folder`` the process that compiles from it (a folder already
    removed: that compile has ended)."""
    try:
        atomic_write(folder / "pid", str(pid))
    except OSError:
        pass


def _compiling_elsewhere(obj: Path) -> bool:
    """Whether a compile of ``obj`` is running in a process of its own (this process's handed-off
    compiles, another process's background ones): its private folder is there, and the process it
    records is alive."""
    for folder in obj.parent.glob(f"{_PENDING}{obj.stem[:32]}-*"):
        try:
            os.kill(int((folder / "pid").read_text()), 0)
            return True
        except (OSError, ValueError):
            continue
    return False


def _wait_elsewhere(obj: Path, timeout: float) -> None:
    """Wait (at most ``timeout`` s) while another process compiles ``obj``: the object it stores is
    used, not compiled a second time beside it."""
    t0 = time.monotonic()
    while not obj.is_file() and _compiling_elsewhere(obj) and time.monotonic() - t0 < timeout:
        time.sleep(0.05)


def _lower_priority(pgid: int) -> None:
    """Let the compiles of process group (and session) ``pgid`` yield the cores to the foreground: its
    nice value, and on Linux its scheduling autogroup's (a session of its own is weighed as a whole
    against the foreground's, whatever its processes' nice values). Best effort."""
    try:
        os.setpriority(os.PRIO_PGRP, pgid, 10)
    except (OSError, AttributeError):
        pass
    try:
        Path(f"/proc/{pgid}/autogroup").write_text("10")
    except OSError:
        pass


def objects_stored(sources: list, toolchain: Toolchain | None = None, cache: Path | None = None) -> bool | None:
    """Whether every one of ``sources`` has its object in the store of ``cache`` now (no waiting for
    a compile of it still running): a library of them is then a link away. None where the store
    cannot hold them (no store, flags that search for headers, a header the key cannot follow)."""
    toolchain = toolchain or Toolchain()
    store = object_store(cache)
    argv, identity = toolchain.argv(), toolchain.identity()
    if store is None or not _storable_flags(argv):
        return None
    entries = [_store_entry(store, source, argv, identity) for source in map(Path, sources)]
    if any(e is None for e in entries):
        return None
    return all(e[1].is_file() for e in entries)


def compile_library(sources: list, name: str, toolchain: Toolchain | None = None,
                    cache: Path | None = None, jobs: int | None = None,
                    force: bool = False) -> Path:
    """Compile ``sources`` (.c files) into a cached shared library and return its path.

    Each source becomes an object file in parallel (:func:`compile_objects`: ``jobs`` compilers,
    default the usable cores), then one link. A failed compile raises
    :class:`CompilerError` with the compiler's own message.
    """
    return compile_libraries([(sources, name)], toolchain, cache, jobs, force)[0]


def compile_libraries(libraries: list, toolchain: Toolchain | None = None, cache: Path | None = None,
                      jobs: int | None = None, force: bool = False, prefer: Toolchain | None = None) -> list:
    """Compile several cached shared libraries, ``[(sources, name)]``, and return their paths in order.

    Each is cached as :func:`compile_library` caches one (its own key, folder and lock); those not
    in the cache have all their sources compiled in one pool of ``jobs`` compilers (the largest
    first, whichever library it belongs to), then each is linked. ``prefer``: a toolchain whose
    objects the store holds already are linked in place of compiling those sources (a quick build's
    unoptimized library takes the optimized objects that are ready).
    """
    toolchain = toolchain or Toolchain()
    root = Path(cache or cache_root())
    todo = []
    for sources, name in libraries:
        sources = [Path(s).resolve() for s in sources]
        key = build_key(sources, toolchain)
        todo.append((sources, name, key, root / "build" / key))
    paths = {}
    with ExitStack() as stack:
        # Locks in one order (by key) in every process: two builds of overlapping sets never deadlock.
        for build_dir in sorted({t[3] for t in todo}):
            stack.enter_context(locked(build_dir))
        missing = []
        for sources, name, key, build_dir in todo:
            lib = None if force else cached_library(build_dir)
            if lib is not None:
                paths[build_dir] = lib
            elif build_dir not in {m[3] for m in missing}:
                missing.append((sources, name, key, build_dir))
        if not missing:
            return [paths[t[3]] for t in todo]
        for _, _, _, build_dir in missing:
            build_dir.mkdir(parents=True, exist_ok=True)
            for old in build_dir.glob("*.so"):  # a corrupt or superseded build
                old.unlink(missing_ok=True)
            for old in build_dir.glob("tmp*"):  # object folders of a build that was killed (we hold the lock)
                if old.is_dir():
                    shutil.rmtree(old, ignore_errors=True)
        argv = toolchain.argv()
        store, identity = object_store(root), toolchain.identity()
        if store is not None:
            _sweep(store, older_than=max(toolchain.timeout, 3600.0))
        with tempfile.TemporaryDirectory(dir=missing[0][3]) as tmp:
            every = [s for m in missing for s in m[0]]
            objects = compile_objects(every, Path(tmp), argv, toolchain.timeout, jobs, store, force, identity,
                                      None if prefer is None else prefer.argv())
            start = 0
            for sources, name, key, build_dir in missing:
                mine, start = objects[start:start + len(sources)], start + len(sources)
                lib_name = f"lib{name}_{key[:16]}_{secrets.token_hex(4)}.so"
                tmp_lib = Path(tmp) / lib_name
                link_shared(sources, mine, tmp_lib, argv, toolchain.timeout, jobs, store, identity)
                os.replace(tmp_lib, build_dir / lib_name)
                atomic_write(build_dir / "build.json", json.dumps(
                    {"library": lib_name, "sha256": _sha256(build_dir / lib_name),
                     "sources": [s.name for s in sources], "argv": argv}, indent=2, sort_keys=True))
                paths[build_dir] = build_dir / lib_name
    return [paths[t[3]] for t in todo]


def link_shared(sources: list, objects: list, out: Path, argv: list, timeout: float, jobs: int | None = None,
                store: Path | None = None, identity: str = "", link_flags: tuple = (), cwd=None) -> None:
    """Link ``objects`` (:func:`compile_objects`' of ``sources``, in order) into the shared library
    ``out``. A stored object that does not start as an object file (damaged in the store) is compiled
    again first; a link error names each stored object by its source."""
    if not all(map(_looks_like_an_object, objects)):
        objects = compile_objects(sources, Path(out).parent, argv, timeout, jobs, store, True, identity)
    try:
        run_compiler([*argv, "-shared", *map(str, objects), "-o", str(out), *link_flags, "-lm"],
                     f"linking {Path(out).name}", timeout, cwd=cwd)
    except CompilerError as exc:
        text = str(exc)
        for src, obj in zip(sources, objects):
            text = text.replace(str(obj), f"{obj} (of {Path(src).name})")
        raise CompilerError(text) from None


def object_store(root: Path | None = None) -> Path | None:
    """The object store of the cache ``root`` (default :func:`cache_root`), made if need be; None where
    it cannot be (a read-only cache): objects are then compiled for the one build."""
    store = Path(root or cache_root()) / OBJECTS
    try:
        store.mkdir(parents=True, exist_ok=True)
    except OSError:
        return None
    return store if os.access(store, os.W_OK) else None


def compile_extension(render, key_material: str, module: str, toolchain: Toolchain | None = None,
                      cache: Path | None = None, include_dirs: tuple = (), force: bool = False,
                      prefer: Toolchain | None = None) -> Path:
    """Compile a CPython extension module into the build cache and return its path.

    ``render()`` returns the module's C source; it is called only when no intact cached build
    exists, so a cached load needs no template engine. ``key_material`` must cover everything
    the source and the binary depend on besides the toolchain (template, render context, Python
    version and ABI, header folders): with the toolchain identity, flags and ``include_dirs``
    it makes the cache key. Cached in ``<cache>/extension/<key>/``, laid out as
    :func:`compile_library`'s folders (``build.json``, a new file name per build). The toolchain's flags are used without ``-Werror`` (headers of other
    Python or numpy versions must not turn a warning into the ctypes fallback), and the header
    folders are ``-isystem``. ``prefer``: a toolchain whose build of the module, where cached, is
    returned instead (a quick build takes the optimized extension when there is one).
    """
    toolchain = toolchain or Toolchain()

    def folder(tc):
        h = hashlib.sha256(b"extension\0" + key_material.encode())
        h.update(tc.identity().encode())
        h.update(json.dumps([tc.cc, list(tc.flags()), list(tc.warnings), [str(d) for d in include_dirs]]).encode())
        return Path(cache or cache_root()) / "extension" / h.hexdigest()

    build_dir = folder(toolchain)
    if prefer is not None and not force:
        lib = cached_library(folder(prefer))
        if lib is not None:
            return lib
    if not force:  # a warm cache serves without a lock (a read-only cache works once warm)
        lib = cached_library(build_dir)
        if lib is not None:
            return lib
    with locked(build_dir):
        if not force:
            lib = cached_library(build_dir)
            if lib is not None:
                return lib
        build_dir.mkdir(parents=True, exist_ok=True)
        for old in build_dir.glob("*.so"):
            old.unlink(missing_ok=True)
        argv = [toolchain.executable(), *shlex.split(toolchain.cc)[1:], *toolchain.flags(),
                *(w for w in toolchain.warnings if w != "-Werror")]
        for d in include_dirs:
            argv += ["-isystem", str(d)]
        link = ["-undefined", "dynamic_lookup"] if sys.platform == "darwin" else []
        with tempfile.TemporaryDirectory(dir=build_dir) as tmp:
            src, obj = Path(tmp) / f"{module}.c", Path(tmp) / f"{module}.o"
            write_file(src, render())
            run_compiler([*argv, "-c", str(src), "-o", str(obj)], src.name, toolchain.timeout)
            lib_name = f"{module}_{build_dir.name[:16]}_{secrets.token_hex(4)}.so"
            run_compiler([*argv, "-shared", str(obj), *link, "-o", str(Path(tmp) / lib_name)],
                         f"linking {lib_name}", toolchain.timeout)
            os.replace(Path(tmp) / lib_name, build_dir / lib_name)
        atomic_write(build_dir / "build.json", json.dumps(
            {"library": lib_name, "sha256": _sha256(build_dir / lib_name), "module": module,
             "argv": argv}, indent=2, sort_keys=True))
        return build_dir / lib_name
