"""hydrogen/layout.py: the loop configuration is described once; the C header, the ctypes mirror
and the exported programs' fill agree with that description."""
import re
import subprocess

import ctypes as C

from hydrogen.layout import LOOP_CONFIG, loop_context
from hydrogen.runtime.build import generated_dir_for
from hydrogen.runtime.compiler import Toolchain
from hydrogen.runtime.loop import _structs


def test_the_c_struct_and_the_ctypes_mirror_have_the_same_fields_offsets_and_size(dyn, tmp_path):
    manifest = dyn.library.manifest
    ctx = loop_context(manifest)
    Config = _structs(ctx)[0]
    names = [f for _, fields in LOOP_CONFIG for f, _, _ in fields]
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
    text = render_template("export_params.h.j2", {**_params_stub(ctx), "config": ctx["config"]})
    fill = text[text.index("static void p_fill_config"):]
    for _, fields in LOOP_CONFIG:
        for name, _, value in fields:
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
    stub.update(model=ctx["model"], inputs=[], outputs=[], slots=[], terms=[], n_terms=0)
    return stub
