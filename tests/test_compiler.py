"""hydrogen/runtime/compiler.py: the translation units compiled in parallel, then one link."""
import ctypes
import os
import shutil
import subprocess
import sys
import textwrap

import pytest

from hydrogen.errors import CompilerError
from hydrogen.runtime.compiler import (Toolchain, cached_library, compile_library, compile_objects, pending_compiles,
                                       usable_cores)


def _logging_cc(tmp_path, pause: float = 0.0):
    """A compiler wrapper that logs each compile's start and end (and how many ran at once), then runs cc."""
    cc = shutil.which("cc")
    if cc is None:
        pytest.skip("no C compiler")
    log, running = tmp_path / "cc.log", tmp_path / "running"
    running.mkdir()
    wrapper = tmp_path / "logcc"
    wrapper.write_text(textwrap.dedent(f"""\
        #!/bin/sh
        if [ "$1" = --version ]; then exec {cc} --version; fi
        src=""; prev=""
        for a in "$@"; do [ "$prev" = -c ] && src="$a"; prev="$a"; done
        [ -z "$src" ] && exec {cc} "$@"
        name=$(basename "$src")
        touch "{running}/$name"
        echo "start $name $(ls "{running}" | wc -l)" >> "{log}"
        sleep {pause}
        {cc} "$@"; rc=$?
        echo "end $name $(ls "{running}" | wc -l)" >> "{log}"
        rm -f "{running}/$name"
        exit $rc
        """))
    wrapper.chmod(0o755)
    return str(wrapper), log


def _sources(folder, names_sizes):
    folder.mkdir(parents=True, exist_ok=True)
    out = []
    for name, size in names_sizes:
        src = folder / f"{name}.c"
        pad = "/* " + "x" * size + " */\n"  # the size orders the compiles, not the work
        src.write_text(f"{pad}int {name}(void) {{ return {len(out) + 1}; }}\n")
        out.append(src)
    return out


def test_translation_units_compile_at_the_same_time(tmp_path):
    cc, log = _logging_cc(tmp_path, pause=1.0)
    srcs = _sources(tmp_path / "src", [("a", 10), ("b", 20), ("c", 30), ("d", 40)])
    lib = compile_library(srcs, "par", Toolchain(cc=cc), cache=tmp_path / "cache", jobs=2)
    starts = [line.split() for line in log.read_text().splitlines() if line.startswith("start")]
    assert len(starts) == 4
    assert max(int(n) for _, _, n in starts) == 2  # two compilers at once, never more than jobs
    dll = ctypes.CDLL(str(lib))
    assert [getattr(dll, n)() for n in "abcd"] == [1, 2, 3, 4]  # one link of every object
    assert cached_library(lib.parent) == lib


def test_largest_sources_start_first(tmp_path):
    cc, log = _logging_cc(tmp_path)
    srcs = _sources(tmp_path / "src", [("small", 10), ("large", 5000), ("medium", 500)])
    compile_library(srcs, "order", Toolchain(cc=cc), cache=tmp_path / "cache", jobs=1)
    starts = [line.split()[1] for line in log.read_text().splitlines() if line.startswith("start")]
    assert starts == ["large.c", "medium.c", "small.c"]


def test_a_failed_compile_stops_the_compiles_not_yet_started(tmp_path):
    cc, log = _logging_cc(tmp_path)
    srcs = _sources(tmp_path / "src", [("ok1", 10), ("ok2", 20)])
    broken = tmp_path / "src" / "broken.c"
    broken.write_text("/* " + "x" * 1000 + " */\nint broken(void) { return undefined_name; }\n")
    with pytest.raises(CompilerError) as err:
        compile_library([*srcs, broken], "stop", Toolchain(cc=cc), cache=tmp_path / "cache", jobs=1)
    assert "C compiler failed on broken.c" in str(err.value) and "undefined_name" in str(err.value)
    assert f"$ {cc}" in str(err.value)  # the command is quoted
    assert str(broken) in str(err.value) and ".tmp-" not in str(err.value)  # the source's own path
    starts = [line.split()[1] for line in log.read_text().splitlines() if line.startswith("start")]
    assert starts == ["broken.c"]  # the largest first; the others were never started
    assert not list((tmp_path / "cache").rglob("*.so"))


