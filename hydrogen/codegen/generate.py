"""Write the generated C for a model: one .c/.h pair per function and a manifest.

Generation is deterministic: the same model and derivation code give
byte-identical files (no timestamps; the manifest is sorted JSON). The output
folder is replaced atomically under an inter-process lock, so an interrupted or
concurrent generation never leaves a half-written folder.
"""
from __future__ import annotations

import functools
import hashlib
import json
import re
import shutil
import tempfile
from pathlib import Path

from ..errors import StaleGeneratedCodeError
from ..fileio import locked, recover_dir, replace_dir, write_file
from ..names import check_identifier
from ..outputs import check_replaceable_dir
from ..resources import templates_dir
from .c_source import tidy

# SymPy, CasADi and the derivation are imported where code is generated, not at import: the
# runtime imports this module for the staleness check only, and stays free of both.

__all__ = [
    "generate", "generate_locked", "extend", "held_controllers", "missing_controllers", "derive", "render",
    "write_function", "check", "check_output", "derivation_hash", "structure_hash", "plant_hash", "drivers_hash",
    "stale_plant", "stale_parts",
    "read_manifest", "expected_manifest_inputs", "numbers_mode", "numbers_hash", "check_numbers_mode", "NUMBERS_MODES",
    "DEFAULT_NUMBERS",
    "MANIFEST", "FORMAT_VERSION",
]

MANIFEST = "manifest.json"
#: Keys every manifest holds: a folder whose manifest has them is a generated folder (may be replaced).
GENERATED_KEYS = ("model_hash", "derivation_hash", "functions")
FORMAT_VERSION = 2
CODEGEN_OPTIONS = {"with_header": True, "casadi_int": "long long int", "casadi_real": "double",
                   "verbose": True}

_PACKAGE = Path(__file__).resolve().parent.parent
TEMPLATES = templates_dir()  # top-level templates/ of a checkout, hydrogen/_templates when installed
#: C drivers rendered from templates/ next to the generated functions: (template, output suffix).
DRIVERS = (("loop.h.j2", "_loop.h"), ("loop.c.j2", "_loop.c"))


#: Top-level modules of the package that shape the generated functions besides the layers of
#: :func:`derivation_hash`: the pressure blocks, the names (the numbers input's), the registries'
#: discovery (which blocks are found, in which order).
DERIVATION_FILES = ("names.py", "pressures.py", "registry.py")
#: The package's folders of derivation code; in the blocks' folders, a block's own module is hashed
#: apart (:func:`block_hash`) and shapes only the functions that use it. The plant's folder is the
#: plant's functions' own (:func:`plant_hash`), but for what the rest of the derivation imports of it.
DERIVATION_DIRS = ("symbolic", "codegen", "controllers", "actuators")
#: The plant's blocks' folder: what :func:`plant_hash` covers.
PLANT_DIR = "plant"
#: What shapes the loop drivers alone (:func:`drivers_hash`, besides the templates and the plant's
#: folder): the loop context and its ports, the escape of its values, the sensors' noise row, where the
#: templates are found; the reference kinds (the loop's configuration, its C reference function) and
#: the estimators (their statements). An edit of these renders the drivers again and derives nothing.
DRIVER_FILES = ("layout.py", "diagram.py", "templating.py", "sensors.py", "loop_logs.py", "resources.py")
DRIVER_DIRS = ("references", "estimators", PLANT_DIR)


def _block_files() -> dict:
    """``{(folder, file name): (role, name)}`` of every registered block's own module: the actuator
    kinds ("kind") and the controllers ("controller")."""
    from ..actuators import KINDS, actuator
    from ..controllers import CONTROLLERS, controller

    out = {}
    for role, names, module in (("kind", KINDS, actuator), ("controller", CONTROLLERS, controller)):
        for name in names:
            path = Path(module(name).__file__)
            out[(path.parent.name, path.name)] = (role, name)
    return out


def block_hash(role: str, name: str) -> str:
    """SHA-256 of the module of block ``name`` (``role`` "kind": an actuator kind; "controller")."""
    for (folder, file), block in _block_files().items():
        if block == (role, name):
            return hashlib.sha256((_PACKAGE / folder / file).read_bytes()).hexdigest()
    raise KeyError(f"no {role} {name!r}")


def _hash_files(h, paths) -> None:
    """Feed each of ``paths`` (relative to the package) into ``h``, its name first."""
    for rel in paths:
        h.update(f"{rel}\0".encode())
        h.update((_PACKAGE / rel).read_bytes())


def _modules(folder: str) -> list:
    """The Python modules of one of the package's folders, relative to the package, sorted."""
    return [f"{folder}/{p.name}" for p in sorted((_PACKAGE / folder).glob("*.py"))]


