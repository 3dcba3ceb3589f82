"""The block registries' one way of finding their modules: every module of a package that declares
what a block of its kind must (:mod:`hydrogen.actuators`, :mod:`hydrogen.references`)."""
from __future__ import annotations

import importlib
import pkgutil

__all__ = ["discover"]


def discover(package: str, path, declares: tuple, key, what: str) -> dict:
    """``{key(module): module}`` of every module of ``package`` (found on ``path``, its ``__path__``)
    that declares every attribute named in ``declares``, in the order the modules are found; an
    ImportError naming both modules when two declare the same key (``what``: the block's kind, for it)."""
    found = {}
    for info in pkgutil.iter_modules(path):
        mod = importlib.import_module(f"{package}.{info.name}")
        if all(hasattr(mod, a) for a in declares):
            k = key(mod)
            if k in found:
                raise ImportError(f"{what} {k!r} is declared twice ({found[k].__name__}, {mod.__name__})")
            found[k] = mod
    return found
