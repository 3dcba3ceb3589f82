"""hydrogen/layout.py: the loop configuration is described once; the C header, the ctypes mirror
and the exported programs' fill agree with that description."""
import copy
import re
import subprocess

import ctypes as C

import pytest

from hydrogen import references
from hydrogen.layout import LOOP_CONFIG, loop_context, plant_offsets
from hydrogen.pressures import n_pressures
from hydrogen.runtime.build import generated_dir_for
from hydrogen.runtime.compiler import Toolchain
from hydrogen.runtime.loop import _structs


def test_the_c_struct_and_the_ctypes_mirror_have_the_same_fields_offsets_and_size(dyn, tmp_path):
    manifest = dyn.library.manifest
    ctx = loop_context(manifest)
    Config = _structs(ctx)[0]
    names = [f for _, fields in LOOP_CONFIG for f, _, _, _ in fields]
    assert [n for n, _ in Config._fields_] == names
    p = ctx["p"]
    src = tmp_path / "offsets.c"
    src.write_text("#include <stdio.h>\n#include <stddef.h>\n"
                   f'#include "{p}_loop.h"\nint main(void) {{\n'
                   f'    printf("size %zu\\n", sizeof({p}_loop_config));\n'
                   + "".join(f'    printf("{n} %zu\\n", offsetof({p}_loop_config, {n}));\n' for n in names)
                   + "    return 0;\n}\n")
    exe = tmp_path / "offsets"
    subprocess.run([Toolchain().cc, "-std=c99", "-Wall", "-Werror", "-I", str(generated_dir_for(dyn.model)),
                    "-o", str(exe), str(src)], check=True, capture_output=True, timeout=120)
    out = dict(line.split() for line in subprocess.run([str(exe)], capture_output=True, text=True,
                                                        timeout=30).stdout.splitlines())
    assert int(out["size"]) == C.sizeof(Config)
    for n in names:
        assert int(out[n]) == getattr(Config, n).offset, n


def test_the_exported_fill_sets_every_field_with_a_value_and_nothing_else(dyn):
    from hydrogen.export import render_template

    ctx = loop_context(dyn.library.manifest)
    config = [{**g, "fields": [{**f, "definition": None} for f in g["fields"]]} for g in ctx["config"]]
    text = render_template("export_params.h.j2", {**_params_stub(ctx), "config": config})
    fill = text[text.index("static void p_fill_config"):]
    for _, fields in LOOP_CONFIG:
        for name, _, value, _ in fields:
            assert bool(re.search(rf"cfg->{name}\b", fill)) == (value is not None), name


def _params_stub(ctx):
    """Just enough of the export context to render params.h (values do not matter here)."""
    import jinja2
    import jinja2.meta

    from hydrogen.codegen.generate import TEMPLATES

    source = (TEMPLATES / "export_params.h.j2").read_text()
    env = jinja2.Environment()
    names = jinja2.meta.find_undeclared_variables(env.parse(source))
    stub = {n: "0" for n in names}
    stub.update(model=ctx["model"], inputs=[], outputs=[], slots=[], terms=[], n_terms=0, numbers=[], number_order=[],
                xc_blocks=[], sensor_config=[])
    return stub