def _plant_imports() -> list:
    """The plant's modules the derivation code outside the plant's folder imports, and those these
    import in turn (statically, function-local imports too; importing a module of the folder runs
    its package's ``__init__``), relative to the package, sorted: they shape every function, not
    the plant's alone. (The blocks the ``__init__`` discovers at import are the plant's own: it
    hands them to the plant's function alone.)"""
    files = [*DERIVATION_FILES, *(rel for sub in DERIVATION_DIRS for rel in _modules(sub))]
    sources = ((rel, (_PACKAGE / rel).read_bytes()) for rel in files)
    # a module that never spells the folder's name imports none of it: parsed only where it does
    todo = {m for rel, source in sources if PLANT_DIR.encode() in source for m in _imports_of(rel, source)}
    found = set()
    while todo:
        rel = todo.pop()
        if rel in found or not rel.startswith(f"{PLANT_DIR}/") or not (_PACKAGE / rel).is_file():
            continue
        found.add(rel)
        todo |= _imports_of(rel, (_PACKAGE / rel).read_bytes())
    return sorted(found)


#: An import statement at the start of a line: ``from <dots><module> import <names>`` (the names
#: maybe parenthesised over lines) or ``import <modules>``. A docstring's line that reads like one
#: only adds a file to a hash: the scan errs on the side of staleness.
_IMPORT = re.compile(r"^[ \t]*(?:from[ \t]+(\.*)([\w.]*)[ \t]+import[ \t]+(\([^)]*\)|[^\n#]*)|import[ \t]+([^\n#]+))",
                     re.MULTILINE)


@functools.lru_cache(maxsize=512)
def _imports_of(rel: str, source: bytes) -> frozenset:
    """The package's modules (files relative to the package: ``plant/supply.py``, a package's
    ``plant/__init__.py``) that the module at ``rel`` imports, from its ``source``: relative imports
    and absolute ones of the package (function-local ones too), each importing its packages'
    ``__init__`` too. A name that is no module counts as its package's (scanned once per content)."""
    here = rel.split("/")[:-1]  # the module's package, as folders below the package's top
    top = __name__.split(".")[0]  # the package's own name, for its absolute imports
    found = set()

    def add(parts):  # a module path below the package's top: the module's file and its packages'
        for k in range(1, len(parts) + 1):
            found.add("/".join(parts[:k]) + ".py")
            found.add("/".join(parts[:k] + ["__init__.py"]))

    def names(text):  # "a, b as c" or "(a,  # a comment\n b)": a, b
        text = re.sub(r"#[^\n]*", "", text).strip("() \t\n").replace("\n", " ")
        return [n.split()[0] for n in text.split(",") if n.strip()]

    for dots, module, imported, plain in _IMPORT.findall(source.decode("utf-8", "replace")):
        if plain:
            for name in names(plain):
                parts = name.split(".")
                if parts[0] == top and len(parts) > 1:
                    add(parts[1:])
            continue
        level, parts = len(dots), module.split(".") if module else []
        if level:
            if level - 1 > len(here):
                continue
            parts = here[:len(here) - (level - 1)] + parts
        elif parts and parts[0] == top:
            parts = parts[1:]
        else:
            continue
        if parts:
            add(parts)
        for name in names(imported):  # a submodule imported by name, or a name of the module (no file)
            add(parts + [name])
    return frozenset(found)


def derivation_hash(kinds=()) -> str:
    """SHA-256 of the code that shapes the generated functions for a robot with actuator ``kinds``:
    the symbolic and codegen layers, the blocks' shared modules, each of those kinds' modules and
    the plant's modules the rest imports. A controller's module is covered by its functions' own
    hash (:func:`block_hash`, recorded per function), the plant's blocks by the plant's functions'
    (:func:`plant_hash`), the loop drivers by :func:`drivers_hash`: adding or editing a controller,
    a kind, a rig part or a reference kind leaves every function that does not use it current."""
    h = hashlib.sha256()
    for name in DERIVATION_FILES:
        h.update((_PACKAGE / name).read_bytes())
    blocks = _block_files()
    own = {blocks_key for blocks_key, block in blocks.items() if block in {("kind", k) for k in kinds}}
    _hash_files(h, [rel for sub in DERIVATION_DIRS for rel in _modules(sub)
                    if tuple(rel.split("/")) not in blocks or tuple(rel.split("/")) in own])
    _hash_files(h, _plant_imports())
    return h.hexdigest()


def plant_hash() -> str:
    """SHA-256 of the plant's folder (its blocks, composed into the plant's functions): recorded on
    each of those functions' manifest entries as their ``block_hash``."""
    h = hashlib.sha256()
    _hash_files(h, _modules(PLANT_DIR))
    return h.hexdigest()


def drivers_hash() -> str:
    """SHA-256 of what the loop drivers are rendered from besides the manifest: the loop's
    templates, :data:`DRIVER_FILES` and :data:`DRIVER_DIRS`."""
    h = hashlib.sha256()
    _hash_files(h, [*DRIVER_FILES, *(rel for sub in DRIVER_DIRS for rel in _modules(sub))])
    for name, _ in DRIVERS:
        path = TEMPLATES / name
        if not path.is_file():
            raise StaleGeneratedCodeError(
                f"{path}: template not found; the installation is incomplete (reinstall hydrogen: "
                "'pip install .' or 'pip install -e .' from the repository, or the wheel)")
        h.update(f"templates/{name}\0".encode())
        h.update(path.read_bytes())
    return h.hexdigest()


