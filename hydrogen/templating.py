"""The one Jinja environment for every template hydrogen renders (C drivers, headers, build files).

A description file is data: the names in it (links, joints, coordinates, cylinders, parameters)
are checked at load time (:mod:`hydrogen.names`), and here every value a template writes goes
through one escape for the kind of file it lands in, so even a name that bypassed the loader
(a :class:`~hydrogen.model.Model` built in Python) can neither close a C string or comment nor
start a preprocessor line:

* C sources and headers (``*.c.j2``, ``*.h.j2``): every character outside a plain set (letters,
  digits, space and ``_.,:;+-=()[]{}<>%'``) becomes a three-digit octal escape. Inside a C
  string literal the compiler decodes it back to the same character, so strings (FMU variable
  names, coordinate names) keep their exact text; inside a comment it is inert text. The values
  hydrogen itself writes in code positions (numbers, identifiers) use only the plain set, so
  their output is unchanged.
* Build files (``Makefile.j2``, ``CMakeLists.txt.j2``): a value with anything but letters,
  digits, space and ``_.-`` is refused (Make and CMake have no escape that is safe everywhere).

Imports neither SymPy, CasADi nor numpy (the runtime renders the CPython extension with it).
"""
from __future__ import annotations

import re
from pathlib import Path

from .errors import HydrogenError

__all__ = ["render", "c_escape", "TemplateValueError"]

_C_PLAIN = re.compile(r"[A-Za-z0-9 _.,:;+\-=()\[\]{}<>%']*")
_C_OTHER = re.compile(r"[^A-Za-z0-9 _.,:;+\-=()\[\]{}<>%']")
_BUILD_PLAIN = re.compile(r"[A-Za-z0-9 _.\-]*")


class TemplateValueError(HydrogenError):
    """A value cannot be written into a generated build file."""


def c_escape(value) -> str:
    """``str(value)`` with every character outside the plain set as a C octal escape (UTF-8 bytes);
    text hydrogen's own code marks as :class:`markupsafe.Markup` (comments it writes) as it is."""
    from markupsafe import Markup

    if isinstance(value, Markup):
        return str(value)
    text = str(value)
    if _C_PLAIN.fullmatch(text):
        return text
    return _C_OTHER.sub(lambda m: "".join(f"\\{b:03o}" for b in m.group().encode("utf-8")), text)


def _build_value(template: str):
    def check(value) -> str:
        text = str(value)
        if not _BUILD_PLAIN.fullmatch(text):
            raise TemplateValueError(f"{template}: the value {text[:80]!r} cannot be written into a build file "
                                     "(letters, digits, spaces, '_', '.' and '-' only)")
        return text
    return check


_ENVIRONMENTS: dict = {}


def _environment(folder: Path, finalize):
    import jinja2

    return jinja2.Environment(loader=jinja2.FileSystemLoader(str(folder)), undefined=jinja2.StrictUndefined,
                              keep_trailing_newline=True, trim_blocks=True, lstrip_blocks=True, finalize=finalize)


def render(template: str, context: dict, folder: Path | None = None) -> str:
    """Render ``template`` (a file name in ``folder``, default the package's templates) with
    ``context``, every value escaped for the file type (see the module docstring)."""
    if folder is None:
        from .resources import templates_dir
        folder = templates_dir()
    c_file = template.endswith((".c.j2", ".h.j2"))
    key = (str(folder), template if not c_file else "c")
    env = _ENVIRONMENTS.get(key)
    if env is None:
        env = _ENVIRONMENTS[key] = _environment(Path(folder), c_escape if c_file else _build_value(template))
    return env.get_template(template).render(**context)
