"""The compile cache: it verifies what it hands out, and survives damage, hangs and interrupts.

Every build here is a real compile of a one-line CasADi function (tens of milliseconds);
"compilers" that hang, interrupt or record their arguments are small shell scripts written
into the test's temporary folder. Each test uses its own cache folder, so no library is
loaded in this process before the test damages it (the dynamic loader would otherwise
hand back its already mapped copy).
"""

from __future__ import annotations

import fcntl
import hashlib
import importlib
import math
import os
import shutil
import signal
import subprocess
import threading
import time
from pathlib import Path

import casadi as ca
import pytest

from cdpr_sym import BuildOptions, CompilationFailed, InvalidCase
from cdpr_sym.codegen import CompiledLibrary, build, default_cache_dir, run_command

# ``cdpr_sym.codegen.build`` is the function the package re-exports; this is its module
build_module = importlib.import_module("cdpr_sym.codegen.build")

REAL_CC = shutil.which("cc")
pytestmark = pytest.mark.skipif(REAL_CC is None, reason="needs a C compiler (cc)")


def _doubling(scale: float = 2.0) -> ca.Function:
    """``f(x) = scale * x``: the smallest function worth compiling."""
    x = ca.SX.sym("x")
    return ca.Function("f", [x], [scale * x])


def _build(cache: Path, scale: float = 2.0, **options) -> CompiledLibrary:
    return build([_doubling(scale)], "tiny", options=BuildOptions(cache_dir=cache, **options))


def _evaluate(library: CompiledLibrary, x: float = 3.0) -> float:
    return float(library.function("f")(x))


def _record(library: CompiledLibrary) -> Path:
    return library.path.with_name(library.path.name + ".sha256")


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _script(folder: Path, name: str, body: str) -> Path:
    """An executable shell script ``folder/name`` running ``body``."""
    path = folder / name
    path.write_text("#!/bin/sh\n" + body)
    path.chmod(0o755)
    return path


def _leftovers(cache: Path) -> list[Path]:
    return sorted(cache.rglob("*.tmp"))