def test_the_runtime_and_the_exported_params_fill_the_same_configuration(dyn, tmp_path):
    """Both fills come from one set of values (hydrogen.simulation.loop_config): the configuration the
    runtime hands the C loop equals, field by field, the one params.h's p_fill_config builds."""
    from hydrogen.export import export, prepare_export
    from hydrogen.simulation.simulator import make_runner

    scenario, controller = "z-1hz", "adaptive-robust"
    folder = export(tmp_path / "out", scenario, controller, duration=0.05, dyn=dyn)
    _, _, _, p = prepare_export(None, dyn, scenario, controller, None, 0.05, True, {})
    runner = make_runner(dyn, p.sc, p.ctrl, p.x0, p.q0, p.estimate, p.h)
    cfg, model = runner.cfg, dyn.model.name
    fields = [f for g in loop_context(dyn.library.manifest)["config"] for f in g["fields"] if f["value"]]
    expected, prints = {}, []
    for f in fields:
        name, ctype = f["name"], f["type"]
        v = getattr(cfg, name)
        if ctype in ("double", "long long"):
            values = [v]
        elif ctype == "const double*":
            # the reference kinds' arrays sized by their own declarations (hydrogen.references)
            size = {**references.config_sizes({f2["name"]: getattr(cfg, f2["name"]) for f2 in fields
                                              if f2["type"] == "long long"}),
                    "theta": len(dyn.model.theta), "pred_theta": len(dyn.model.theta), "bias": dyn.model.n,
                    "xc_lo": max(cfg.n_xc, 1), "xc_hi": max(cfg.n_xc, 1), "friction": 3 * dyn.model.n_cylinders, "valve": 5 * dyn.model.n_cylinders,
                    "p_low": n_pressures(dyn.model), "p_high": n_pressures(dyn.model),
                    "numbers": 1 if dyn.numbers is None else len(dyn.numbers),
                    "sensor_res": max(loop_context(dyn.library.manifest)["n_sensed"], 1),
                    "sensor_bias": max(loop_context(dyn.library.manifest)["n_sensed"], 1)}.get(name, dyn.model.n_cylinders)
            values = [v[i] for i in range(size)]
        else:
            values = list(v)
        expected[name] = values
        fmt = "%lld" if ctype in ("long long", "slots") else "%.17g"
        prints += [f'    printf("{name} {fmt}\\n", {"(long long)" if fmt == "%lld" else ""}'
                   f'{"c." + name if len(values) == 1 and ctype in ("double", "long long") else f"c.{name}[{i}]"});'
                   for i in range(len(values))]
    src = tmp_path / "fill.c"
    src.write_text("#include <stdio.h>\n#include <string.h>\n"
                   f'#include "{model}_loop.h"\n#include "params.h"\n'
                   f"int main(void) {{\n    {model}_loop_config c;\n    p_fill_config(&c);\n"
                   + "\n".join(prints) + "\n    return 0;\n}\n")
    exe = tmp_path / "fill"
    subprocess.run([Toolchain().cc, "-std=c99", "-Wall", "-Werror", "-Wno-unused-const-variable", "-I",
                    str(folder), "-o", str(exe), str(src)], check=True, capture_output=True, timeout=120)
    got = {}
    for line in subprocess.run([str(exe)], capture_output=True, text=True, timeout=30).stdout.splitlines():
        name, value = line.split()
        got.setdefault(name, []).append(float(value))
    assert set(got) == set(expected) and len(got) == len(fields)
    for name in expected:
        assert got[name] == [float(x) for x in expected[name]], name
    assert got["delay"] == [1.0] and got["use_kalman"] == [1.0]  # the rig's: one period, filtered rates


def test_each_plant_parts_c_offset_is_read_off_the_layout():
    parts = [("q", "n"), ("qdot", "n"), ("pc", "n_pressures"), ("spool", "m"), ("spool_rate", "m")]
    summary = {"plant": [{"name": k, "size": s, "start": 0, "entries": 1} for k, s in parts]}
    assert plant_offsets(summary) == {"q": "0", "qdot": "NQ", "pc": "2 * NQ", "spool": "2 * NQ + NPC",
                                      "spool_rate": "2 * NQ + NPC + NL"}


def test_the_c_loop_follows_a_new_plant_part_in_the_layout(dyn):
    """A part declared before the pressures (one per actuator) moves every pressure access of the
    rendered loop and the state's size: the template writes no part's place itself."""
    from hydrogen.templating import render

    manifest = copy.deepcopy(dyn.library.manifest)
    s = manifest["model"]
    at = [p["name"] for p in s["plant"]].index("pc")
    s["plant"].insert(at, {"name": "extra", "size": "m", "start": -1, "entries": s["m"]})
    old = render("loop.c.j2", loop_context(dyn.library.manifest))
    new = render("loop.c.j2", loop_context(manifest))
    assert "x[2 * NQ + i] = clip(x[2 * NQ + i]" in old
    assert "x[2 * NQ + NL + i] = clip(x[2 * NQ + NL + i]" in new and "x[2 * NQ + i]" not in new
    assert "memcpy(x + 2 * NQ + NL, s->pc_meas" in new and "pc = xp + 2 * NQ + NL;" in new
    assert loop_context(manifest)["nx"] == loop_context(dyn.library.manifest)["nx"] + s["m"]
    assert "plant state x = [q, qdot, extra, pc, spool, spool rate]" in render("loop.h.j2", loop_context(manifest))


def test_a_field_declared_twice_in_the_loop_is_refused(monkeypatch):
    """A block's declared name that clashes with the loop's own (an estimator's number called "delay")
    would give the C struct two members of one name: the layout refuses it at import, naming it."""
    from hydrogen import layout

    original = layout.LOOP_CONFIG
    config = (*original, ("an estimator's numbers", (("delay", "double[1]", "P_DELAY", "run.delay"),)))
    monkeypatch.setattr(layout, "LOOP_CONFIG", config)
    with pytest.raises(ImportError, match="configuration field 'delay' is declared twice"):
        layout._check_unique()
    # a number named as the exported params.h's own start lengths (P_L0, which the estimators' start reads)
    monkeypatch.setattr(layout, "LOOP_CONFIG", (*original, ("numbers", (("l0", "double[1]", "P_L0", "run.l0"),))))
    with pytest.raises(ImportError, match="params.h name 'P_L0' is declared twice"):
        layout._check_unique()
    monkeypatch.setattr(layout, "LOOP_CONFIG", original)
    monkeypatch.setattr(layout, "LOOP_STATE", (*layout.LOOP_STATE, ("k", "double", None, "a clash")))
    with pytest.raises(ImportError, match="declared twice"):
        layout._check_unique()
