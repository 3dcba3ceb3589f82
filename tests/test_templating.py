"""hydrogen/templating.py: every template, rendered with hostile names, is the same program.

The loader refuses such names (tests/test_names.py); these tests bypass it (a Model built in
Python) and check the second line of defence: each C template rendered with names that try to
close a string or a comment, start a preprocessor line or call ``system`` compiles to the same
tokens as with plain names (only string and comment contents differ), strings keep the names'
exact text, an exported program and an FMU built from them behave exactly as the plain ones, and
nothing outside the output folder is touched.
"""
import ast
import dataclasses
import json
import re
import subprocess

import numpy as np
import pytest

import hydrogen
from hydrogen.codegen.generate import render_drivers
from hydrogen.export import export
from hydrogen.runtime import extension
from hydrogen.runtime.build import generated_dir_for
from hydrogen.runtime.compiler import Toolchain
from hydrogen.templating import TemplateValueError, c_escape, render

MODEL = "excavator_arm"  # the smaller shipped robot: its programs and FMUs compile fastest


def hostile(i: int, marker) -> str:
    """A name that would run ``touch marker`` if a template wrote it unescaped."""
    return (f'c{i}" ); system("touch {marker}"); /* */ int x{i} = 0; // \\\n'
            f'#define exit(s) system("touch {marker}") ??/\n$(shell touch {marker}) `touch {marker}` \'')


def _tokens(c_text: str) -> list:
    """C tokens with comments dropped and string/char literal contents blanked."""
    pattern = r'"(?:\\.|[^"\\\n])*"|\'(?:\\.|[^\'\\\n])*\'|/\*.*?\*/|//[^\n]*|[A-Za-z_]\w*|\d[\w.]*|\S'
    out = []
    for tok in re.findall(pattern, c_text, re.S):
        if tok.startswith(("/*", "//")):
            continue
        out.append('""' if tok.startswith('"') else "''" if tok.startswith("'") else tok)
    return out


def _strings(c_text: str) -> set:
    """The decoded string literals of a C text."""
    lits = re.findall(r'"((?:\\.|[^"\\\n])*)"', re.sub(r"/\*.*?\*/|//[^\n]*", "", c_text, flags=re.S))
    return {ast.literal_eval('b"' + s + '"').decode() for s in lits}


@pytest.fixture(scope="module")
def arm(cache):
    return hydrogen.build(MODEL, cache=cache)


@pytest.fixture(scope="module")
def hostile_arm(arm, tmp_path_factory):
    """The arm's dynamics with every description name replaced by a hostile one."""
    marker = tmp_path_factory.mktemp("outside") / "PWNED"
    m = arm.model
    k = iter(range(1000))
    links = {lk.name: hostile(next(k), marker).replace(".", "") for lk in m.links}
    coords = {c: hostile(next(k), marker) for c in m.coordinate_names}
    model = dataclasses.replace(
        m, coordinate_names=tuple(coords.values()), scenarios=_renamed(m.scenarios, coords),
        cylinders=tuple(dataclasses.replace(c, name=hostile(next(k), marker)) for c in m.cylinders),
        links=tuple(dataclasses.replace(lk, name=links[lk.name]) for lk in m.links),
        theta_names=tuple(links[t.split(".")[0]] + "." + t.split(".")[1] for t in m.theta_names))
    assert np.array_equal(model.theta, m.theta)
    # the library's numbers keep the arm's names (the manifest lists them so; a hostile name is refused
    # in params.h's comments): their ranges and order rules are the arm's, by those names
    for attr in ("number_ranges", "number_orders"):
        object.__setattr__(model, attr, getattr(m, attr))
    manifest = json.loads(json.dumps(arm.library.manifest))
    manifest["model"].update(coordinates=list(model.coordinate_names),
                             cylinders=[c.name for c in model.cylinders], theta_names=list(model.theta_names))
    return _Proxy(arm, model, manifest), marker


def _renamed(data, names: dict):
    """``data`` (parsed TOML) with every string equal to a key of ``names`` replaced."""
    if isinstance(data, dict):
        return {k: _renamed(v, names) for k, v in data.items()}
    if isinstance(data, list):
        return [_renamed(v, names) for v in data]
    return names.get(data, data) if isinstance(data, str) else data


class _Proxy:
    """``dyn`` seen through another Model and manifest (everything else is the real library's)."""

    def __init__(self, dyn, model, manifest):
        self._dyn, self.model = dyn, model
        self.library = _LibraryProxy(dyn.library, manifest)

    def __getattr__(self, name):
        return getattr(self._dyn, name)


class _LibraryProxy:
    def __init__(self, library, manifest):
        self._library, self.manifest = library, manifest

    def __getattr__(self, name):
        return getattr(self._library, name)