def model_kinds(model) -> tuple:
    """The actuator kinds ``model`` uses, sorted."""
    return tuple(sorted({c.kind for c in model.cylinders}))


def render_drivers(manifest: dict, folder: Path) -> list:
    """Render the C drivers of templates/ into ``folder`` from the manifest's one template context
    (:func:`hydrogen.layout.loop_context`); returns their file names."""
    from ..layout import loop_context
    from ..templating import render as render_template

    ctx = loop_context(manifest)
    names = []
    for template, suffix in DRIVERS:
        name = ctx["model"] + suffix
        write_file(Path(folder) / name, render_template(template, ctx, TEMPLATES))
        names.append(name)
    return names


def structure_hash(model) -> str:
    """SHA-256 of what a parametric generation bakes into its C for ``model``: the description's
    structure (:meth:`hydrogen.model.Model.structure`) and the summary the drivers are rendered
    from (:func:`hydrogen.layout.model_summary`: sizes, names, kinds; no number), but for what the
    plant's blocks decide of it (the plant's hash covers that). Equal for two descriptions one
    library with the numbers as inputs serves."""
    from ..layout import PLANT_SUMMARY, model_summary

    summary = {k: v for k, v in model_summary(model).items() if k not in PLANT_SUMMARY}
    text = json.dumps([model.structure(), summary], sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()


#: How the description's numbers reach the generated functions: folded into them as constants, or
#: as one more input of each, ``numbers`` (the manifest lists the names, :meth:`Model.numbers`).
NUMBERS_MODES = ("constants", "inputs")
#: The default: the numbers as inputs. Folding them buys no speed (benchmarks/bench_folding.py: the
#: instructions and ns per call within a few % either way), and with them as inputs an edit of
#: numbers loads the same compiled code.
DEFAULT_NUMBERS = "inputs"


def check_numbers_mode(numbers: str) -> str:
    """``numbers`` if it is one of :data:`NUMBERS_MODES`, else a ScenarioError naming them."""
    if numbers not in NUMBERS_MODES:
        from ..errors import ScenarioError
        raise ScenarioError(f"numbers must be one of {', '.join(map(repr, NUMBERS_MODES))}, got {numbers!r}")
    return numbers


def numbers_mode(manifest: dict) -> str:
    """The :data:`NUMBERS_MODES` entry a manifest was generated in."""
    return "inputs" if "numbers" in manifest else "constants"


def expected_manifest_inputs(model, numbers: str = DEFAULT_NUMBERS) -> dict:
    """What a manifest must record for its files to be current for ``model``: with the numbers as
    inputs, the model's structure hash (an edit of numbers only keeps the folder current)."""
    key = model.baked_hash() if check_numbers_mode(numbers) == "constants" else structure_hash(model)
    return {"model_hash": key, "derivation_hash": derivation_hash(model_kinds(model)), "drivers_hash": drivers_hash(),
            "format": FORMAT_VERSION}


def numbers_hash(names: list) -> str:
    """SHA-256 of the names of a folder's numbers, in order: the manifest records it beside the list,
    since the list maps each value the runtime fills to its place in the generated C (two names
    swapped would feed one number where the other belongs, with no file changed)."""
    return hashlib.sha256(json.dumps(list(names), separators=(",", ":")).encode()).hexdigest()


def c_name(model_name: str, fname: str) -> str:
    """C symbol of a generated function: ``<model>_<function>``."""
    return f"{model_name}_{fname}"


def write_function(sf, model_name: str, folder: Path, cache: dict) -> dict:
    """Write ``sf``'s C (``<model>_<name>.c`` and ``.h``) into ``folder``; returns its manifest
    entry. ``cache``: the CasADi conversions made so far (:func:`casadi_function`)."""
    from .casadi_functions import casadi_function

    name = c_name(model_name, sf.name)
    fun = casadi_function(sf, c_name=name, cache=cache)
    write_casadi([fun], name, folder)
    owner = _owner(sf.name)
    # a controller's functions record its module's hash, the plant's the plant's folder's: an edit
    # of it stales them alone
    own = plant_hash() if _is_plant(sf.name) else None if owner is None else block_hash("controller", owner)
    return {
        "name": sf.name, "c_name": name, "doc": sf.doc,
        **({} if own is None else {"block_hash": own}),
        "source": f"{name}.c", "header": f"{name}.h",
        "inputs": [[fun.name_in(i), *fun.size_in(i)] for i in range(fun.n_in())],
        "outputs": [[fun.name_out(i), *fun.size_out(i)] for i in range(fun.n_out())],
        "instructions": fun.n_instructions(),
        # inputs no output depends on (e.g. the composite gains of a lean variant): an export or FMU
        # must not offer them as parameters, setting them would change nothing
        "unread_inputs": _unread_inputs(fun),
    }


def write_casadi(functions: list, name: str, folder: Path) -> None:
    """Write CasADi ``functions`` into ``folder`` as ``<name>.c`` and ``<name>.h`` (a function they
    call is written once), clean under -Wall -Wextra."""
    import casadi as ca

    cg = ca.CodeGenerator(f"{name}.c", dict(CODEGEN_OPTIONS))
    for fun in functions:
        cg.add(fun)
    with tempfile.TemporaryDirectory() as tmp:
        cg.generate(tmp + "/")
        for ext in (".c", ".h"):
            text = Path(tmp, name + ext).read_text()
            if ext == ".c":
                text = tidy(text)
            write_file(folder / (name + ext), text)  # a full disk names the file


def _unread_inputs(fun) -> list:
    # structural, by sparsity propagation: no symbolic evaluation of the graph (which costs seconds
    # on a large controller)
    outs = list(fun.name_out())
    return [name for name in fun.name_in() if not any(fun.which_depends(name, outs, 1, False))]


def _listed_numbers_hash(names) -> str | None:
    """:func:`numbers_hash` of a manifest's list, None when it is not a list of names."""
    if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
        return None
    return numbers_hash(names)


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def derive(model, numbers: str = DEFAULT_NUMBERS, controllers=None, core=True, seed=None, tail=(),
           marks=None) -> tuple:
    """``(functions, names)``: the functions derived for ``numbers`` (:data:`NUMBERS_MODES`), and
    the names of the description's numbers they take as their input ``numbers`` ("inputs"; None
    for "constants", which folds them). ``controllers``: the controllers derived (None: all);
    ``core``: whether the core's functions are (or the names of some of its parts,
    :data:`hydrogen.symbolic.functions.CORE_PARTS`); ``seed``: the numbers' names of functions
    derived before, which these must share ("inputs"); ``tail`` and ``marks``: as
    :func:`hydrogen.symbolic.functions.derive_parametric` takes them ("inputs"). None for
    ``controllers``: those the model lists."""
    from ..symbolic.functions import derive_functions, derive_parametric

    kinds = tuple(model.controllers if controllers is None else controllers)
    if check_numbers_mode(numbers) == "inputs":
        functions, names, _ = derive_parametric(model, kinds, core=core, seed=seed, tail=tail, marks=marks)
        return functions, names
    return derive_functions(model, kinds, core), None


def _write_functions(functions: list, model_name: str, folder: Path, cache: dict, written=None, first=None,
                     tick=None) -> dict:
    """Write ``functions``' C into ``folder``; their manifest entries by name. Those ``first`` (of a
    name) holds before the others; each batch converted in the functions' order, the first with the
    functions its own are composed of (a composed function reuses its parts' conversions: the same C
    whatever the order of writing), then written the semi-implicit steps first: the largest sources,
    the longest compiles, which ``written(name, path)`` (called with each) may start first."""
    from ..symbolic.functions import SemiImplicitStep
    from .casadi_functions import casadi_function

    wanted = [f for f in functions if first is None or first(f.name)]
    parts = _with_parts(wanted)
    entries = {}
    for convert, batch in (([f for f in functions if f.name in parts], wanted),
                           (functions, [f for f in functions if f not in wanted])):
        for sf in convert:
            casadi_function(sf, c_name(model_name, sf.name), cache)
        for sf in sorted(batch, key=lambda f: not isinstance(f, SemiImplicitStep)):
            entries[sf.name] = write_function(sf, model_name, folder, cache)
            if written is not None:
                written(sf.name, folder / entries[sf.name]["source"])
            if tick is not None:
                tick()
    return entries


def _with_parts(functions: list) -> set:
    """Names of ``functions`` and of the functions they are composed of (a specialisation's base, a
    step's controller and rates), recursively."""
    from ..symbolic.functions import SemiImplicitStep, Specialisation

    out, todo = set(), list(functions)
    while todo:
        f = todo.pop()
        if f.name not in out:
            out.add(f.name)
            todo += [f.base] if isinstance(f, Specialisation) else \
                [f.controller, f.rates] if isinstance(f, SemiImplicitStep) else []
    return out


def _is_plant(name: str) -> bool:
    """Whether a generated function is the plant's (composed from the plant's blocks)."""
    from ..plant import FUNCTION

    return name == FUNCTION


def _owner(name: str) -> str | None:
    """The controller a generated function belongs to (by the registry's names), None for the core."""
    from ..controllers import function_owner

    owner = function_owner(name)
    return None if owner is None else owner[0]


#: The words of :func:`check`'s reason for a controller whose functions' derivation changed.
STALE_CONTROLLER = "derivation changed for controller"


def stale_controllers(manifest: dict) -> tuple:
    """The controllers a generated folder holds whose module changed since their functions were
    generated (or that are not registered any more), in the registry's order."""
    from ..controllers import CONTROLLERS

    now, out = {}, []  # each controller's module hashed once (a build checks this on every load)
    for e in manifest.get("functions", []):
        owner = _owner(e["name"])
        if owner is None or owner in out:
            continue
        if owner not in now:
            now[owner] = block_hash("controller", owner)
        if e.get("block_hash") != now[owner]:
            out.append(owner)
    return tuple(k for k in CONTROLLERS if k in out)


#: The words of :func:`check`'s reason for the plant's function when the plant's blocks changed.
STALE_PLANT = "derivation changed for the plant"


def stale_plant(manifest: dict) -> bool:
    """Whether a generated folder's plant function was generated from other blocks than today's
    (its recorded hash is not the plant folder's; a folder without the function holds no plant)."""
    entries = [e for e in manifest.get("functions", []) if _is_plant(e["name"])]
    return bool(entries) and any(e.get("block_hash") != plant_hash() for e in entries)


def held_controllers(manifest: dict) -> tuple:
    """The controllers whose functions a generated folder holds, in the registry's order."""
    from ..controllers import CONTROLLERS

    held = {_owner(e["name"]) for e in manifest.get("functions", [])}
    return tuple(k for k in CONTROLLERS if k in held)


def missing_controllers(manifest: dict, controllers) -> tuple:
    """Of ``controllers`` (names), those a generated folder does not hold yet."""
    held = held_controllers(manifest)
    return tuple(k for k in controllers if k not in held)


def _canonical(entries: list) -> list:
    """Manifest entries in the order a whole generation writes them: the core's, then each
    controller's in the registry's order (a folder grown controller by controller reads the same)."""
    from ..controllers import CONTROLLERS

    rank = {None: -1, **{k: i for i, k in enumerate(CONTROLLERS)}}
    return sorted(entries, key=lambda e: rank[_owner(e["name"])])  # stable: each group keeps its order


def _file_hashes(folder: Path) -> dict:
    return {p.name: _sha256(p) for p in sorted(folder.iterdir()) if p.name != MANIFEST}


def render(model, folder: Path, functions=None, progress: bool = False, numbers: str = DEFAULT_NUMBERS,
           names=None, controllers=None, written=None, first=None) -> dict:
    """Write every function's C and the manifest into an existing empty ``folder``.

    ``progress`` shows a bar on a terminal (nothing when stderr is not one). ``numbers``
    (:data:`NUMBERS_MODES`): "inputs" gives every function the description's numbers as its input
    ``numbers`` (names in the manifest's ``numbers``); the loop driver then passes them on from its
    configuration. ``functions`` and ``names``: what :func:`derive` gives for ``numbers``, when
    derived already (else derived here, the core and ``controllers``: None for all; the core's C is
    written before the controllers are derived). ``written``: called as ``written(name, path)`` with
    each C source as soon as it is written (``name`` the function's, None for a loop driver), e.g.
    to start its compile while the rest is derived; ``first``: of a function's name, whether the
    caller needs it (its library) first: those are written before the others of their derivation
    (the manifest lists every function in the same order whatever ``first`` says).
    """

    import casadi as ca
    import sympy as sp
    from tqdm import tqdm

    folder = Path(folder)
    if functions is not None and (names is None) != (check_numbers_mode(numbers) == "constants"):
        raise ValueError(f"render: functions derived for numbers={numbers!r} come with "
                         f"{'the names of their numbers (derive)' if names is None else 'no names'}")
    bar = tqdm(desc="generating C", unit="fn", disable=None if progress else True)
    cache = {}  # CasADi conversions by function name: the composed functions reuse them
    entries = {}

    def write(fs):
        entries.update(_write_functions(fs, model.name, folder, cache, written, first, bar.update))

    marks = {}  # numbers met by the end of each core part (its first derivation, unseeded)
    if functions is None:
        core, names = derive(model, numbers, controllers=(), marks=marks)
        write(core)
        own, grown = derive(model, numbers, controllers, core=False, seed=names)
        if grown != names:  # a controller met a number the core did not: every function takes the whole vector
            core, names = derive(model, numbers, controllers=(), seed=grown)
            cache.clear()
            write(core)
        write(own)
        functions = [*core, *own]
    else:
        write(functions)
    bar.close()
    summary, drivers = _drivers(model, names, folder, written)
    manifest = {
        **expected_manifest_inputs(model, numbers),
        **({} if names is None else {"numbers": names, "numbers_hash": numbers_hash(names)}),
        # where the plant's numbers start and end in them: the plant derived again alone must meet the same
        **({NUMBERS_MET: _plant_numbers(marks)} if names is not None and marks else {}),
        "model_name": model.name,
        "model": summary,
        "casadi_version": ca.__version__,
        "sympy_version": sp.__version__,
        "casadi_int": CODEGEN_OPTIONS["casadi_int"],
        "casadi_real": CODEGEN_OPTIONS["casadi_real"],
        "functions": _canonical([entries[f.name] for f in functions]),
        "drivers": [d for d in drivers if d.endswith(".c")],
        "files": _file_hashes(folder),
    }
    write_file(folder / MANIFEST, json.dumps(manifest, indent=2, sort_keys=True) + "\n")
    return manifest


#: The manifest's key of the span of its numbers the plant's function met first, ``[start, stop]``.
NUMBERS_MET = "plant_numbers"


def _plant_numbers(marks: dict) -> list:
    """``[start, stop]`` of the numbers the plant's part met first, from a derivation's marks (the
    count met by the end of each core part, :data:`hydrogen.symbolic.functions.CORE_PARTS`' order)."""
    from ..symbolic.functions import CORE_PARTS, PLANT_PART

    order = [name for name, _ in CORE_PARTS]
    before = order[order.index(PLANT_PART) - 1] if order.index(PLANT_PART) else None
    return [marks[before] if before else 0, marks[PLANT_PART]]


def _summary(model) -> dict:
    """The manifest's record of ``model`` (:func:`hydrogen.layout.model_summary`), as JSON reads it."""
    from ..layout import model_summary

    return json.loads(json.dumps(model_summary(model)))


def _drivers(model, names, folder: Path, written=None) -> tuple:
    """Render the loop drivers of ``model`` (numbers ``names``, None when folded) into ``folder``:
    ``(the model summary they are rendered from, the drivers' file names)``; ``written(None, path)``
    with each C source."""
    from ..layout import model_summary

    summary = model_summary(model)
    drivers = render_drivers({"model": summary, **({} if names is None else {"numbers": names})}, folder)
    if written is not None:
        for d in drivers:
            if d.endswith(".c"):
                written(None, folder / d)
    return summary, drivers


def generate(model, out_dir: Path, force: bool = False, progress: bool = False, numbers: str = DEFAULT_NUMBERS,
             controllers=None, written=None, first=None, whole=None) -> bool:
    """Generate C for ``model`` into ``out_dir`` unless it is already current.

    ``controllers``: the controllers the folder must hold (None: all); a current folder that lacks
    some gets theirs added (:func:`extend`), nothing else derived again. Returns True when files
    were (re)written. The folder is swapped in whole under a lock; concurrent callers wait, then
    find it current. ``written`` and ``first``: as :func:`render` takes them; ``whole()`` is called
    when a part that would have been derived alone (:func:`stale_parts`) is derived with all the
    rest after all (the plant met other numbers first, a controller a number the folder lacks).
    """
    out_dir = Path(out_dir)
    check_replaceable_dir(out_dir, MANIFEST, GENERATED_KEYS, "a hydrogen generated folder")  # before the lock file
    with locked(out_dir):
        return generate_locked(model, out_dir, force, progress, numbers, controllers, written, first, whole)


def _staged(out_dir: Path, write) -> None:
    """Fill a new folder beside ``out_dir`` with ``write(staging)``, then swap it in whole."""
    out_dir.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=f".{out_dir.name}.new-", dir=out_dir.parent))
    staging.chmod(0o755)  # mkdtemp makes it private; generated code is for everyone
    try:
        write(staging)
        replace_dir(staging, out_dir)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise


