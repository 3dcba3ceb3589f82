"""Direct ctypes calls into CasADi-generated C functions, through buffers made once.

A generated function has the C signature
``int f(const double** arg, double** res, long long* iw, double* w, int mem)``.
:class:`CompiledFunction` allocates the input and output arrays and the work
vectors once, fills the pointer tables once, and per call only copies the
inputs in, calls, and copies the outputs out. No CasADi Python object is
touched on the call path.
"""
from __future__ import annotations

import ctypes
import threading
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from ..errors import BuildCacheError, InputError
from ..layout import NUMBERS

__all__ = ["GeneratedLibrary", "CompiledFunction", "LazyFunctions", "load_failure", "function_groups", "group_sources",
           "group_name", "group_of", "CORE", "RATES"]

_c_int = ctypes.c_longlong  # casadi_int, fixed by the code generator options
_DOUBLE_P = ctypes.POINTER(ctypes.c_double)



def _out_fault(o, shape) -> str | None:
    """None if ``o`` can take an output of ``shape``; else "shape" or the one fault, as a message tail.
    Checked in this order, with these words, by the extension too (templates/pyext.c.j2, check_out)."""
    if not isinstance(o, np.ndarray):
        return "shape"
    if o.dtype.type is not np.float64:  # any byte order: that is the next check
        return f"must be float64, got {o.dtype}"
    if not o.dtype.isnative:
        return f"must be float64 in native byte order, got {o.dtype.str}"
    if o.shape != shape:
        return "shape"
    if not o.flags.c_contiguous:
        got = "a Fortran-order (column-major) array" if o.flags.f_contiguous else "a non-contiguous array"
        return f"must be C-contiguous (row-major, as np.empty gives), got {got}"
    if not o.flags.aligned:
        return "must be aligned, got an unaligned array"
    if not o.flags.writeable:
        return "must be writeable, got a read-only array"
    return None