def test_sources_of_one_name_in_two_folders_both_reach_the_library(tmp_path):
    one, two = tmp_path / "one" / "f.c", tmp_path / "two" / "f.c"
    for path, fn in ((one, "f_one"), (two, "f_two")):
        path.parent.mkdir()
        path.write_text(f"int {fn}(void) {{ return 7; }}\n")
    lib = compile_library([one, two], "twins", Toolchain(), cache=tmp_path / "cache")
    dll = ctypes.CDLL(str(lib))
    assert dll.f_one() == 7 and dll.f_two() == 7


def test_every_compiler_call_has_the_timeout(tmp_path):
    fake = tmp_path / "slowcc"
    fake.write_text('#!/bin/sh\nif [ "$1" = --version ]; then echo slowcc 1.0; exit 0; fi\nexec sleep 30\n')
    fake.chmod(0o755)
    srcs = _sources(tmp_path / "src", [("a", 1), ("b", 2)])
    with pytest.raises(CompilerError, match="did not finish [ab].c within 0.5 s"):
        compile_objects(srcs, tmp_path, [str(fake), "-O2"], timeout=0.5, jobs=2)


@pytest.mark.parametrize("jobs", [0, -1, 1.5, True, "2"])
def test_a_bad_job_count_is_named(tmp_path, jobs):
    with pytest.raises(CompilerError, match="jobs must be a whole number"):
        compile_objects([], tmp_path, ["cc"], timeout=1.0, jobs=jobs)


def test_usable_cores_is_at_least_one():
    assert usable_cores() >= 1


def _compiled(log) -> list:
    return [line.split()[1] for line in log.read_text().splitlines() if line.startswith("start")] if log.exists() else []


def test_a_library_whose_sources_changed_in_part_compiles_only_the_changed_ones(tmp_path):
    cc, log = _logging_cc(tmp_path)
    srcs = _sources(tmp_path / "src", [("a", 10), ("b", 20), ("c", 30)])
    compile_library(srcs, "first", Toolchain(cc=cc), cache=tmp_path / "cache", jobs=1)
    assert sorted(_compiled(log)) == ["a.c", "b.c", "c.c"]
    log.unlink()
    srcs[1].write_text("int b(void) { return 20; }\n")
    lib = compile_library(srcs, "second", Toolchain(cc=cc), cache=tmp_path / "cache", jobs=1)
    assert _compiled(log) == ["b.c"]  # a and c from the object store
    dll = ctypes.CDLL(str(lib))
    assert (dll.a(), dll.b(), dll.c()) == (1, 20, 3)


def test_a_precompiled_source_is_not_compiled_again_even_after_its_folder_is_gone(tmp_path):
    from hydrogen.runtime.compiler import precompile

    cc, log = _logging_cc(tmp_path)
    staging = _sources(tmp_path / "staging", [("a", 10), ("b", 20)])
    precompile(staging, Toolchain(cc=cc), cache=tmp_path / "cache")  # read now, compiled from a copy
    shutil.copytree(tmp_path / "staging", tmp_path / "final")
    shutil.rmtree(tmp_path / "staging")  # as a generated folder's staging folder is renamed
    final = [tmp_path / "final" / s.name for s in staging]
    lib = compile_library(final, "pre", Toolchain(cc=cc), cache=tmp_path / "cache", jobs=2)
    assert sorted(_compiled(log)) == ["a.c", "b.c"]  # once each: by the background compiles
    assert (ctypes.CDLL(str(lib)).a(), ctypes.CDLL(str(lib)).b()) == (1, 2)


def test_a_damaged_object_in_the_store_is_compiled_again(tmp_path):
    srcs = _sources(tmp_path / "src", [("a", 10), ("b", 20)])
    cache = tmp_path / "cache"
    compile_library(srcs, "first", Toolchain(), cache=cache)
    for obj in (cache / "objects").glob("*.o"):
        obj.write_bytes(b"not an object")
    more = _sources(tmp_path / "more", [("c", 5)])  # a new library of the same objects and one more
    lib = compile_library([*srcs, *more], "second", Toolchain(), cache=cache)
    assert ctypes.CDLL(str(lib)).b() == 2


def test_an_included_header_is_part_of_an_objects_key(tmp_path):
    cc, log = _logging_cc(tmp_path)
    src = tmp_path / "src"
    src.mkdir()
    (src / "k.h").write_text("#define K 1\n")
    (src / "k.c").write_text('#include "k.h"\nint k(void) { return K; }\n')
    compile_library([src / "k.c"], "one", Toolchain(cc=cc), cache=tmp_path / "cache")
    (src / "k.h").write_text("#define K 2\n")
    more = _sources(tmp_path / "more", [("m", 5)])  # a new library: only k.c compiles again
    lib = compile_library([src / "k.c", *more], "two", Toolchain(cc=cc), cache=tmp_path / "cache")
    assert sorted(_compiled(log)) == ["k.c", "k.c", "m.c"] and ctypes.CDLL(str(lib)).k() == 2