def generate_locked(model, out_dir: Path, force: bool = False, progress: bool = False,
                    numbers: str = DEFAULT_NUMBERS, controllers=None, written=None, first=None, whole=None) -> bool:
    """:func:`generate` for a caller that already holds ``locked(out_dir)``."""
    out_dir = Path(out_dir)
    check_identifier(model.name, "model name")  # it becomes C symbols, file names and build-file text
    recover_dir(out_dir)
    need = model.controllers if controllers is None else controllers
    parts = None if force else stale_parts(model, out_dir, numbers, need)
    manifest = read_manifest(out_dir) or {}
    if parts is not None:  # current but for controllers changed or missing, the plant's blocks or the drivers' code
        stale, missing = parts.get("controllers", ()), parts.get("missing", ())
        plant, drivers = parts.get("plant", False), parts.get("drivers", False)
        redo = (*stale, *(k for k in missing if k not in stale))
        if not (redo or plant or drivers):
            return False
        if extend(model, out_dir, redo, progress, replacing=stale, written=written, first=first, plant=plant,
                  drivers=drivers):
            return True
        controllers = (*held_controllers(manifest), *(k for k in missing if k not in stale))  # whole again
        if whole is not None:
            whole()
    check_replaceable_dir(out_dir, MANIFEST, GENERATED_KEYS, "a hydrogen generated folder", probe=False)  # even forced
    _staged(out_dir, lambda staging: render(model, staging, progress=progress, numbers=numbers,
                                            controllers=controllers, written=written, first=first))
    return True


