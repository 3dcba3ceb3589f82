"""The CPython extension of a generated library: rendered, compiled, cached, loaded and bound.

The extension (``templates/pyext.c.j2``, rendered from the manifest) holds no generated code: it
gets the address of every generated function from the already loaded shared library and calls
it directly (METH_FASTCALL-style vectorcall, numpy's C API), with batches in one C loop. It is
built by :func:`~hydrogen.runtime.compiler.compile_extension` with the library's toolchain and
cached under a key over the template, the manifest's functions, the Python version and ABI and the
Python and numpy header folders. Without the Python headers, or when the build fails, the runtime
keeps the ctypes calls of :mod:`hydrogen.runtime.library` (one warning line).
"""
from __future__ import annotations

import ctypes
import hashlib
import importlib.machinery
import importlib.util
import json
import sys
import sysconfig
import warnings
from pathlib import Path

from ..errors import BuildCacheError, InputError
from ..layout import NUMBERS
from .compiler import Toolchain, compile_extension

__all__ = ["attach_extension", "build_extension", "load_extension", "bind_functions", "abi_key",
           "python_include_dir", "numpy_include_dir", "unavailable_reason", "TEMPLATE", "BACKENDS"]

TEMPLATE = "pyext.c.j2"
BACKENDS = ("auto", "extension", "ctypes")


def _templates() -> Path:
    from ..codegen.generate import TEMPLATES
    return TEMPLATES


def python_include_dir() -> Path:
    """Folder of this interpreter's ``Python.h``."""
    return Path(sysconfig.get_paths()["include"])


def numpy_include_dir() -> Path:
    import numpy
    return Path(numpy.get_include())


def abi_key() -> dict:
    """What a compiled extension depends on in this interpreter (part of its cache key)."""
    import numpy
    return {"python": sys.version, "cache_tag": sys.implementation.cache_tag,
            "ext_suffix": sysconfig.get_config_var("EXT_SUFFIX"), "abiflags": getattr(sys, "abiflags", ""),
            "platform": sysconfig.get_platform(), "include": str(python_include_dir()),
            "numpy": numpy.__version__, "numpy_include": str(numpy_include_dir())}


def unavailable_reason() -> str | None:
    """Why the extension cannot be built here (missing headers or template), or None."""
    header = python_include_dir() / "Python.h"
    if not header.is_file():
        return f"no Python headers ({header} is missing; install the Python development package)"
    numpy_header = numpy_include_dir() / "numpy" / "arrayobject.h"
    if not numpy_header.is_file():
        return f"no numpy C headers ({numpy_header} is missing)"
    template = _templates() / TEMPLATE
    if not template.is_file():
        return f"template {template} not found (install hydrogen from a source checkout)"
    return None


def module_name(manifest: dict) -> str:
    return f"_hydrogen_{manifest['model_name']}"


def _user_inputs(entry: dict) -> tuple:
    """``(inputs a caller passes, whether the function takes the description's numbers)``: the
    numbers input (:data:`hydrogen.layout.NUMBERS`, always the last) is filled at bind time."""
    inputs = [(n, int(r), int(c)) for n, r, c in entry["inputs"]]
    names = [n for n, _, _ in inputs]
    if NUMBERS not in names:
        return inputs, False
    if names.index(NUMBERS) != len(names) - 1:
        raise BuildCacheError(f"{entry['c_name']}: the numbers input is not the last; regenerate")
    return inputs[:-1], True


def render_context(manifest: dict) -> dict:
    fns = []
    for e in manifest["functions"]:
        inputs, numbers = _user_inputs(e)
        fns.append({"name": e["name"], "c_name": e["c_name"], "inputs": [list(i) for i in inputs],
                    "numbers": numbers, "outputs": [[n, int(r), int(c)] for n, r, c in e["outputs"]]})
    return {"model": manifest["model_name"], "module": module_name(manifest),
            "casadi_int": manifest.get("casadi_int", "long long int"), "functions": fns,
            "max_in": max([len(f["inputs"]) for f in fns] + [1]),
            "max_out": max([len(f["outputs"]) for f in fns] + [1])}


def render(context: dict) -> str:
    from ..templating import render as render_template

    return render_template(TEMPLATE, context, _templates())


def build_extension(manifest: dict, toolchain: Toolchain | None = None, cache: Path | None = None,
                    force: bool = False, prefer: Toolchain | None = None) -> Path:
    """Render and compile the extension for ``manifest`` (or find it in the cache); its path.
    ``prefer``: a toolchain whose cached build is taken first (:func:`compile_extension`)."""
    context = render_context(manifest)
    template = (_templates() / TEMPLATE).read_bytes()
    key = json.dumps({"template": hashlib.sha256(template).hexdigest(), "context": context, "abi": abi_key()},
                     sort_keys=True)
    return compile_extension(lambda: render(context), key, context["module"], toolchain, cache,
                             include_dirs=(python_include_dir(), numpy_include_dir()), force=force, prefer=prefer)