def test_a_header_changed_alone_is_another_library(tmp_path):
    """The same source bytes with a header of theirs changed (a generated loop header that gained a
    field while its source stayed as it was) make another library: never the one compiled against
    the old header (its struct layout), which a later version of hydrogen would load and crash in."""
    src = tmp_path / "src"
    src.mkdir()
    (src / "layout.h").write_text("typedef struct { double a; } cfg;\n#define K 1\n")
    (src / "k.h").write_text('#include "layout.h"\n')
    (src / "k.c").write_text('#include "k.h"\nint k(void) { return K + (int)sizeof(cfg); }\n')
    first = compile_library([src / "k.c"], "k", Toolchain(), cache=tmp_path / "cache")
    assert ctypes.CDLL(str(first)).k() == 1 + 8
    (src / "layout.h").write_text("typedef struct { double a, b; } cfg;\n#define K 1\n")  # two headers deep
    second = compile_library([src / "k.c"], "k", Toolchain(), cache=tmp_path / "cache")
    assert second.parent != first.parent and ctypes.CDLL(str(second)).k() == 1 + 16


@pytest.mark.skipif(not hasattr(__import__("os"), "fork"), reason="no fork here")
def test_a_forked_child_compiles_what_its_parent_had_started(tmp_path):
    """A child forked while its parent's background compile runs never waits for it (that thread is
    not in the child): it compiles the source itself."""
    import os

    from hydrogen.runtime.compiler import precompile

    slow = tmp_path / "slowcc"
    slow.write_text(f'#!/bin/sh\nif [ "$1" = --version ]; then exec cc --version; fi\nsleep 2\nexec cc "$@"\n')
    slow.chmod(0o755)
    srcs = _sources(tmp_path / "src", [("a", 10)])
    precompile(srcs, Toolchain(cc=str(slow)), cache=tmp_path / "cache")
    pid = os.fork()
    if pid == 0:  # the child: the same object, its own compile, then exit with the library's answer
        import signal

        signal.signal(signal.SIGALRM, lambda *_: os._exit(98))  # waiting on the parent's compile
        signal.alarm(30)
        try:
            lib = compile_library(srcs, "child", Toolchain(cc=str(slow)), cache=tmp_path / "cache")
            os._exit(ctypes.CDLL(str(lib)).a())
        except BaseException:
            os._exit(99)
    _, status = os.waitpid(pid, 0)
    assert os.waitstatus_to_exitcode(status) == 1


def test_headers_found_through_search_flags_keep_objects_out_of_the_store(tmp_path):
    """With -I the compiler finds headers the store's key cannot see: those objects stay the build's own,
    so a header changed there is compiled in."""
    inc, src = tmp_path / "inc", tmp_path / "src"
    inc.mkdir()
    src.mkdir()
    (inc / "k.h").write_text("#define K 1\n")
    (src / "a.c").write_text('#include "k.h"\nint a(void) { return K; }\n')
    (src / "b.c").write_text("int b(void) { return 1; }\n")
    tc = Toolchain(cflags=("-O0", "-fPIC", f"-I{inc}"))
    compile_library([src / "a.c", src / "b.c"], "one", tc, cache=tmp_path / "cache")
    assert not list((tmp_path / "cache" / "objects").glob("*.o"))
    (inc / "k.h").write_text("#define K 2\n")
    (src / "b.c").write_text("int b(void) { return 2; }\n")  # a new library key
    lib = compile_library([src / "a.c", src / "b.c"], "two", tc, cache=tmp_path / "cache")
    assert ctypes.CDLL(str(lib)).a() == 2


def test_a_source_rewritten_while_it_compiles_stores_the_bytes_its_key_names(tmp_path):
    """The stored object is compiled from a copy of the bytes its key was made from, so a source
    rewritten meanwhile (a folder generated again) never puts other code under that key."""
    srcs = _sources(tmp_path / "src", [("a", 10), ("b", 20)])
    original = srcs[0].read_text()
    rewriting = tmp_path / "rewritingcc"
    rewriting.write_text(f"""#!/bin/sh
if [ "$1" = --version ]; then exec cc --version; fi
sed -i 's/return 1;/return 9;/' {srcs[0]}
exec cc "$@"
""")
    rewriting.chmod(0o755)
    lib = compile_library(srcs[:1], "one", Toolchain(cc=str(rewriting)), cache=tmp_path / "cache")
    assert ctypes.CDLL(str(lib)).a() == 1 and "return 9" in srcs[0].read_text()
    srcs[0].write_text(original)
    lib = compile_library(srcs, "two", Toolchain(cc=str(rewriting)), cache=tmp_path / "cache")
    assert ctypes.CDLL(str(lib)).a() == 1