def test_c_escape_keeps_plain_text_and_round_trips_through_the_compiler(tmp_path):
    assert c_escape("leg1, 2.5e-3 (m) [x]") == "leg1, 2.5e-3 (m) [x]"
    names = [hostile(0, "/tmp/x"), "é\t\x01", "*/", "??=", "\\"]
    src = "#include <stdio.h>\nint main(void) {\n" + "".join(
        f'    puts("{c_escape(n)}"); /* {c_escape(n)} */\n' for n in names) + "    return 0;\n}\n"
    (tmp_path / "t.c").write_text(src)
    tc = Toolchain()
    subprocess.run([tc.cc, "-std=c99", "-Wall", "-Wextra", "-Werror", "-o", str(tmp_path / "t"),
                    str(tmp_path / "t.c")], check=True, capture_output=True, timeout=120)
    out = subprocess.run([str(tmp_path / "t")], capture_output=True, timeout=30).stdout.decode()
    assert out == "".join(n + "\n" for n in names)


def test_build_files_refuse_what_make_would_expand():
    ctx = {"model": "m", "scenario": "s$(shell touch x)", "controller": "p", "prog": "m_p", "sources": [],
           "headers": []}
    with pytest.raises(TemplateValueError, match="cannot be written into a build file"):
        render("Makefile.j2", ctx)
    with pytest.raises(TemplateValueError, match="cannot be written into a build file"):
        render("CMakeLists.txt.j2", ctx)


def _syntax_check(folder, c_file):
    tc = Toolchain()
    proc = subprocess.run([tc.cc, "-std=c99", "-Wall", "-Wextra", "-Werror", "-fsyntax-only", "-I", str(folder),
                           str(folder / c_file)], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]


def test_loop_driver_and_extension_render_to_the_same_tokens(arm, hostile_arm, tmp_path):
    dyn, _ = hostile_arm
    gen = generated_dir_for(arm.model)
    texts = {}
    for which, manifest in (("plain", arm.library.manifest), ("hostile", dyn.library.manifest)):
        folder = tmp_path / which
        folder.mkdir()
        for h in gen.glob("*.h"):
            (folder / h.name).write_bytes(h.read_bytes())
        names = render_drivers(manifest, folder)
        (folder / "pyext.c").write_text(extension.render(extension.render_context(manifest)))
        for name in names:
            if name.endswith(".c"):
                _syntax_check(folder, name)
        texts[which] = {n: (folder / n).read_text() for n in [*names, "pyext.c"]}
    assert texts["plain"].keys() == texts["hostile"].keys()
    for name in texts["plain"]:
        assert _tokens(texts["plain"][name]) == _tokens(texts["hostile"][name]), name
    loop_h = next(t for n, t in texts["hostile"].items() if n.endswith("_loop.h"))
    assert "system(" not in re.sub(r"/\*.*?\*/", "", loop_h, flags=re.S)


def _run_export(folder):
    proc = subprocess.run(["make", "-s", "-C", str(folder), "run"], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return re.sub(r"cpu_s_per_period \S+\n", "", proc.stdout)  # the one line that is a timing


def test_an_export_with_hostile_names_is_the_same_program(arm, hostile_arm, tmp_path):
    dyn, marker = hostile_arm
    gen = generated_dir_for(arm.model)
    kw = dict(scenario="arm-dig", controller="p", duration=0.05, generated=gen)
    plain = export(tmp_path / "plain", dyn=arm, **kw)
    bad = export(tmp_path / "hostile", dyn=dyn, **kw)
    for name in ("main.c", "params.h"):
        p_text, h_text = (plain / name).read_text(), (bad / name).read_text()
        assert _tokens(p_text) == _tokens(h_text), name
    assert set(dyn.model.coordinate_names) <= _strings((bad / "main.c").read_text())
    out_plain, out_bad = _run_export(plain), _run_export(bad)
    for p_name, h_name in zip(arm.model.coordinate_names, dyn.model.coordinate_names):
        out_bad = out_bad.replace(h_name, p_name)
    assert out_bad == out_plain
    assert not marker.exists()
    assert sorted(p.name for p in marker.parent.iterdir()) == []


def test_an_fmu_with_hostile_names_keeps_them_and_steps_as_the_plain_one(arm, hostile_arm, tmp_path):
    fmpy = pytest.importorskip("fmpy")
    from hydrogen.fmu import export_fmu

    dyn, marker = hostile_arm
    kw = dict(scenario="arm-dig", controller="p", duration=0.05, generated=generated_dir_for(arm.model))
    plain = export_fmu(tmp_path / "plain.fmu", "closed-loop", dyn=arm, **kw)
    bad = export_fmu(tmp_path / "hostile.fmu", "closed-loop", dyn=dyn, **kw)
    names = [v.name for v in fmpy.read_model_description(str(bad)).modelVariables]
    for c in dyn.model.coordinate_names:  # the XML carries each name exactly (structured, quoted)
        assert any(c.replace("\\", "\\\\").replace("'", "\\'") in n for n in names), c
    r_plain = fmpy.simulate_fmu(str(plain))
    r_bad = fmpy.simulate_fmu(str(bad))
    a = np.array([list(row) for row in r_plain])
    b = np.array([list(row) for row in r_bad])
    assert a.shape == b.shape and np.array_equal(a, b)
    assert not marker.exists()