def _plant_again(model, manifest: dict):
    """The plant's functions derived again alone for a generated folder, or None where only a whole
    generation gives what one would write: with the numbers as inputs, the plant must meet first
    exactly the numbers it met first before (the span recorded, :data:`NUMBERS_MET`), else the
    numbers' order of a whole generation differs; the functions then take the folder's whole vector."""
    from ..symbolic.functions import PLANT_PART

    mode, seed = numbers_mode(manifest), manifest.get("numbers")
    if mode == "constants":
        return derive(model, mode, controllers=(), core=(PLANT_PART,))[0]
    span = manifest.get(NUMBERS_MET)
    if not span:
        return None
    marks = {}
    functions, names = derive(model, mode, controllers=(), core=(PLANT_PART,), seed=seed[:span[0]], tail=seed,
                              marks=marks)
    return functions if names == seed and marks[PLANT_PART] == span[1] else None


def extend(model, folder: Path, controllers, progress: bool = False, replacing=(), written=None,
           first=None, plant: bool = False, drivers: bool = False) -> bool:
    """Add the functions of ``controllers`` to the current generated ``folder`` (the caller holds its
    lock): they alone are derived and written, the folder swapped in whole with its manifest. The
    result is byte for byte what a whole generation of the same controllers writes. ``replacing``:
    controllers among them the folder holds already (their module changed): their functions' files
    and entries give way to the new ones. ``plant``: the plant's functions are derived again and
    replace theirs (its blocks changed); ``drivers``: the loop drivers are rendered again (their
    code changed), and the manifest's model summary with them. False (nothing written) when they
    read a description number the folder's functions do not take (or the plant meets its numbers in
    another order): then only a whole generation can give every function the same numbers input.
    ``written`` and ``first``: as :func:`render` takes them."""
    from tqdm import tqdm

    folder = Path(folder)
    manifest = read_manifest(folder)
    mode = numbers_mode(manifest)
    seed = manifest.get("numbers")
    with tqdm(total=1, desc="deriving (SymPy)", disable=None if progress and (controllers or plant) else True) as bar:
        functions, names = derive(model, mode, controllers, core=False, seed=seed) if controllers else ([], seed)
        if names != seed:
            return False
        own = _plant_again(model, manifest) if plant else []
        if own is None or plant and {f.name for f in own} != {e["name"] for e in manifest["functions"]
                                                              if _is_plant(e["name"])}:
            return False
        bar.update()

    kept = [e for e in manifest["functions"] if _owner(e["name"]) not in replacing]
    dropped = {f for e in manifest["functions"] if e not in kept or plant and _is_plant(e["name"])
               for f in (e["source"], e["header"])}
    if drivers:
        dropped |= {f"{model.name}{suffix}" for _, suffix in DRIVERS}

    def write(staging):
        for p in folder.iterdir():
            if not p.name.startswith(".") and p.name not in dropped:
                shutil.copy2(p, staging / p.name)
        with tqdm(total=len(own) + len(functions), desc="generating C", unit="fn",
                  disable=None if progress else True) as bar:
            made = _write_functions([*own, *functions], model.name, staging, {}, written, first, bar.update)
        renewed = {f.name: made[f.name] for f in own}
        added = [made[f.name] for f in functions]
        grown = {**manifest, "functions": _canonical([*(renewed.get(e["name"], e) for e in kept), *added])}
        if drivers:
            summary, names = _drivers(model, manifest.get("numbers"), staging, written)
            grown.update(model=summary, drivers=[d for d in names if d.endswith(".c")], drivers_hash=drivers_hash())
        grown["files"] = _file_hashes(staging)
        write_file(staging / MANIFEST, json.dumps(grown, indent=2, sort_keys=True) + "\n")

    _staged(folder, write)
    return True