class CompiledFunction:
    """One generated function, callable with numpy arrays; returns fresh arrays.

    Matrices are column-major in CasADi; outputs come back as numpy arrays of
    the recorded shape (C order copies), vectors as 1-D arrays.
    """

    def __init__(self, lib: ctypes.CDLL, entry: dict, numbers=None):
        self._lib, self._entry, self._numbers = lib, entry, numbers
        self._lock = threading.Lock()  # ctypes releases the GIL: one caller at a time per buffer set
        self.name = entry["name"]
        self.c_name = entry["c_name"]
        self.doc = entry.get("doc", "")
        self.backend = "ctypes"
        fn = getattr(lib, self.c_name)
        fn.restype = ctypes.c_int
        fn.argtypes = None  # pointer tables are passed as prepared ctypes objects
        self._fn = fn
        sz = [_c_int() for _ in range(4)]
        getattr(lib, self.c_name + "_work")(*map(ctypes.byref, sz))
        n_arg, n_res, n_iw, n_w = (s.value for s in sz)
        shapes = [(int(r), int(c)) for _, r, c in entry["inputs"]]
        names = [n for n, _, _ in entry["inputs"]]
        self.out_shapes = [(int(r), int(c)) for _, r, c in entry["outputs"]]
        self.out_names = [n for n, _, _ in entry["outputs"]]
        #: inputs no output depends on (from the manifest): setting them changes nothing
        self.unread_inputs = tuple(entry.get("unread_inputs", ()))
        self._check_sparsity(lib, shapes)
        # Fortran-ordered buffers match CasADi's column-major dense layout.
        self._in = [np.zeros(s, order="F") for s in shapes]
        self._out = [np.zeros(s, order="F") for s in self.out_shapes]
        # The description's numbers (a library generated with them as inputs): filled here once,
        # never an argument of a call.
        hidden = names.index(NUMBERS) if NUMBERS in names else None
        if hidden is not None:
            if numbers is None or np.shape(numbers) != (shapes[hidden][0],):
                raise BuildCacheError(f"{self.c_name}: takes the description's {shapes[hidden][0]} numbers as "
                                      f"inputs, got {'none' if numbers is None else np.shape(numbers)}; build "
                                      "it with hydrogen.build")
            self._in[hidden][:, 0] = numbers
        #: every input in the order of the C argument table (:meth:`c_tables`), the hidden one too
        self.arg_names = list(names)
        user = [i for i in range(len(names)) if i != hidden]
        self.in_shapes = [shapes[i] for i in user]
        self.in_names = [names[i] for i in user]
        self._arg = (ctypes.c_void_p * max(n_arg, len(self._in)))(*[b.ctypes.data for b in self._in])
        self._res = (ctypes.c_void_p * max(n_res, len(self._out)))(*[b.ctypes.data for b in self._out])
        self._iw = (_c_int * max(n_iw, 1))()
        self._w = (ctypes.c_double * max(n_w, 1))()
        self._mem = ctypes.c_int(0)
        # Column vectors are seen as 1-D arrays by the user; matrices as 2-D (C-order copies out).
        self._in_views = [b[:, 0] if b.shape[1] == 1 else b for b in (self._in[i] for i in user)]
        self._in_vshapes = [v.shape for v in self._in_views]
        self._out_views = [b[:, 0] if b.shape[1] == 1 else b for b in self._out]
        self._n_in = len(self.in_names)
        self._single = len(self._out) == 1

    def _check_sparsity(self, lib, in_shapes):
        sp_out = getattr(lib, self.c_name + "_sparsity_out")
        sp_out.restype = ctypes.POINTER(_c_int)
        sp_in = getattr(lib, self.c_name + "_sparsity_in")
        sp_in.restype = ctypes.POINTER(_c_int)
        for getter, shapes, kind in ((sp_in, in_shapes, "input"), (sp_out, self.out_shapes, "output")):
            for i, (r, c) in enumerate(shapes):
                sp = getter(_c_int(i))
                rows, cols = sp[0], sp[1]
                # Dense patterns are stored compactly as {rows, cols, 1}; otherwise
                # {rows, cols, colind[0]=0, …}, so the third entry tells them apart.
                dense = sp[2] == 1 or (sp[2] == 0 and sp[2 + cols] == rows * cols)
                if (rows, cols) != (r, c) or not dense:
                    raise BuildCacheError(
                        f"{self.c_name}: {kind} {i} is {rows}x{cols} (dense: {dense}) in the "
                        f"library, manifest says dense {r}x{c}; regenerate")

    def _bad_input(self, args):
        if len(args) != len(self.in_names):  # the inputs a caller passes: not the description's numbers
            return TypeError(f"{self.name} takes {len(self.in_names)} inputs "
                             f"({', '.join(self.in_names)}), got {len(args)}")
        for view, x, name in zip(self._in_views, args, self.in_names):
            if np.shape(x) != view.shape:
                return ValueError(f"{self.name}: input '{name}' needs shape {view.shape}, "
                                  f"got {np.shape(x)}")
        return None

    def call_into(self, *args):
        """Copy inputs in and evaluate; results stay in the output buffers (returned, not copied)."""
        # Hot path: one numpy copy per input, one ctypes call; shapes are checked
        # exactly (no silent broadcasting of a scalar into a vector).
        if len(args) != self._n_in:
            raise self._bad_input(args)
        for view, shape, x in zip(self._in_views, self._in_vshapes, args):
            if getattr(x, "shape", None) != shape and np.shape(x) != shape:
                raise self._bad_input(args)
            view[...] = x
        if self._fn(self._arg, self._res, self._iw, self._w, self._mem):
            raise RuntimeError(f"{self.c_name} returned an error code")
        return self._out_views

    def __call__(self, *args, out=None):
        """Evaluate; returns a fresh array (a tuple of them for several outputs). Thread-safe.

        Inputs of shape (n, ...) are a batch of n states (unstacked inputs are shared by all);
        ``out=`` (an array, or a tuple of arrays) receives the results and is returned. Same
        semantics and messages as the compiled extension, but a batch is a Python loop here.
        """
        with self._lock:
            if out is None and len(args) == self._n_in and all(
                    getattr(x, "shape", None) == shape for x, shape in zip(args, self._in_vshapes)):
                outs = self.call_into(*args)
                if self._single:
                    return outs[0].copy()
                return tuple(o.copy() for o in outs)
            return self._call_general(args, out)

    def _call_general(self, args, out):
        if len(args) != self._n_in:
            raise self._bad_input(args)
        arrays, batched, n = [], [], None
        for i, (x, name, (r, c)) in enumerate(zip(args, self.in_names, self.in_shapes)):
            try:
                a = np.asarray(x)
                if a.dtype != np.float64 or not a.flags.c_contiguous:
                    a = np.ascontiguousarray(a.astype(np.float64, casting="safe"))
            except (TypeError, ValueError) as exc:
                raise TypeError(f"{self.name}: input '{name}' cannot be converted to a float64 array: "
                                f"{exc}") from None
            user = self._in_vshapes[i]
            if a.shape == user:
                batched.append(False)
            elif a.ndim == len(user) + 1 and a.shape[1:] == user:
                batched.append(True)
                if n is None:
                    n, first = a.shape[0], name
                elif a.shape[0] != n:
                    raise InputError(f"{self.name}: input '{name}' holds {a.shape[0]} states (its first "
                                     f"dimension) but input '{first}' holds {n}: stacked inputs need the same n")
            else:
                raise InputError(f"{self.name}: input '{name}' needs shape {_shape_text(user)}, or "
                                 f"{_shape_text(user, True)} for a batch of n states, got {a.shape}")
            arrays.append(a)
        outs = self._outputs(out, n, arrays)
        if n is None:
            for o, r in zip(outs, self.call_into(*arrays)):
                o[...] = r
        else:
            _check_nan_rows(self, arrays, batched, n)
            for k in range(n):
                for o, r in zip(outs, self.call_into(*[a[k] if b else a for a, b in zip(arrays, batched)])):
                    o[k] = r
        if out is not None:
            return out
        return outs[0] if self._single else tuple(outs)

    def _outputs(self, out, n, inputs):
        shapes = [((n,) if n is not None else ()) + v.shape for v in self._out_views]
        if out is None:
            return [np.empty(s) for s in shapes]
        if self._single and isinstance(out, np.ndarray):
            outs = [out]
        elif isinstance(out, tuple) and len(out) == len(shapes):
            outs = list(out)
        else:
            k = len(shapes)
            raise TypeError(f"{self.name}: out must be {'an array or a tuple of ' if k == 1 else 'a tuple of '}"
                            f"{k} array{'' if k == 1 else 's'} (one per output), got {type(out)!r}")
        for o, shape, name, view in zip(outs, shapes, self.out_names, self._out_views):
            fault = _out_fault(o, shape)
            if fault == "shape":
                got = o.shape if isinstance(o, np.ndarray) else repr(type(o))
                with_n = f" with n = {n}" if n is not None else ""
                raise InputError(f"{self.name}: out for output '{name}' needs a writeable C-contiguous float64 "
                                 f"array of shape {_shape_text(view.shape, n is not None)}{with_n}, got {got}"
                                 f"{'' if isinstance(o, np.ndarray) else ' (not a numpy array)'}")
            if fault:
                raise InputError(f"{self.name}: out for output '{name}' {fault}")
            for a, iname in zip(inputs, self.in_names):
                if o.size and a.size and np.may_share_memory(o, a):
                    raise InputError(f"{self.name}: out for output '{name}' shares memory with input '{iname}'")
        for i, (o, name) in enumerate(zip(outs, self.out_names)):  # one output written over another's
            for other, oname in zip(outs[i + 1:], self.out_names[i + 1:]):
                if o.size and other.size and np.may_share_memory(o, other):
                    raise InputError(f"{self.name}: out for output '{name}' shares memory with output '{oname}'")
        return outs

    def set_inputs(self, values: dict) -> None:
        """Write inputs by name into this function's own buffers (for callers that then evaluate
        through :meth:`c_tables`, such as the C loop); shapes are checked."""
        for name, value in values.items():
            i = self.in_names.index(name)
            view = self._in_views[i]
            try:
                view[...] = np.reshape(np.asarray(value, float), view.shape)
            except ValueError:
                raise InputError(f"{self.name}: input '{name}' needs shape {view.shape}, "
                                 f"got {np.shape(value)}") from None

    def c_tables(self) -> dict:
        """The C entry point and the argument, result and work tables this object owns, as
        ``c_void_p`` (fn, arg, res, iw, w): for C code that calls the function on these buffers."""
        return {"fn": ctypes.cast(self._fn, ctypes.c_void_p), "arg": ctypes.cast(self._arg, ctypes.c_void_p),
                "res": ctypes.cast(self._res, ctypes.c_void_p), "iw": ctypes.cast(self._iw, ctypes.c_void_p),
                "w": ctypes.cast(self._w, ctypes.c_void_p)}

    def output(self, k: int = 0) -> np.ndarray:
        """A copy of output ``k`` from the last evaluation on this object's buffers."""
        return np.array(self._out_views[k])

    def clone(self) -> "CompiledFunction":
        """The same function with buffers of its own (for a controller runtime or a loop runner)."""
        return CompiledFunction(self._lib, self._entry, self._numbers)