def _fake_compiler(tmp_path, version: str):
    """A compiler that answers --version with ``version`` and compiles with cc."""
    cc = shutil.which("cc")
    if cc is None:
        pytest.skip("no C compiler")
    wrapper = tmp_path / "fakecc"
    wrapper.write_text(f'#!/bin/sh\nif [ "$1" = --version ]; then echo "{version}"; exit 0; fi\nexec {cc} "$@"\n')
    wrapper.chmod(0o755)
    return str(wrapper)


def test_the_default_flags_add_gccs_own_only_for_gcc(tmp_path):
    """GCC gets GCC_CFLAGS with the default flags; clang (even installed as gcc) the defaults alone;
    flags a user chose (even the defaults) are exactly those. The flags used are in the library's key and in its build.json."""
    from hydrogen.runtime.compiler import DEFAULT_CFLAGS, GCC_CFLAGS, build_key

    (tmp_path / "clang-tools").mkdir()  # a path naming clang does not make GCC clang
    gcc = _fake_compiler(tmp_path / "clang-tools", "gcc (GCC) 12.2.0\\nCopyright (C) 2022 Free Software Foundation, Inc.")
    (tmp_path / "other").mkdir()
    clang = _fake_compiler(tmp_path / "other", "Apple clang version 15.0.0\\nTarget: arm64-apple-darwin23")
    (tmp_path / "gcc-named").mkdir()  # clang installed as gcc: its text names both
    clang_as_gcc = _fake_compiler(tmp_path / "gcc-named", "gcc: clang version 14.0 (Free Software Foundation headers)")
    assert Toolchain(cc=clang_as_gcc).flags() == DEFAULT_CFLAGS
    assert Toolchain(cc=gcc).flags() == (*DEFAULT_CFLAGS, *GCC_CFLAGS)
    assert set(GCC_CFLAGS) <= set(Toolchain(cc=gcc).argv())
    assert Toolchain(cc=clang).flags() == DEFAULT_CFLAGS
    assert Toolchain(cc=gcc, cflags=("-O1", "-fPIC")).flags() == ("-O1", "-fPIC")
    assert Toolchain(cc=gcc, cflags=DEFAULT_CFLAGS).flags() == DEFAULT_CFLAGS  # chosen: exactly those
    src = tmp_path / "a.c"
    src.write_text("int a(void) { return 1; }\n")
    lib = compile_library([src], "a", Toolchain(cc=gcc), cache=tmp_path / "cache")
    import json
    assert set(GCC_CFLAGS) <= set(json.loads((lib.parent / "build.json").read_text())["argv"])
    assert build_key([src], Toolchain(cc=gcc)) != build_key([src], Toolchain(cc=gcc, cflags=DEFAULT_CFLAGS[:-1]))


def test_unoptimized_turns_every_optimisation_flag_to_O0_and_keeps_the_rest():
    tc = Toolchain(cflags=("-O3", "-fPIC", "-march=native", "-Os"), warnings=("-Wall",))
    quick = tc.unoptimized()
    assert quick.flags() == ("-O0", "-fPIC", "-march=native") and quick.warnings == ("-Wall",)
    default = Toolchain().unoptimized().flags()
    assert default[0] == "-O0" and "-O2" not in default and "-ffp-contract=off" in default