def _alive(pid: int) -> bool:
    """Whether process ``pid`` is running (a zombie waiting to be reaped counts as dead)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (FileNotFoundError, ProcessLookupError):
        return False
    return state not in ("Z", "X")


def _dies_soon(pid: int, seconds: float = 3.0) -> bool:
    deadline = time.monotonic() + seconds
    while _alive(pid):
        if time.monotonic() > deadline:
            return False
        time.sleep(0.02)
    return True


# -- 1. verification of cached libraries ---------------------------------------------------

def test_a_build_records_the_sha256_of_the_library_it_publishes(tmp_path):
    library = _build(tmp_path)
    assert library.compiled_now is True
    assert _record(library).read_text() == f"{_sha256(library.path)}  tiny.so\n"
    assert _build(tmp_path).compiled_now is False


def _truncate(path: Path) -> None:
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])


def _flip_bytes(path: Path) -> None:
    data = bytearray(path.read_bytes())
    middle = len(data) // 2
    data[middle:middle + 16] = bytes(b ^ 0xFF for b in data[middle:middle + 16])
    path.write_bytes(bytes(data))


def _empty(path: Path) -> None:
    path.write_bytes(b"")


def _drop_record(path: Path) -> None:
    path.with_name(path.name + ".sha256").unlink()


def _garble_record(path: Path) -> None:
    path.with_name(path.name + ".sha256").write_bytes(b"\xff\xfe not a digest")


@pytest.mark.parametrize("damage", [_truncate, _flip_bytes, _empty, _drop_record,
                                    _garble_record])
def test_a_damaged_cached_library_is_rebuilt_not_loaded(tmp_path, damage):
    first = _build(tmp_path)
    damage(first.path)
    again = _build(tmp_path)
    assert again.compiled_now is True
    assert again.path == first.path and again.key == first.key
    assert _record(again).read_text() == f"{_sha256(again.path)}  tiny.so\n"
    assert _evaluate(again) == 6.0
    assert _build(tmp_path).compiled_now is False


def test_a_swapped_library_is_rebuilt_instead_of_giving_other_numbers(tmp_path):
    doubling = _build(tmp_path, 2.0)
    tripling = _build(tmp_path, 3.0)  # same name, other source: its own key and folder
    assert tripling.key != doubling.key
    shutil.copyfile(tripling.path, doubling.path)  # a valid library, of another function
    again = _build(tmp_path, 2.0)
    assert again.compiled_now is True
    assert _evaluate(again) == 6.0
    assert _sha256(again.path) != _sha256(tripling.path)


def test_a_swapped_library_with_a_fresh_record_is_rebuilt(tmp_path):
    """Another key's library copied in together with a record of its own sha256 (what
    ``sha256sum lib.so > lib.so.sha256`` writes): it lacks this key's mark, so it is
    rebuilt, not loaded under the wrong name."""
    doubling = _build(tmp_path, 2.0)
    tripling = _build(tmp_path, 3.0)
    shutil.copyfile(tripling.path, doubling.path)
    _record(doubling).write_text(f"{_sha256(doubling.path)}  tiny.so\n")
    again = _build(tmp_path, 2.0)
    assert again.compiled_now is True
    assert _evaluate(again) == 6.0


def test_the_record_is_in_place_before_the_library_is_published(tmp_path, monkeypatch):
    renamed: list[str] = []
    replace = os.replace

    def recording_replace(source, destination):
        renamed.append(Path(destination).name)
        replace(source, destination)

    monkeypatch.setattr(os, "replace", recording_replace)
    _build(tmp_path)
    assert renamed.index("tiny.so.sha256") < renamed.index("tiny.so")


# -- 2. a compiler that never returns -------------------------------------------------------

@pytest.mark.parametrize("timeout", [0, -1.0, math.inf, math.nan, "10", True, None])
def test_the_timeout_must_be_a_positive_finite_number_of_seconds(timeout):
    with pytest.raises(InvalidCase) as raised:
        BuildOptions(timeout=timeout)
    assert raised.value.field == "timeout"
    assert "\n" not in str(raised.value)


def test_the_timeout_defaults_to_minutes_and_is_not_part_of_the_key(tmp_path):
    assert BuildOptions().timeout == 300.0
    first = _build(tmp_path, timeout=60)
    assert _build(tmp_path, timeout=5.5).key == first.key


def test_a_hanging_compiler_is_killed_after_the_timeout(tmp_path):
    pid_file = tmp_path / "sleep.pid"
    hanging = _script(tmp_path, "hanging-cc",
                      f'sleep 30 &\necho $! > "{pid_file}"\nwait\n')
    cache = tmp_path / "cache"
    started = time.monotonic()
    with pytest.raises(CompilationFailed) as raised:
        _build(cache, compiler=str(hanging), timeout=0.5)
    assert time.monotonic() - started < 5.0
    first_line, command_line, advice = str(raised.value).splitlines()
    assert "timed out after 0.5 s" in first_line and str(hanging) in first_line
    assert command_line.startswith(f"command: {hanging} ")  # the command as typed, spaced
    assert advice == ("a slow but working compiler needs a larger BuildOptions(timeout=...) "
                      "(seconds)")
    assert _dies_soon(int(pid_file.read_text())), "the compiler's own child survived"
    assert _leftovers(cache) == [] and list(cache.rglob("*.so")) == []
    assert _build(cache).compiled_now is True  # the real compiler, into the same cache


# -- 3. interrupted builds leave no temporary files ----------------------------------------

_OUTPUT_OF_ARGS = 'while [ $# -gt 0 ]; do [ "$1" = -o ] && out="$2"; shift; done\n'


@pytest.mark.slow  # a real SIGINT to this process: flaky once in the full quick suite
def test_ctrl_c_during_a_compile_kills_the_compiler_and_removes_its_output(tmp_path,
                                                                           python_sigint):
    pid_file = tmp_path / "sleep.pid"
    interrupting = _script(tmp_path, "interrupting-cc", _OUTPUT_OF_ARGS + (
        'printf "half a library" > "$out"\n'
        f'sleep 30 &\necho $! > "{pid_file}"\n'
        "kill -INT $PPID\nwait\n"))
    cache = tmp_path / "cache"
    with pytest.raises(KeyboardInterrupt):
        _build(cache, compiler=str(interrupting))
    assert _dies_soon(int(pid_file.read_text())), "the compiler's own child survived"
    assert _leftovers(cache) == [] and list(cache.rglob("*.so*")) == []


def test_ctrl_c_while_the_compiler_starts_is_held_until_its_group_can_be_killed(
        tmp_path, monkeypatch, python_sigint):
    """A Ctrl-C landing inside ``Popen``, after the compiler started but before the call
    holds its process, used to leave the compiler running (the test above failed now and
    then under load): it is now delivered once the process is known, and the group dies."""
    pid_file = tmp_path / "sleep.pid"
    compiler = _script(tmp_path, "slow-cc", f'sleep 30 &\necho $! > "{pid_file}"\nwait\n')

    class InterruptedWhileStarting(subprocess.Popen):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            deadline = time.monotonic() + 10.0
            while not (pid_file.exists() and pid_file.read_text().endswith("\n")):
                assert time.monotonic() < deadline, "the compiler never started its child"
                time.sleep(0.01)
            os.kill(os.getpid(), signal.SIGINT)  # Python's handler runs inside __init__
            time.sleep(0.2)

    monkeypatch.setattr(build_module.subprocess, "Popen", InterruptedWhileStarting)
    with pytest.raises(KeyboardInterrupt):
        _build(tmp_path / "cache", compiler=str(compiler))
    monkeypatch.undo()
    assert _dies_soon(int(pid_file.read_text())), "the compiler's own child survived"
    assert _leftovers(tmp_path / "cache") == []


def test_an_interrupt_while_writing_the_record_leaves_no_library(tmp_path, monkeypatch):
    source_written = build_module.write_atomically
    calls = []

    def write_then_interrupt(path, text):
        calls.append(Path(path).name)
        if Path(path).name.endswith(".sha256"):
            raise KeyboardInterrupt
        source_written(path, text)

    monkeypatch.setattr(build_module, "write_atomically", write_then_interrupt)
    with pytest.raises(KeyboardInterrupt):
        _build(tmp_path)
    assert calls == ["tiny.c", "tiny_key.c", "tiny.so.sha256"]
    assert _leftovers(tmp_path) == [] and list(tmp_path.rglob("*.so*")) == []
    monkeypatch.undo()
    assert _build(tmp_path).compiled_now is True


def test_an_interrupt_inside_the_compiler_call_leaves_no_partial_output(tmp_path, monkeypatch):
    def compiler_writing_then_interrupted(command, *, timeout=None):
        Path(command[command.index("-o") + 1]).write_bytes(b"\x7fELF partial")
        raise KeyboardInterrupt

    monkeypatch.setattr(build_module, "run_command", compiler_writing_then_interrupted)
    with pytest.raises(KeyboardInterrupt):
        _build(tmp_path)
    assert _leftovers(tmp_path) == [] and list(tmp_path.rglob("*.so*")) == []


def test_a_killed_compiler_fails_in_one_line_and_leaves_no_partial_output(tmp_path):
    killed = _script(tmp_path, "killed-cc", _OUTPUT_OF_ARGS
                     + 'printf "half a library" > "$out"\nkill -KILL $$\n')
    cache = tmp_path / "cache"
    with pytest.raises(CompilationFailed, match="exit code -9"):
        _build(cache, compiler=str(killed))
    assert _leftovers(cache) == []


def test_temporary_files_of_a_dead_build_are_removed_under_the_lock(tmp_path):
    library = _build(tmp_path)
    folder = library.path.parent
    stale = [folder / "tmpk2j4x9.so.tmp", folder / "tmp81hd0q.tmp"]
    for path in stale:
        path.write_bytes(b"left by a build killed mid-way")
    with open(folder / ".lock", "a") as lock:  # another build is running in this folder
        fcntl.flock(lock, fcntl.LOCK_EX)
        results: list[CompiledLibrary] = []
        waiting = threading.Thread(target=lambda: results.append(_build(tmp_path)))
        waiting.start()
        time.sleep(0.3)
        assert all(path.exists() for path in stale), "removed without holding the lock"
        assert waiting.is_alive()
    waiting.join(timeout=10)
    assert not waiting.is_alive() and results[0].compiled_now is False
    assert _leftovers(tmp_path) == []
    assert {p.name for p in folder.iterdir()} == {".lock", "tiny.c", "tiny_key.c", "tiny.so",
                                                  "tiny.so.sha256"}
    assert _build(tmp_path).compiled_now is False


# -- 4. an unusable cache location ----------------------------------------------------------

def _assert_cache_dir_error(error: InvalidCase, path: Path) -> None:
    message = str(error)
    assert error.field == "cache_dir"
    assert "\n" not in message
    assert str(path) in message
    assert "XDG_CACHE_HOME" in message and "cache_dir" in message


def test_a_cache_dir_that_is_a_file_is_a_one_line_error(tmp_path):
    occupied = tmp_path / "cache"
    occupied.write_text("not a folder")
    with pytest.raises(InvalidCase) as raised:
        _build(occupied)
    _assert_cache_dir_error(raised.value, occupied)
    assert "is a file" in str(raised.value)


def test_an_xdg_cache_home_that_is_a_file_is_a_one_line_error(tmp_path, monkeypatch):
    occupied = tmp_path / "xdg"
    occupied.write_text("not a folder")
    monkeypatch.setenv("XDG_CACHE_HOME", str(occupied))
    with pytest.raises(InvalidCase) as raised:
        build([_doubling()], "tiny")
    _assert_cache_dir_error(raised.value, occupied)


def test_a_key_folder_taken_by_a_file_is_a_one_line_error(tmp_path):
    key_folder = _build(tmp_path / "elsewhere").path.parent.name
    cache = tmp_path / "cache"
    cache.mkdir()
    (cache / key_folder).write_text("not a folder")
    with pytest.raises(InvalidCase) as raised:
        _build(cache)
    _assert_cache_dir_error(raised.value, cache / key_folder)


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only folders")
def test_a_cache_dir_without_write_permission_is_a_one_line_error(tmp_path):
    cache = tmp_path / "cache"
    cache.mkdir()
    cache.chmod(0o555)
    try:
        with pytest.raises(InvalidCase) as raised:
            _build(cache)
    finally:
        cache.chmod(0o755)
    _assert_cache_dir_error(raised.value, cache)


def test_the_timeout_holds_when_it_is_shorter_than_one_wait_slice(monkeypatch):
    monkeypatch.setattr(build_module, "_WAIT_SLICE", 20.0)
    with subprocess.Popen(["sleep", "30"]) as sleeper:
        started = time.monotonic()
        with pytest.raises(subprocess.TimeoutExpired):
            build_module._communicate_in_slices(sleeper, 0.2)
        waited = time.monotonic() - started
        sleeper.kill()
    assert waited < 10.0  # the deadline, not one whole 20 s slice


def test_a_program_that_cannot_be_run_is_a_compilation_failure(tmp_path):
    missing = tmp_path / "no-such-compiler"
    with pytest.raises(CompilationFailed) as raised:
        run_command([str(missing), "--version"])
    # the operating system's reason in words, not Python's "[Errno 2] ..." form
    assert str(raised.value) == f"cannot run {missing}: No such file or directory"


def test_the_default_cache_is_under_the_home_folder_without_xdg_cache_home(
        tmp_path, monkeypatch):
    monkeypatch.delenv("XDG_CACHE_HOME", raising=False)
    monkeypatch.setenv("HOME", str(tmp_path))
    assert default_cache_dir() == tmp_path / ".cache" / "cdpr_sym"
    monkeypatch.setenv("XDG_CACHE_HOME", "")  # set but empty counts as unset (XDG spec)
    assert default_cache_dir() == tmp_path / ".cache" / "cdpr_sym"


# -- 5. compiler flags are part of the cache key --------------------------------------------

def test_compiler_flags_are_part_of_the_cache_key(tmp_path):
    log = tmp_path / "argv.log"
    wrapper = _script(tmp_path, "recording-cc", f'echo "$*" >> "{log}"\nexec "{REAL_CC}" "$@"\n')
    cache = tmp_path / "cache"
    default = _build(cache, compiler=str(wrapper))
    unoptimised = _build(cache, compiler=str(wrapper), flags=("-O0",))
    assert default.compiled_now is True and unoptimised.compiled_now is True
    assert default.key != unoptimised.key
    assert default.path.parent != unoptimised.path.parent
    default_argv, unoptimised_argv = (line.split() for line in log.read_text().splitlines())
    assert "-O2" in default_argv and "-O0" not in default_argv
    assert "-O0" in unoptimised_argv and "-O2" not in unoptimised_argv
    assert str(unoptimised.path.parent) in " ".join(unoptimised_argv)
    assert _evaluate(default) == _evaluate(unoptimised) == 6.0
    assert _build(cache, compiler=str(wrapper), flags=("-O0",)).compiled_now is False
    assert len(log.read_text().splitlines()) == 2


def test_a_library_built_for_this_cpu_is_not_shared_with_another(tmp_path, monkeypatch):
    cache, native = tmp_path / "cache", ("-O2", "-march=native")
    here = _build(cache, flags=native)
    portable = _build(cache)
    monkeypatch.setattr(build_module, "host_cpu", lambda: "another processor")
    elsewhere = _build(cache, flags=native)
    assert elsewhere.compiled_now is True and elsewhere.key != here.key
    # a portable build does not depend on the processor
    assert _build(cache).key == portable.key and _build(cache).compiled_now is False