def _shape_text(shape: tuple, batch: bool = False) -> str:
    """A shape as the extension words it, e.g. (m,) or (n, p); with batch, (k, m) or (k, n, p)."""
    if batch:
        return "(n, " + ", ".join(map(str, shape)) + ")"
    return str(tuple(shape))


#: NaN rows listed in an error message, at most (as the extension)
_MAX_LISTED = 10


def _check_nan_rows(fn, arrays, batched, n):
    """As the extension: a NaN in a shared input is reported alone; else every NaN row of each input."""
    if not n:
        return
    msgs = [f"input '{name}' (one value shared by all {n} states) contains NaN"
            for a, b, name in zip(arrays, batched, fn.in_names) if not b and np.isnan(a).any()]
    if not msgs:
        for a, b, name in zip(arrays, batched, fn.in_names):
            rows = np.flatnonzero(np.isnan(a.reshape(n, -1)).any(axis=1)) if b else ()
            if len(rows):
                listed = [int(k) for k in rows[:_MAX_LISTED]]
                msgs.append(f"input '{name}' has NaN in {len(rows)} of {n} rows: {listed}"
                            f"{' ...' if len(rows) > _MAX_LISTED else ''}")
    if msgs:
        raise InputError(f"{fn.name}: NaN states in a batch: {'; '.join(msgs)}")