def read_manifest(folder: Path) -> dict | None:
    """The manifest of a generated folder, or None if absent or unreadable."""
    try:
        return json.loads((Path(folder) / MANIFEST).read_text())
    except (OSError, ValueError):
        return None


def check_output(model, folder: Path, numbers: str | None = None) -> list:
    """Reasons ``folder`` is stale for ``model``, judged by the generated output (``generate --check``).

    When only the code's hashes differ (the derivation's, the drivers', a controller's or the
    plant's: an edit that may not change what is generated, such as a comment), the code is
    generated again into a temporary folder and compared byte for byte, the manifest without them: the files that differ are named, and identical
    output is still stale by its recorded hash alone (a build uses a folder only at the current
    hash), which the one reason then says. ``numbers``: the mode the folder must be in (None: its
    own), as for :func:`check`.
    """
    found = _reasons(model, folder, numbers)
    reasons = [text for _, text in found]
    if not reasons:  # current, but a folder grown for some controllers only is not a whole generation
        missing = missing_controllers(read_manifest(folder), model.controllers)
        return [f"{folder}: holds no functions of {', '.join(missing)} (generated for some controllers "
                "only)"] if missing else []
    derivation_only = all(part is not STALES_ALL or "derivation_hash changed" in text for part, text in found)
    if not derivation_only:
        return reasons
    folder = Path(folder)
    with tempfile.TemporaryDirectory() as tmp:
        render(model, Path(tmp), numbers=numbers_mode(read_manifest(folder) or {}))
        fresh = {p.name: p.read_bytes() for p in Path(tmp).iterdir()}
    present = {p.name for p in folder.iterdir() if not p.name.startswith(".")}
    out = []
    for name in sorted(present | set(fresh)):
        if name not in fresh or name not in present:
            out.append(f"{folder / name}: {'not generated any more' if name not in fresh else 'missing'}")
        elif name == MANIFEST:
            old, new = (json.loads(b) for b in ((folder / name).read_bytes(), fresh[name]))
            for m in (old, new):  # the hashes of the code; what it generated is compared
                m.pop("derivation_hash", None)
                m.pop("drivers_hash", None)
                for e in m.get("functions", []):
                    e.pop("block_hash", None)
            if old != new:
                out.append(f"{folder / name}: differs from a fresh generation")
        elif (folder / name).read_bytes() != fresh[name]:
            out.append(f"{folder / name}: differs from a fresh generation")
    if not out:  # the same output under an old hash: a build would not use the folder (it checks the hash)
        out.append(f"{folder}: its output is what a fresh generation writes, but it records the derivation "
                   f"code's old hash, so every build would generate it again: run 'hydrogen generate --model "
                   f"{model.name}' to record the current one")
    return out


