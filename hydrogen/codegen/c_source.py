"""Edits of the C that CasADi writes, applied to every generated source before it is saved.

Each edit keeps what the code computes and what a caller may pass (a NULL input still reads as
zeros); they are textual, on the forms CasADi's code generator prints, and a source without those
forms passes through unchanged.
"""
from __future__ import annotations

import re

#: the body of a function CasADi writes for an SX graph
_SX_FUNCTION = re.compile(
    r"^(static int casadi_f\d+\(const casadi_real\*\* arg, casadi_real\*\* res, "
    r"casadi_int\* iw, casadi_real\* w, int mem\) \{)$", re.M)
_RELEASE = re.compile(r"^(CASADI_SYMBOL_EXPORT void \w+_release\(int mem\) \{)$", re.M)
#: one input element read as CasADi prints it: ``arg[k]? arg[k][i] : 0``
_READ = re.compile(r"arg\[(\d+)\]\? arg\[\1\]\[(\d+)\] : 0")
_UNUSED = "  (void)arg; (void)res; (void)iw; (void)w; (void)mem;\n"
ZEROS = "hg_zeros"


def tidy(c_source: str) -> str:
    """The C source with both edits of this module applied."""
    return hoist_input_reads(mark_unused(c_source))


def mark_unused(c_source: str) -> str:
    """Mark the parameters CasADi leaves unused, so the C is clean under -Wall -Wextra -Werror."""
    c_source = _SX_FUNCTION.sub(lambda m: m.group(1) + "\n" + _UNUSED.rstrip("\n"), c_source)
    return _RELEASE.sub(r"\1\n  (void)mem;", c_source)


def hoist_input_reads(c_source: str) -> str:
    """Test each input pointer for NULL once per call instead of at every element read.

    CasADi reads an input element as ``arg[k]? arg[k][i] : 0``; a function taking a description's
    numbers as inputs reads dozens of them per call, and the test and branch of each cost more than
    the load. Each SX function gets ``const casadi_real* hg_in<k> = arg[k] ? arg[k] : hg_zeros;`` for
    the inputs it reads, and every read becomes ``hg_in<k>[i]``; ``hg_zeros`` (static, file-local)
    is as long as the longest read, so a NULL input still reads as zeros. Needs :func:`mark_unused`
    first: the declarations go after its line.
    """
    starts = [m.end() for m in _SX_FUNCTION.finditer(c_source)]
    if not starts:
        return c_source
    pieces, width = [c_source[:starts[0]]], 0
    for start, end in zip(starts, starts[1:] + [len(c_source)]):
        body = c_source[start:end]
        reads = _READ.findall(body)
        if not body.startswith("\n" + _UNUSED) or not reads:
            pieces.append(body)
            continue
        width = max([width] + [int(i) + 1 for _, i in reads])
        inputs = sorted({int(k) for k, _ in reads})
        decl = "".join(f"  const casadi_real* hg_in{k} = arg[{k}] ? arg[{k}] : {ZEROS};\n" for k in inputs)
        body = _READ.sub(lambda r: f"hg_in{r.group(1)}[{r.group(2)}]", body)
        split = 1 + len(_UNUSED)
        pieces.append(body[:split] + decl + body[split:])
    if not width:
        return c_source
    # the zeros go above the first function and CasADi's comment naming it
    head = pieces[0]
    sig = head.rfind("static int casadi_f")
    above = head.rfind("\n", 0, sig - 1) + 1
    at = above if head.startswith("/*", above) else sig
    pieces[0] = head[:at] + f"static const casadi_real {ZEROS}[{width}] = {{0}};\n\n" + head[at:]
    return "".join(pieces)