def load_failure(path: Path, exc: Exception) -> str:
    """Why the dynamic loader refused the compiled library at ``path``, with the way out when it is
    known. "failed to map segment" is glibc's word for an mmap of code refused: a noexec mount."""
    text = str(exc)
    msg = f"{path}: cannot load compiled library: {text}"
    if "failed to map segment" in text:
        msg += (f". The folder {Path(path).parent} may be on a file system mounted noexec (no code may be run "
                "from it, as /tmp often is): set HYDROGEN_CACHE_DIR (or build(cache=...)) to a folder on "
                "another file system")
    return msg


#: The library of everything that is not a controller: kinematics, rigid body, hydraulics, plant, loop driver.
CORE = "core"


def group_name(kind: str, variant: str | None = None) -> str:
    """The library of controller ``kind``'s ``variant`` (None: the full controller): ``kind``, or
    ``kind-variant`` (e.g. ``adaptive-robust-lean``)."""
    return kind if variant is None else f"{kind}-{variant}"


#: The suffix of a controller variant's library of its state's rates alone (``kind[-variant]-rates``):
#: only the Python engine's semi-implicit update calls them, so the C loop's runs never compile them.
RATES = "rates"


def group_of(fname: str) -> str:
    """The library that holds generated function ``fname`` (:func:`function_groups`): :data:`CORE`,
    its controller's variant's, or that variant's rates library (:data:`RATES`)."""
    from ..controllers import function_owner, rates_function_name

    owner = function_owner(fname)
    if owner is None:
        return CORE
    return f"{group_name(*owner)}-{RATES}" if fname == rates_function_name(*owner) else group_name(*owner)


def function_groups(manifest: dict) -> dict:
    """The manifest's function names by the library that holds them: :data:`CORE` first, then per
    controller (in the order the controllers are registered) one group per variant that a run calls
    on its own, the full one (:func:`group_name` ``kind``: the controller and its semi-implicit step)
    and the lean one (``kind-lean``, run when every composite rate is 0), each followed by its rates
    library (``kind[-lean]-rates``: the Python engine's), so a run compiles only what it calls."""
    from ..controllers import CONTROLLERS, LEAN

    names = [e["name"] for e in manifest["functions"]]
    owner = {n: group_of(n) for n in names}
    groups = {CORE: [n for n in names if owner[n] == CORE]}
    for kind in CONTROLLERS:
        for variant in (None, LEAN):
            for group in (group_name(kind, variant), f"{group_name(kind, variant)}-{RATES}"):
                mine = [n for n in names if owner[n] == group]
                if mine:
                    groups[group] = mine
    return groups