@pytest.mark.skipif(os.name != "posix", reason="hand-off runs under a POSIX shell")
def test_compiles_handed_off_finish_after_their_process_and_are_not_compiled_again(tmp_path, monkeypatch):
    """A process starts three compiles into the store, hands them off and ends at once: a build right
    after it in another process compiles none of them again (it waits for the objects the handed-off
    compiles store: the running one's and the two queued ones'), and no private copy is left."""
    import time

    import hydrogen.runtime.compiler as compiler
    sources = []
    for i in range(3):
        src = tmp_path / f"f{i}.c"
        src.write_text("".join(f"double g{i}_{k}(double x) {{ return x * {k}.5 + {i}; }}\n" for k in range(1500)))
        sources.append(src)
    cache, flags = tmp_path / "cache", ("-O1", "-fPIC")
    code = ("from hydrogen.runtime.compiler import precompile, hand_off_precompiles, Toolchain\n"
            f"precompile({[str(s) for s in sources]!r}, Toolchain(cflags={flags!r}), {str(cache)!r})\n"
            "hand_off_precompiles()\n")
    subprocess.run([sys.executable, "-c", code], check=True, timeout=120)
    assert pending_compiles(cache) > 0  # going on without the process (three of about 0.5 s, one after another)
    calls = []
    real = compiler.run_compiler
    monkeypatch.setattr(compiler, "run_compiler", lambda argv, *a, **k: (calls.append(argv), real(argv, *a, **k))[1])
    lib = compile_library(sources, "handed", Toolchain(cflags=flags), cache=cache)
    assert [c for c in calls if "-c" in c] == [] and len(calls) == 1  # the link alone
    f = ctypes.CDLL(str(lib)).g2_7
    f.restype, f.argtypes = ctypes.c_double, [ctypes.c_double]
    assert f(2.0) == 2.0 * 7.5 + 2
    t0 = time.monotonic()
    while pending_compiles(cache):
        assert time.monotonic() - t0 < 60, "a handed-off compile left its private copy"
        time.sleep(0.05)


@pytest.mark.skipif(os.name != "posix", reason="background compiles run under a POSIX shell")
def test_a_background_compile_not_handed_off_ends_with_the_build_that_started_it(tmp_path):
    """A build that fails or is interrupted (cancel_precompiles, also at exit) stops the compiles it
    started and did not hand off: none of them outlives it or stores its object later."""
    import time

    from hydrogen.runtime.compiler import cancel_precompiles, objects_stored, precompile
    pid_file = tmp_path / "pid"
    slow = tmp_path / "slowcc"
    slow.write_text(f'#!/bin/sh\ncase "$*" in *--version*) exec cc "$@";; esac\necho $$ > {pid_file}\n'
                    'sleep 30\nexec cc "$@"\n')
    slow.chmod(0o755)
    src = tmp_path / "f.c"
    src.write_text("double f(double x) { return 2 * x; }\n")
    tc, cache = Toolchain(cc=str(slow), cflags=("-O1", "-fPIC")), tmp_path / "cache"
    precompile([src], tc, cache)
    t0 = time.monotonic()
    while not pid_file.is_file() or not pid_file.read_text().strip():
        assert time.monotonic() - t0 < 30, "the background compile never started"
        time.sleep(0.02)
    pid = int(pid_file.read_text())
    cancel_precompiles()

    def alive():
        try:
            return "\nState:\tZ" not in open(f"/proc/{pid}/status").read()
        except OSError:
            return False
    while alive():
        assert time.monotonic() - t0 < 30, "the compile outlived the build that started it"
        time.sleep(0.02)
    assert objects_stored([src], tc, cache) is False


@pytest.mark.skipif(os.name != "posix", reason="hand-off runs under a POSIX shell")
def test_a_hand_off_keeps_the_compiles_of_the_toolchain_it_is_told_to(tmp_path):
    """hand_off_precompiles(keep=A): A's compiles stay the process's (a quick build waits for its
    unoptimized ones) and end with it; the others finish on their own."""
    import time

    from hydrogen.runtime.compiler import objects_stored
    sources = []
    for i in range(3):
        src = tmp_path / f"k{i}.c"
        src.write_text("".join(f"double k{i}_{k}(double x) {{ return x * {k}.25 - {i}; }}\n" for k in range(1500)))
        sources.append(src)
    cache, a, b = tmp_path / "cache", ("-O1", "-fPIC"), ("-O2", "-fPIC")
    code = ("from hydrogen.runtime.compiler import precompile, hand_off_precompiles, Toolchain\n"
            f"a, b = Toolchain(cflags={a!r}), Toolchain(cflags={b!r})\n"
            f"precompile({[str(s) for s in sources]!r}, a, {str(cache)!r}, first=True)\n"
            f"precompile({[str(s) for s in sources]!r}, b, {str(cache)!r})\n"
            "hand_off_precompiles(keep=a)\n")
    subprocess.run([sys.executable, "-c", code], check=True, timeout=120)
    t0 = time.monotonic()
    while not objects_stored(sources, Toolchain(cflags=b), cache):
        assert time.monotonic() - t0 < 120, "the handed-off compiles never stored their objects"
        time.sleep(0.05)
    assert objects_stored(sources[-1:], Toolchain(cflags=a), cache) is False  # never started, not handed off