def check(model, folder: Path, numbers: str | None = None) -> list:
    """Reasons ``folder`` is stale for ``model`` (empty list: current).

    Compares the recorded model, derivation and drivers hashes with the current ones, each
    controller's and the plant's functions' recorded hash with their code's, and every file with
    the hash the manifest recorded for it. ``numbers``: the mode the folder must be in
    (:data:`NUMBERS_MODES`; None: the manifest's own, whose model hash is then the structure hash
    for "inputs").
    """
    return [text for _, text in _reasons(model, folder, numbers)]


#: What a reason of :func:`_reasons` stales: the whole folder, one controller's functions
#: (``("controller", name)``), the plant's function, or the loop drivers alone.
STALES_ALL, STALES_PLANT, STALES_DRIVERS = None, "plant", "drivers"


def same_tools(manifest: dict) -> bool:
    """Whether a generated folder was written by the CasADi and SymPy this process runs: only then may
    functions written now join its others (CasADi stamps its version into each file, which the
    runtime holds to the manifest's)."""
    import casadi as ca
    import sympy as sp

    return (manifest.get("casadi_version"), manifest.get("sympy_version")) == (ca.__version__, sp.__version__)


def stale_parts(model, folder: Path, numbers: str | None = None, controllers=None) -> dict | None:
    """What of ``folder`` is stale for ``model``: None when the whole of it (a generation derives
    everything again), else a dict, empty when current: ``controllers`` (the names of those whose
    module changed), ``missing`` (of ``controllers``, the names a folder that must hold them lacks;
    None: not asked), ``plant`` (True: the plant's blocks changed), ``drivers`` (True: the loop
    drivers' code changed, or the plant's). Where functions would be derived again (a controller's,
    the plant's, a missing controller's) in a folder another CasADi or SymPy wrote, the whole of it."""
    found = _reasons(model, folder, numbers)
    if any(part is STALES_ALL for part, _ in found):
        return None
    manifest = read_manifest(folder)
    missing = () if controllers is None else missing_controllers(manifest, controllers)
    if (missing or any(part == STALES_PLANT or isinstance(part, tuple) for part, _ in found)) \
            and not same_tools(manifest):
        return None  # functions written now would not match the folder's others (CasADi stamps its version)
    out = {}
    stale = tuple(part[1] for part, _ in found if isinstance(part, tuple))
    if stale:
        out["controllers"] = stale
    if missing:
        out["missing"] = missing
    if any(part == STALES_PLANT for part, _ in found):
        out["plant"] = out["drivers"] = True
    if any(part == STALES_DRIVERS for part, _ in found):
        out["drivers"] = True
    return out