def group_sources(manifest: dict, group: str) -> list:
    """The generated files (names in the folder) the library ``group`` is compiled from: its functions'
    sources (the manifest's ``source`` fields), and the loop drivers for :data:`CORE`."""
    names = set(function_groups(manifest).get(group, ()))
    if not names:
        raise KeyError(f"no library '{group}' in this manifest")
    sources = [e["source"] for e in manifest["functions"] if e["name"] in names]
    return sources + (list(manifest.get("drivers", [])) if group == CORE else [])


class LazyFunctions(Mapping):
    """The functions of a :class:`GeneratedLibrary` by name; looking one up loads (and, the first time,
    compiles) the library that holds it. ``name in functions`` and iterating over the names load
    nothing; ``values()``/``items()`` load every library."""

    def __init__(self, library: "GeneratedLibrary", table: dict):
        self._library, self._table = library, table

    def __getitem__(self, name):
        if name not in self._library.group_of:  # a KeyError still, naming what there is
            raise KeyError(f"no generated function {name!r} in this build; its functions: "
                           f"{', '.join(sorted(self._library.group_of))}")
        group = self._library.group_of[name]
        if name not in self._table:
            self._library.load(group)
        return self._table[name]

    def __contains__(self, name):
        return name in self._library.group_of

    def __iter__(self):
        return iter(self._library.group_of)

    def __len__(self):
        return len(self._library.group_of)

    def loaded(self) -> dict:
        """The functions whose library is loaded already (nothing is compiled or loaded)."""
        return dict(self._table)


class GeneratedLibrary:
    """The compiled functions of one generated folder (see its manifest), in several shared libraries.

    ``path`` is the :data:`CORE` library (rigid body, kinematics, hydraulics, plant, loop driver),
    loaded at once. Each controller's functions are in a library of their own that ``loader(group,
    force)`` returns the path of (compiling it when it is not in the cache); it is loaded the
    first time one of its functions is looked up in :attr:`functions` (or by :meth:`load`).
    Without a ``loader``, ``path`` holds every function (one library for the whole folder).
    """

    def __init__(self, path: Path, manifest: dict, generated_dir: Path | None = None, loader=None,
                 numbers=None, cache_root: Path | None = None):
        self.path = Path(path)
        #: the build cache root the libraries were compiled in (None: not known), whose object store
        #: other compiles of the same sources (an FMU's) share
        self.cache_root = None if cache_root is None else Path(cache_root)
        #: the values of the manifest's ``numbers`` (a folder generated with the description's numbers as
        #: inputs), from ``numbers`` (a dict by name, or what returns one: ``Model.numbers``, called only
        #: for such a folder); None for a folder with the numbers folded
        self.numbers = _numbers_vector(manifest, numbers)
        self.generated_dir = None if generated_dir is None else Path(generated_dir)
        self.manifest = manifest
        self._loader = loader
        groups = function_groups(manifest)
        if loader is None:
            groups = {CORE: [n for names in groups.values() for n in names]}
        #: library (group) name of each function
        self.group_of = {n: g for g, names in groups.items() for n in names}
        self._groups = groups
        self._entries = {e["name"]: e for e in manifest["functions"]}
        self._lock = threading.RLock()  # one loader at a time: two threads never load a group twice
        self._cdlls = {}
        #: path of each loaded library, by group
        self.paths = {}
        self._ctypes, self._fast = {}, {}
        self._binder = None
        #: extension Functions by name once attached (:mod:`hydrogen.runtime.extension`), else None
        self.extension_functions = None
        self.extension_path = None
        self.backend = "ctypes"
        self.functions = LazyFunctions(self, self._ctypes)
        self._open(CORE, self.path)

    def _open(self, group: str, path: Path):
        """Load the library ``path`` as ``group``: ABI checked, its functions made."""
        path = Path(path)
        try:
            cdll = ctypes.CDLL(str(path))
        except OSError as exc:
            raise BuildCacheError(load_failure(path, exc)) from None
        entries = [self._entries[n] for n in self._groups[group]]
        _check_abi(cdll, path, entries, self.manifest["casadi_version"])
        fns = {e["name"]: CompiledFunction(cdll, e, self.numbers) for e in entries}
        self._cdlls[group], self.paths[group] = cdll, path
        if group == CORE:
            self._lib = cdll
        self._ctypes.update(fns)
        if self._binder is not None:
            try:
                self._fast.update(self._binder(list(fns)))
            except BaseException:  # not half loaded: the next use loads the group again
                for name in fns:
                    self._ctypes.pop(name, None)
                self._cdlls.pop(group, None)
                self.paths.pop(group, None)
                raise

    def load(self, group: str) -> Path:
        """Load the library ``group`` (a controller's name, or :data:`CORE`) if it is not yet; its path.

        The first use compiles it (``loader``); a cached library that does not load here (another
        CasADi, another ABI, a corrupt file) is rebuilt once."""
        with self._lock:
            if group in self.paths:
                return self.paths[group]
            if group not in self._groups:
                raise KeyError(f"no library '{group}' in this build; libraries: {', '.join(self._groups)}")
            path = self._loader(group, False)
            try:
                self._open(group, path)
            except BuildCacheError:
                self._open(group, self._loader(group, True))
            return self.paths[group]

    def loaded_groups(self) -> tuple:
        """The libraries loaded so far, in the order they were loaded."""
        return tuple(self.paths)

    def unoptimized(self) -> tuple:
        """The loaded libraries a quick build compiled unoptimized (``hydrogen.build(..., quick=True)``):
        the same numbers, each call slower; a build after the optimized objects are in loads those."""
        made = set(getattr(self._loader, "unoptimized", {}).values())
        return tuple(g for g, p in self.paths.items() if p in made)

    def groups(self) -> tuple:
        """Every library of this build: :data:`CORE`, then the controllers'."""
        return tuple(self._groups)

    def attach(self, binder) -> LazyFunctions:
        """Give the library extension functions: ``binder(names)`` returns them by name for functions
        already loaded; it is called now for the loaded libraries and again for each one loaded later."""
        with self._lock:
            self._binder = None
            self._fast.clear()
            self._fast.update(binder([n for n in self.group_of if n in self._ctypes]))
            self._binder = binder
            return LazyFunctions(self, self._fast)

    def detach(self) -> None:
        """Drop the extension functions (ctypes calls only)."""
        with self._lock:
            self._binder = None
            self._fast.clear()

    def symbol(self, name: str):
        """A C symbol of a loaded library (ctypes function), e.g. the loop driver's entry points."""
        for cdll in list(self._cdlls.values()):
            try:
                return getattr(cdll, name)
            except AttributeError:
                continue
        raise BuildCacheError(f"{self.path}: no symbol '{name}'; rebuild")

    def __getitem__(self, name) -> CompiledFunction:
        return self.functions[name]


