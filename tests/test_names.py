"""hydrogen/names.py and its use at load time: a description's names are data, never code.

Each name a description gives (TOML or URDF) is written into generated C, FMUs and logs; a name
that could close a C comment or string, start a preprocessor line or run a shell command is
refused when the file is loaded, naming the file and the field. A description cannot set the
compiler, its flags or where files are written.
"""
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

import hydrogen
from hydrogen.errors import ModelError
from hydrogen.model import model_path
from hydrogen.names import check_name

#: Names that would run code or break a generated file if written unchecked.
HOSTILE = (
    'leg */ int pwned = system("touch PWNED"); /*',
    'x"); system("touch PWNED"); ("',
    "a\n#include </etc/passwd>",
    "$(shell touch PWNED)",
    "a??/",
    "bo\\om",
    "boom.mass",
    "",
    "l" * 65,
    "böom",
    "-lead",
)


@pytest.mark.parametrize("name", ["leg1", "FL_hip", "arm-2", "A9", "x"])
def test_plain_names_pass(name):
    assert check_name(name, "here") == name


@pytest.mark.parametrize("name", HOSTILE)
def test_hostile_names_are_refused(name):
    with pytest.raises(ModelError, match="here: the name"):
        check_name(name, "here")


def _stewart_text():
    return model_path("ubc_stewart").read_text()


def _write(tmp_path, text, name="mine.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def _toml_string(s: str) -> str:
    """A TOML basic string holding ``s`` exactly."""
    return '"' + s.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n") + '"'


PAYLOAD = 'p */ int pwned = system("touch PWNED"); /*'

#: (field, how to put PAYLOAD into the Stewart description, what the error names)
TOML_FIELDS = [
    ("link name", lambda t, p: t.replace('name = "platform"', f"name = {p}").replace('child = "platform"', f"child = {p}"),
     "link"),
    ("joint name", lambda t, p: t.replace('name = "platform_pose"', f"name = {p}"), "joint"),
    ("joint parent", lambda t, p: t.replace('parent = "base"', f"parent = {p}"), "parent"),
    ("coordinate name", lambda t, p: t.replace('names = ["x",', f"names = [{p},"), r"\[coordinates\] names"),
    ("cylinder name", lambda t, p: t.replace('name = "leg1"', f"name = {p}"), r"\[\[cylinders\]\] #1 name"),
    ("scenario name", lambda t, p: t + f"\n[scenarios.{p}]\nreference = \"paper-sim\"\n", r"\[scenarios"),
    ("figures controller", lambda t, p: t + f"\n[figures]\nnonlinear = {p}\n", r"\[figures\] nonlinear"),
]


@pytest.mark.parametrize("field, edit, where", TOML_FIELDS, ids=[f[0] for f in TOML_FIELDS])
def test_a_hostile_toml_name_is_refused_at_load_time(tmp_path, field, edit, where):
    text = edit(_stewart_text(), _toml_string(PAYLOAD))
    assert text != _stewart_text()
    path = _write(tmp_path, text)
    with pytest.raises(ModelError) as err:
        hydrogen.load_model(path)
    msg = str(err.value)
    assert str(path) in msg and re.search(where, msg), msg
    assert "\n" not in msg


def _excavator_copy(tmp_path, edit_urdf):
    toml = model_path("excavator_arm")
    urdf_name = re.search(r'^urdf\s*=\s*"([^"]+)"', toml.read_text(), re.M).group(1)
    urdf = toml.parent / urdf_name
    (tmp_path / urdf_name).write_text(edit_urdf(urdf.read_text()))
    return _write(tmp_path, toml.read_text(), "arm.toml"), tmp_path / urdf_name


def test_a_hostile_urdf_link_name_is_refused_at_load_time(tmp_path):
    # XML character references carry newlines and quotes into the parsed name
    payload = "boom&#10;#define system_call system(&quot;touch PWNED&quot;)"
    path, urdf = _excavator_copy(tmp_path, lambda t: t.replace('"boom"', f'"{payload}"'))
    with pytest.raises(ModelError) as err:
        hydrogen.load_model(path)
    assert "the name" in str(err.value) and "link" in str(err.value), str(err.value)


def test_a_hostile_urdf_joint_name_is_refused_at_load_time(tmp_path):
    toml = model_path("excavator_arm").read_text()
    joint = re.search(r'<joint name="([^"]+)"', (model_path("excavator_arm").parent / "excavator_arm.urdf").read_text())
    assert joint, "the shipped URDF has named joints"
    payload = "j */ x /*"
    path, urdf = _excavator_copy(tmp_path, lambda t: t.replace(f'<joint name="{joint.group(1)}"',
                                                               f'<joint name="{payload}"'))
    del toml
    with pytest.raises(ModelError, match=r"joint .* the name"):
        hydrogen.load_model(path)


@pytest.mark.parametrize("key, value", [("cc", '"sh -c touch PWNED"'), ("cflags", '["-fplugin=/tmp/x.so"]'),
                                        ("compiler", '"clang"'), ("output", '"/etc"'), ("cache", '"/tmp"'),
                                        ("generated", '"../../"')])
def test_a_description_cannot_set_the_compiler_flags_or_paths(tmp_path, key, value):
    path = _write(tmp_path, f"{key} = {value}\n" + _stewart_text())
    with pytest.raises(ModelError, match=f"top level: unknown key '{key}'"):
        hydrogen.load_model(path)


def test_a_description_cannot_build_a_table_for_the_build(tmp_path):
    path = _write(tmp_path, _stewart_text() + '\n[build]\ncflags = ["-O0"]\n')
    with pytest.raises(ModelError, match="unknown key 'build'"):
        hydrogen.load_model(path)


@pytest.mark.parametrize("name", ["../evil", "a/b", "x;rm"])
def test_a_model_name_cannot_reach_a_path(tmp_path, name):
    path = _write(tmp_path, _stewart_text().replace('name = "ubc_stewart"', f"name = {_toml_string(name)}"))
    with pytest.raises(ModelError, match="name"):
        hydrogen.load_model(path)


def test_the_cli_refuses_a_hostile_description_with_exit_2_and_runs_nothing(tmp_path):
    marker = tmp_path / "PWNED"
    payload = f'p */ int pwned = system("touch {marker}"); /*'
    path = _write(tmp_path, _stewart_text().replace('name = "leg1"', f"name = {_toml_string(payload)}"))
    # the hydrogen under test, also when it is not installed (cwd is tmp_path, not the checkout)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(Path(hydrogen.__file__).parents[1]),
                                                        os.environ.get("PYTHONPATH", "")])}
    proc = subprocess.run([sys.executable, "-m", "hydrogen", "simulate", "--model", str(path), "--scenario",
                           "paper-sim", "--controller", "p", "--duration", "0.01"],
                          capture_output=True, text=True, timeout=300, cwd=tmp_path, env=env)
    assert proc.returncode == 2, proc.stderr
    assert "Traceback" not in proc.stderr and str(path) in proc.stderr and "the name" in proc.stderr
    assert not marker.exists()