def _reasons(model, folder: Path, numbers: str | None = None) -> list:
    """:func:`check`'s reasons, each as ``(what it stales, text)`` (:data:`STALES_ALL`, :data:`STALES_PLANT`,
    :data:`STALES_DRIVERS` or ``("controller", name)``)."""
    folder = Path(folder)
    manifest = read_manifest(folder)
    if manifest is None:
        return [(STALES_ALL, f"{folder}: no readable {MANIFEST}")]
    reasons = []
    mode = numbers_mode(manifest)
    if numbers is not None and check_numbers_mode(numbers) != mode:
        reasons.append((STALES_ALL, f"{folder}: generated with the numbers as {mode}, wanted as {numbers}"))
    for key, value in expected_manifest_inputs(model, mode).items():
        if manifest.get(key) != value:
            reasons.append((STALES_DRIVERS if key == "drivers_hash" else STALES_ALL,
                            f"{folder}: {key} changed (recorded {str(manifest.get(key))[:12]}, now {str(value)[:12]})"))
    if manifest.get("model") != _summary(model):  # what the drivers and the runtime read of the model
        reasons.append((STALES_DRIVERS, f"{folder}: the model's summary changed (sizes, names, kinds, sensors)"))
    for k in stale_controllers(manifest):
        reasons.append((("controller", k),
                        f"{folder}: {STALE_CONTROLLER} '{k}' (its module changed since its functions were generated)"))
    if stale_plant(manifest):
        reasons.append((STALES_PLANT, f"{folder}: {STALE_PLANT} (a module of hydrogen/plant changed since it was generated)"))
    listed = _listed_numbers_hash(manifest.get("numbers"))
    if mode == "inputs" and (listed is None or manifest.get("numbers_hash") != listed):
        reasons.append((STALES_ALL, f"{folder / MANIFEST}: its numbers list does not match the numbers_hash recorded "
                               "at generation (edited since, or from another generation)"))
    recorded = manifest.get("files", {})
    present = {p.name for p in folder.iterdir() if p.name != MANIFEST and not p.name.startswith(".")}
    for name in sorted(present | set(recorded)):
        path = folder / name
        if name not in recorded:
            reasons.append((STALES_ALL, f"{path}: not listed in the manifest"))
        elif not path.exists():
            reasons.append((STALES_ALL, f"{path}: missing"))
        elif _sha256(path) != recorded[name]:
            reasons.append((STALES_ALL, f"{path}: edited since generation (hash differs)"))
    return reasons