def _numbers_vector(manifest: dict, numbers: dict | None):
    names = manifest.get("numbers")
    if names is None:
        return None
    numbers = numbers() if callable(numbers) else numbers
    missing = [n for n in names if numbers is None or n not in numbers]
    if missing:
        raise BuildCacheError(f"the generated functions take the description's numbers, and {missing[0]} is not "
                              f"among the ones given ({len(missing)} missing); build with hydrogen.build")
    out = np.array([numbers[n] for n in names], float)
    out.setflags(write=False)
    return out


def _check_abi(cdll, path: Path, entries: list, casadi_version: str) -> None:
    for entry in entries:
        stem = Path(entry["source"]).stem
        try:
            int_size = getattr(cdll, stem + "_casadi_int_size")
            real_size = getattr(cdll, stem + "_casadi_real_size")
            version = getattr(cdll, stem + "_casadi_version")
        except AttributeError as exc:
            raise BuildCacheError(f"{path}: missing symbol ({exc}); not a hydrogen build") from None
        if int_size() != ctypes.sizeof(_c_int) or real_size() != ctypes.sizeof(ctypes.c_double):
            raise BuildCacheError(
                f"{path}: {entry['c_name']} was built with casadi_int of {int_size()} bytes and "
                f"casadi_real of {real_size()} bytes; this runtime needs 8 and 8")
        v = [ctypes.c_int() for _ in range(3)]
        version(*map(ctypes.byref, v))
        built = ".".join(str(x.value) for x in v)
        if built != casadi_version:
            raise BuildCacheError(
                f"{path}: {entry['c_name']} comes from CasADi {built}, the generated "
                f"folder from CasADi {casadi_version}; rebuild")
