"""Names that hydrogen writes into generated files: C symbols, file names, Makefile and CMake text.

A model name becomes part of C symbols (``<model>_leg_lengths``), of file names
(``<model>_loop.c``) and of the exported ``Makefile`` and ``CMakeLists.txt``, so it
must be safe in all of them. :func:`check_identifier` accepts:

* ASCII letters, digits and underscores only (C identifiers; portable file names on
  every file system, no shell, Make or CMake meta-characters, no case folding
  surprises from non-ASCII);
* starting with a letter (C reserves names that start with an underscore);
* no trailing underscore and no double underscore (``<model>_<function>`` must split
  back unambiguously; C++ reserves ``__``);
* at most :data:`MAX_IDENTIFIER` characters (C compilers and linkers accept far more;
  file names stay well under the usual 255-byte limit with every suffix appended).

Other names written into generated text (a scenario's name in the exported
Makefile, CMakeLists.txt, params.h and main.c) are checked by :func:`check_label`:
the same, plus ``-`` and ``.`` inside (``z-1hz``), never a newline, a quote, ``$``,
``*/`` or a space.

The names a description gives (links, joints, coordinates, cylinders, from TOML or URDF) are
written into generated C comments and strings, the FMU's variable names and the logs' columns,
and are checked by :func:`check_name` when the description is loaded: the label rule without
``.``, which separates a link from its parameter (``boom.mass``) and the parts of an FMI
structured name. (Every value a template writes is escaped again for its file type:
:mod:`hydrogen.templating`.)
"""
from __future__ import annotations

import re

from .errors import ModelError

__all__ = ["check_identifier", "check_label", "check_name", "MAX_IDENTIFIER", "NUMBERS"]

#: The input of every function of a folder generated with the description's numbers as inputs
#: (the manifest's ``numbers`` names its entries): the runtime fills it, a caller never passes it.
#: Named here, below the derivation, which gives its functions the input by this name.
NUMBERS = "numbers"

#: Longest accepted model name (characters).
MAX_IDENTIFIER = 64

_IDENTIFIER = re.compile(r"[A-Za-z](?:[A-Za-z0-9]|_(?!_))*")
_LABEL = re.compile(r"[A-Za-z0-9](?:[A-Za-z0-9_.-]*[A-Za-z0-9])?")
_NAME = re.compile(r"[A-Za-z0-9](?:[A-Za-z0-9_-]*[A-Za-z0-9])?")


def _shown(value) -> str:
    text = repr(value)
    return text if len(text) <= 80 else text[:60] + f"... ({len(text)} characters)"


def check_identifier(value, where: str, error=ModelError) -> str:
    """``value`` if it is a safe name for C symbols and files (see the module docstring), else
    ``error`` (default :class:`~hydrogen.errors.ModelError`) naming ``where``."""
    if not isinstance(value, str):
        raise error(f"{where}: expected a name (a string), got {type(value).__name__} {_shown(value)}")
    problem = None
    if not value:
        problem = "is empty"
    elif len(value) > MAX_IDENTIFIER:
        problem = f"is {len(value)} characters long (at most {MAX_IDENTIFIER})"
    elif not value.isascii():
        problem = "has non-ASCII characters"
    elif not value[0].isalpha():
        problem = "must start with a letter"
    elif value.endswith("_"):
        problem = "must not end with an underscore"
    elif "__" in value:
        problem = "must not contain a double underscore"
    elif not _IDENTIFIER.fullmatch(value):
        problem = "may hold only ASCII letters, digits and single underscores"
    if problem:
        raise error(f"{where}: the name {_shown(value)} {problem} (it becomes C symbol and file names: "
                    f"letters, digits and single underscores, starting with a letter, "
                    f"at most {MAX_IDENTIFIER} characters)")
    return value


def check_label(value, where: str, error=ModelError) -> str:
    """``value`` if it is safe to write into a Makefile, CMake file or C comment (letters, digits,
    ``_``, ``-`` and ``.``, starting and ending with a letter or digit, at most
    :data:`MAX_IDENTIFIER` characters), else ``error`` naming ``where``."""
    if not isinstance(value, str) or len(value) > MAX_IDENTIFIER or not value.isascii() \
            or not _LABEL.fullmatch(value):
        raise error(f"{where}: {_shown(value)} cannot be written into generated files; use ASCII letters, "
                    f"digits, '_', '-' and '.', starting and ending with a letter or digit, "
                    f"at most {MAX_IDENTIFIER} characters")
    return value


def check_name(value, where: str, error=ModelError) -> str:
    """``value`` if it is a safe name for a description's link, joint, coordinate or cylinder
    (letters, digits, ``_`` and ``-``, starting and ending with a letter or digit, at most
    :data:`MAX_IDENTIFIER` characters), else ``error`` naming ``where``."""
    if not isinstance(value, str) or len(value) > MAX_IDENTIFIER or not value.isascii() \
            or not _NAME.fullmatch(value):
        raise error(f"{where}: the name {_shown(value)} is not allowed: names are written into generated C, "
                    f"FMUs and logs, so use ASCII letters, digits, '_' and '-', starting and ending with a "
                    f"letter or digit, at most {MAX_IDENTIFIER} characters")
    return value