def load_extension(path: Path, name: str):
    """Import the compiled extension module at ``path`` (not entered in ``sys.modules``)."""
    loader = importlib.machinery.ExtensionFileLoader(name, str(path))
    spec = importlib.util.spec_from_file_location(name, str(path), loader=loader)
    module = importlib.util.module_from_spec(spec)
    loader.exec_module(module)
    return module


def bind_functions(module, library):
    """Extension Functions for the generated functions of ``library``, bound to the library's code: a
    mapping by name (:class:`~hydrogen.runtime.library.LazyFunctions`) whose functions are bound as
    their libraries are loaded (a controller's on its first use).

    The extension's table (names, C names, shapes) must equal the manifest's, or nothing is bound.
    """
    manifest = library.manifest
    want = tuple((e["name"], e["c_name"], tuple(_user_inputs(e)[0]),
                  tuple((n, int(r), int(c)) for n, r, c in e["outputs"]), int(_user_inputs(e)[1]))
                 for e in manifest["functions"])
    if module.specs() != want:
        raise BuildCacheError(f"{module.__file__}: the extension's functions differ from the manifest's; rebuild")
    if module.CASADI_INT_SIZE != ctypes.sizeof(ctypes.c_longlong):
        raise BuildCacheError(f"{module.__file__}: casadi_int of {module.CASADI_INT_SIZE} bytes; runtime needs 8")
    index = {e["name"]: (i, e) for i, e in enumerate(manifest["functions"])}

    def bind(names) -> dict:
        slow_fns = library.functions.loaded()
        out = {}
        for name in names:
            i, entry = index[name]
            c_name = entry["c_name"]
            addr = ctypes.cast(library.symbol(c_name), ctypes.c_void_p).value
            work = ctypes.cast(library.symbol(c_name + "_work"), ctypes.c_void_p).value
            numbers = library.numbers.ctypes.data if _user_inputs(entry)[1] else 0  # kept alive by library
            fn = module.bind(i, addr, work, library, numbers)
            slow = slow_fns[name]
            fn.__doc__ = entry.get("doc", "")
            for attr in ("name", "c_name", "doc", "in_names", "arg_names", "out_names", "in_shapes", "out_shapes",
                         "unread_inputs"):
                setattr(fn, attr, getattr(slow, attr))
            fn.backend = "extension"
            fn.clone = slow.clone  # a ctypes function with buffers of its own (controller runtimes)
            out[name] = fn
        return out

    return library.attach(bind)


def attach_extension(library, toolchain: Toolchain | None = None, cache: Path | None = None,
                     backend: str = "auto", prefer: Toolchain | None = None) -> str:
    """Give ``library`` its extension functions (``library.extension_functions``) if it can.

    ``backend``: "auto" (the extension, else ctypes with a one-line warning), "extension" (an
    error if it cannot be built) or "ctypes". Returns the backend in use, also set as
    ``library.backend``. ``prefer``: as :func:`build_extension` takes it.
    """
    if backend not in BACKENDS:
        raise InputError(f"backend must be one of {BACKENDS}, got {backend!r}")
    library.extension_functions, library.extension_path, library.backend = None, None, "ctypes"
    if hasattr(library, "detach"):
        library.detach()
    if backend == "ctypes":
        return "ctypes"
    reason = unavailable_reason()
    if reason is None:
        try:
            path = build_extension(library.manifest, toolchain, cache, prefer=prefer)
            try:
                module = load_extension(path, module_name(library.manifest))
            except ImportError:  # a cached file that does not load here: rebuild once
                path = build_extension(library.manifest, toolchain, cache, force=True)
                module = load_extension(path, module_name(library.manifest))
            library.extension_functions = bind_functions(module, library)
            library.extension_path, library.backend = path, "extension"
            return "extension"
        except Exception as exc:  # noqa: BLE001 - an optional accelerator: any failure means ctypes
            text = str(exc).strip()
            reason = f"{type(exc).__name__}: {text.splitlines()[0] if text else ''}"
    if backend == "extension":
        raise BuildCacheError(f"the compiled Python extension cannot be used: {reason}")
    warnings.warn(f"hydrogen: using ctypes calls (slower) instead of the compiled extension: {reason}",
                  RuntimeWarning, stacklevel=3)
    return "ctypes"
