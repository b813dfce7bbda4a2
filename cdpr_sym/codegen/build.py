"""Building generated C: the compiler, its options, and an on-disk cache of libraries.

Staged like a build: CasADi generates one C file for a set of functions
(:func:`~cdpr_sym.codegen.generate.generate_c`), its text is hashed (with the compiler,
flags and CasADi version) into a cache key, and only a key that is not yet on disk is
compiled. The compiled library is loaded either as ``ca.external`` functions (CasADi's own
call path) or through ctypes (:mod:`cdpr_sym.codegen.native`), which avoids CasADi's
per-call overhead in hot loops.

Cache layout: one folder ``<name>-<key>`` per key in the cache folder, holding the C source
``<name>.c``, the key's mark ``<name>_key.c``, the library ``<name>.so``, its record
``<name>.so.sha256`` (one line ``<sha256 hex>  <name>.so``, the format ``sha256sum -c``
reads) and a lock file ``.lock``.

Concurrency: a build holds an exclusive file lock on its key folder for its whole life (cache
hits included) and publishes the library by an atomic rename, so two processes building the
same model never see a partial file. Holding the lock also proves that nobody else is writing
in the folder, so temporary files found there (``*.tmp``) were left by a process that died
mid-build, and are removed.

Verification: the record is written (atomically) before the library is renamed into place,
and a cache hit is returned only when the library's sha256 equals its record and the library
carries its own key (a string compiled into it from ``<name>_key.c``). A library that is
damaged, truncated, swapped for another one (even with a fresh record) or has no record is
deleted and rebuilt under the lock: an unverified file is never handed out to be loaded.
What this guards against is accident (a crash mid-write, a disk error, a file copied over
another); it is no defence against someone who can write the cache folder, who can make a
library with any key and record, and so run code as the user. Hashing costs about 0.6 ms per
MB of library here (70 us for a 70 kB one), small next to generating the C for the key.

Recipes: generating the C only to find its key costs tens of milliseconds per library, most
of a command's start-up once the library is built. :func:`build_recipe` names what the
source is generated from (the caller's recipe: robot, controller and options), adds the
package's own code (:func:`~cdpr_sym.version.source_digest`), the compiler, flags, CasADi
version and host, and keeps in ``recipes/`` the key that recipe was built under. A later
build of the same recipe finds the key there and loads the verified library without
generating anything; a missing or unverified library falls back to :func:`build`.

Failures: the compiler runs in its own process group, which is killed (the compiler and
everything it started) when it outlives :attr:`BuildOptions.timeout` or when the build is
interrupted, Ctrl-C included; the partial output is removed on any exit. A cache folder that
cannot be used (a path that is a file, no permission, a full disk) is one
:class:`InvalidCase` naming the folder.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import math
import numbers
import os
import platform
import shutil
import signal
import subprocess
import tempfile
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path

import casadi as ca

try:  # POSIX; elsewhere builds are not locked (publishing stays atomic)
    import fcntl
except ImportError:  # pragma: no cover - Windows
    fcntl = None

from cdpr_sym.codegen.generate import generate_c
from cdpr_sym.codegen.native import NativeLibrary
from cdpr_sym.errors import CompilationFailed, CompilerNotFound, InvalidCase
from cdpr_sym.version import source_digest

BACKENDS = ("auto", "c", "casadi")
# -Bsymbolic: calls between generated functions bind inside the library, never to a
# same-named symbol another loaded library exports (e.g. a ``step`` elsewhere in the process).
# -fno-semantic-interposition tells the compiler the same, so it may inline an exported
# function (the generated ``step``) into its caller (the rollout loop): 1.4x the single run.
_LINK_FLAGS = ("-fPIC", "-shared", "-Wl,-Bsymbolic", "-fno-semantic-interposition", "-std=c99")
#: Suffix of the file recording a library's sha256 (``<name>.so`` -> ``<name>.so.sha256``).
_RECORD_SUFFIX = ".sha256"
#: Suffix of every temporary file a build writes in a key folder.
_TEMPORARY_SUFFIX = ".tmp"


def default_cache_dir() -> Path:
    """``$XDG_CACHE_HOME/cdpr_sym`` (or ``~/.cache/cdpr_sym``): where libraries are kept."""
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "cdpr_sym"


def find_compiler(preferred: str | None = None) -> str | None:
    """``preferred`` if given and found, else the first of $CC, cc, gcc, clang; or None.

    A ``preferred`` compiler that is not found gives None (never a silent substitute).
    """
    return _find_compiler(preferred, os.environ.get("CC"), os.environ.get("PATH"))


@functools.lru_cache(maxsize=32)
def _find_compiler(preferred: str | None, cc: str | None, path: str | None) -> str | None:
    """:func:`find_compiler` for one environment (a PATH scan per simulator lookup cost
    ~50 us, a twentieth of a whole run)."""
    if preferred:
        return shutil.which(preferred, path=path)
    for candidate in (cc, "cc", "gcc", "clang"):
        if candidate and shutil.which(candidate, path=path):
            return shutil.which(candidate, path=path)
    return None


def require_compiler(preferred: str | None = None) -> str:
    """:func:`find_compiler`, raising :class:`CompilerNotFound` when there is none."""
    compiler = find_compiler(preferred)
    if compiler is None:
        raise CompilerNotFound(
            "no C compiler found (looked for "
            + (preferred if preferred else "$CC, cc, gcc, clang")
            + "); install one (e.g. 'apt-get install gcc') or pass backend='casadi' "
            "to run CasADi's slower virtual machine instead")
    return compiler


def run_command(command: Sequence[str], *, timeout: float | None = None) -> str:
    """Run a compiler (or a program it built); its stdout, or :class:`CompilationFailed`.

    The program runs in its own process group. When it is still running after ``timeout``
    seconds (None: no limit), or when this call is interrupted (e.g. by Ctrl-C), the whole
    group is killed, so no compiler pass outlives the call.
    """
    command = [str(part) for part in command]
    process: subprocess.Popen | None = None
    # one try from the start: an interruption right after the program started (before a
    # narrower try was entered) would otherwise leave its process group running
    try:
        with _interrupts_held():  # a Ctrl-C during the start raises once process is set
            process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                       text=True, errors="replace", **_own_process_group())
        stdout, stderr = _communicate_in_slices(process, timeout)
    except subprocess.TimeoutExpired:  # raised by the wait alone: the program runs
        _kill_group(process)
        raise CompilationFailed(
            f"{command[0]} timed out after {timeout:g} s and was stopped\n"
            f"command: {' '.join(command)}\n"
            "a slow but working compiler needs a larger BuildOptions(timeout=...) "
            "(seconds)") from None
    except OSError as error:
        if process is not None:
            _kill_group(process)
            raise
        raise CompilationFailed(f"cannot run {command[0]}: {error.strerror or error}") from None
    except BaseException:
        if process is not None:
            _kill_group(process)
        raise
    if process.returncode != 0:
        raise CompilationFailed(
            f"{' '.join(command)} failed with exit code {process.returncode}:\n"
            f"{stderr[-4000:]}")
    return stdout


@contextmanager
def _interrupts_held() -> Iterator[None]:
    """Hold SIGINT and SIGTERM (those with a Python handler) while a program starts, then run
    each handler once for what arrived. Raised inside ``Popen``, before its process is known,
    a ``KeyboardInterrupt`` would leave the program's process group running (a compiler
    interrupted an instant after it started outlived its caller); on leaving, the caller
    holds the process and kills its group. Off the main thread, where Python runs no signal
    handler, nothing is held."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    handlers, arrived = {}, []
    for number in (signal.SIGINT, signal.SIGTERM):
        handler = signal.getsignal(number)
        if callable(handler):  # not SIG_IGN or SIG_DFL, nor set outside Python
            handlers[number] = handler
            signal.signal(number, lambda number, frame: arrived.append(number))
    try:
        yield
    finally:
        for number, handler in handlers.items():
            signal.signal(number, handler)
        for number in dict.fromkeys(arrived):
            handlers[number](number, None)


#: Longest wait inside one call while a program runs, s: a Ctrl-C that the kernel delivered
#: to another thread of this process is acted on within this time.
_WAIT_SLICE = 0.1


def _communicate_in_slices(process: subprocess.Popen, timeout: float | None
                           ) -> tuple[str, str]:
    """``process.communicate(timeout)``, waiting in short slices so that an interruption is
    raised promptly; raises ``TimeoutExpired`` after ``timeout`` s (None: no limit)."""
    deadline = None if timeout is None else time.monotonic() + timeout
    while True:
        left = _WAIT_SLICE if deadline is None else min(_WAIT_SLICE,
                                                        deadline - time.monotonic())
        try:
            return process.communicate(timeout=max(left, 0.0))
        except subprocess.TimeoutExpired:
            if deadline is not None and time.monotonic() >= deadline:
                raise


def _own_process_group() -> dict[str, int]:
    """Popen arguments starting the child as the leader of a new process group (POSIX)."""
    return {"process_group": 0} if hasattr(os, "killpg") else {}


def _kill_group(process: subprocess.Popen) -> None:
    """Kill ``process`` and everything it started (its process group), reap it and close
    its pipes."""
    try:
        os.killpg(process.pid, signal.SIGKILL)
    except (AttributeError, ProcessLookupError, PermissionError):
        process.kill()  # no process groups here, or the group is already gone
    process.wait()
    for pipe in (process.stdout, process.stderr):
        if pipe is not None:
            pipe.close()


#: The default compiler flags: optimised, but every floating-point operation exactly as
#: the generated code writes it (see :class:`BuildOptions`).
EXACT_FLAGS = ("-O2", "-fno-math-errno", "-fno-trapping-math", "-ffp-contract=off")


@dataclasses.dataclass(frozen=True)
class BuildOptions:
    """How generated code is built.

    Parameters
    ----------
    backend : {"auto", "c", "casadi"}
        ``"c"`` compiles generated C and fails with :class:`CompilerNotFound` without a
        compiler; ``"casadi"`` runs CasADi's virtual machine (no compiler, ~10-50x slower);
        ``"auto"`` (default) uses C when a compiler is found, else falls back to ``"casadi"``
        (but a ``compiler`` named explicitly and not found is an error).
    cache_dir : Path, optional
        Where compiled libraries are kept; default :func:`default_cache_dir`.
    compiler : str, optional
        Compiler command; default the first of $CC, cc, gcc, clang on the PATH.
    flags : tuple of str
        Optimisation flags passed to the compiler. The default (:data:`EXACT_FLAGS`) keeps
        every operation of the generated code as written and rounded as IEEE double
        arithmetic rounds it: no re-association, no reciprocals, no fused multiply-add
        (GCC contracts to FMA by default where the target has it, arm64 included), IEEE
        infinities and NaN (the simulator's stop checks rely on them). A run is then the
        same bit for bit in the scalar loop and in the batched one at any lane count.
        Re-association and reciprocals were measured at 0.8-1.3x the speed of this
        default across designs, not a consistent gain.
    timeout : float
        Seconds one compile may take (positive, finite; default 300 s) before the compiler
        is killed and :class:`CompilationFailed` raised. Not part of the cache key.
    """

    backend: str = "auto"
    cache_dir: Path | None = None
    compiler: str | None = None
    flags: tuple[str, ...] = EXACT_FLAGS
    timeout: float = 300.0

    def __post_init__(self) -> None:
        if self.backend not in BACKENDS:
            raise InvalidCase("backend", f"expected one of {BACKENDS}, got {self.backend!r}")
        if (isinstance(self.timeout, bool) or not isinstance(self.timeout, numbers.Real)
                or not math.isfinite(self.timeout) or self.timeout <= 0):
            raise InvalidCase("timeout", "expected a positive, finite number of seconds, "
                              f"got {self.timeout!r}")

    def resolved_backend(self) -> str:
        """``"c"`` or ``"casadi"``, after looking for a compiler when ``backend="auto"``."""
        if self.backend == "casadi":
            return "casadi"
        if find_compiler(self.compiler) is not None:
            return "c"
        if self.backend == "c" or self.compiler:
            require_compiler(self.compiler)
        return "casadi"


def lighter(options: BuildOptions, timeout: float | None = None) -> BuildOptions:
    """``options`` with the default flags' ``-O2`` lowered to ``-O1`` (and ``timeout``, if
    given), for large generated files whose compile time -O2 multiplies; other flags are
    left alone.

    The arithmetic is the same bits at either level: GCC and Clang turn on no
    value-changing floating-point transformation at any -O level (re-association and
    reciprocals need -ffast-math or its parts), and :data:`EXACT_FLAGS`' -ffp-contract=off
    forbids the one they do by default, fusing a multiply and an add; a level changes which
    instructions carry each IEEE operation, never its result (checked on every preset's
    NMPC run, and in tests/test_build_level.py). Flags that differ from the default are
    kept as given: to force -O2 append it (``EXACT_FLAGS + ("-O2",)``).
    """
    if options.flags != EXACT_FLAGS:
        return options
    flags = tuple("-O1" if flag == "-O2" else flag for flag in options.flags)
    changes: dict[str, object] = {"flags": flags}
    if timeout is not None:
        changes["timeout"] = max(timeout, options.timeout)
    return dataclasses.replace(options, **changes)


@dataclasses.dataclass(frozen=True)
class CompiledLibrary:
    """A compiled shared library of generated functions.

    Attributes
    ----------
    path : Path
        The shared library (its sha256 checked against its record when it was built or
        found in the cache).
    source : Path
        The generated C file it was built from.
    key : str
        The cache key (hash of source, compiler, flags and CasADi version).
    compiled_now : bool
        True when this build ran the compiler (a new key, or a cached library that failed
        verification); False when the cache already had a verified library.
    """

    path: Path
    source: Path
    key: str
    compiled_now: bool

    def function(self, name: str) -> ca.Function:
        """A generated function loaded back as a CasADi ``Function`` (``ca.external``)."""
        return ca.external(name, str(self.path))

    def native(self) -> NativeLibrary:
        """The library loaded for direct calls through ctypes."""
        return NativeLibrary(self.path)


def build(functions: Sequence[ca.Function], name: str, *, extra_source: str = "",
          options: BuildOptions = BuildOptions()) -> CompiledLibrary:
    """Generate, compile (unless cached and verified) and return the library of ``functions``.

    ``extra_source`` is C appended to the generated file (e.g. a loop over a generated
    function); it can call every function in ``functions`` by name.

    Raises
    ------
    CompilerNotFound
        No C compiler is available.
    CompilationFailed
        The compiler rejected the generated code (its output is in the message), could not
        be run, or ran longer than ``options.timeout``.
    InvalidCase
        The cache folder cannot be used (field ``cache_dir``).
    """
    compiler = require_compiler(options.compiler)
    source_text = generate_c(functions, name) + extra_source
    key = _cache_key(source_text, compiler, options.flags)
    root = Path(options.cache_dir or default_cache_dir())
    folder = root / f"{name}-{key}"
    library = folder / f"{name}.so"
    source = folder / f"{name}.c"
    with _locked_folder(root, folder):
        _remove_temporaries(folder)
        if _verified(library, key):
            return CompiledLibrary(library, source, key, compiled_now=False)
        try:
            _discard(library)
            write_atomically(source, source_text)
            _compile(compiler, options.flags, source, library, key, timeout=options.timeout)
        except OSError as error:
            raise _unusable_cache(root, folder, error) from None
    return CompiledLibrary(library, source, key, compiled_now=True)


#: What a recipe's generator returns: the functions and the C appended to them.
Generated = tuple[Sequence[ca.Function], str]


def build_recipe(recipe: str | None, name: str, generate: Callable[[], Generated], *,
                 options: BuildOptions = BuildOptions()) -> CompiledLibrary:
    """``build(*generate(), name)``, without calling ``generate`` when this ``recipe`` was
    built before and its library is still in the cache, verified (:func:`built_recipe`);
    with no recipe (None), always ``build(*generate(), name)``.

    ``recipe`` must determine the generated source together with the package's code: every
    value the generator reads that is not in the package (robot data, the controller's
    fields, layout switches). The package's own code (its digest, taken once per process:
    code reloaded into a running process is not seen), the compiler, flags, CasADi version
    and host are added here. A module constant changed at run time is not seen either.

    Raises the errors of :func:`build`.
    """
    found = None if recipe is None else built_recipe(recipe, name, options=options)
    if found is not None:
        return found
    functions, extra_source = generate()
    built = build(functions, name, extra_source=extra_source, options=options)
    if recipe is None:
        return built
    entry = _recipe_entry(recipe, name, options)
    try:
        entry.parent.mkdir(exist_ok=True)
        write_atomically(entry, built.key)
    except OSError as error:
        raise _unusable_cache(entry.parent.parent, entry.parent, error) from None
    return built


def built_recipe(recipe: str, name: str, *, options: BuildOptions = BuildOptions()
                 ) -> CompiledLibrary | None:
    """The verified library :func:`build_recipe` made of ``recipe`` before, or None (never
    built, built by other code or options, or its library gone or damaged)."""
    entry = _recipe_entry(recipe, name, options)
    try:
        key = entry.read_text().strip()
    except (OSError, UnicodeDecodeError):
        return None
    if len(key) != 20 or any(c not in "0123456789abcdef" for c in key):
        return None
    root = entry.parent.parent
    folder = root / f"{name}-{key}"
    if not folder.is_dir():
        return None
    library = folder / f"{name}.so"
    with _locked_folder(root, folder):
        if _verified(library, key):
            return CompiledLibrary(library, folder / f"{name}.c", key, compiled_now=False)
    return None


def _recipe_entry(recipe: str, name: str, options: BuildOptions) -> Path:
    """The file that records the cache key ``recipe`` was built under."""
    compiler = require_compiler(options.compiler)
    root = Path(options.cache_dir or default_cache_dir())
    return root / "recipes" / f"{name}-{_recipe_key(recipe, compiler, options.flags)}"


def _recipe_key(recipe: str, compiler: str, flags: Sequence[str]) -> str:
    return _cache_key(f"{source_digest(full=True)}\0{recipe}", compiler, flags)


def _cache_key(source_text: str, compiler: str, flags: Sequence[str]) -> str:
    digest = hashlib.sha256()
    # a library built for this host's instruction set must not be loaded on another CPU
    # sharing the cache (illegal instruction)
    host = host_cpu() if any(flag.startswith(("-march=native", "-mcpu=native"))
                              for flag in flags) else ""
    for part in (source_text, compiler, " ".join((*flags, *_LINK_FLAGS)), ca.__version__,
                 host):
        digest.update(part.encode())
        digest.update(b"\0")
    return digest.hexdigest()[:20]


@functools.lru_cache(maxsize=1)
def host_cpu() -> str:
    """This machine's processor model and feature flags (Linux), else its architecture."""
    try:
        lines = Path("/proc/cpuinfo").read_text().splitlines()
    except OSError:
        lines = []
    wanted = [line for line in lines if line.startswith(("model name", "flags", "Features"))]
    return "\n".join(dict.fromkeys(wanted)) or f"{platform.machine()} {platform.processor()}"


@contextmanager
def _locked_folder(root: Path, folder: Path) -> Iterator[None]:
    """Create ``folder`` (in the cache folder ``root``) and hold its exclusive lock.

    Raises :class:`InvalidCase` (``cache_dir``) when the folder cannot be made or locked.
    """
    try:
        folder.mkdir(parents=True, exist_ok=True)
        lock = open(folder / ".lock", "a")
    except OSError as error:
        raise _unusable_cache(root, folder, error) from None
    with lock:
        if fcntl is not None:
            try:
                fcntl.flock(lock, fcntl.LOCK_EX)
            except OSError as error:
                raise _unusable_cache(root, folder, error) from None
        yield


def _unusable_cache(root: Path, folder: Path, error: OSError) -> InvalidCase:
    """The one-line error for a cache folder that cannot be used, saying how to fix it."""
    blocker = _file_in_the_way(folder)
    reason = (f"{blocker} is a file, not a folder" if blocker is not None
              else f"{error.strerror or error} at {error.filename or folder}")
    return InvalidCase("cache_dir", f"cannot keep compiled libraries in {root} ({reason}); "
                       "set XDG_CACHE_HOME or pass BuildOptions(cache_dir=...) to a "
                       "writable folder")


def _file_in_the_way(folder: Path) -> Path | None:
    """The nearest of ``folder`` and its parents that exists but is not a folder, if any."""
    for path in (folder, *folder.parents):
        try:
            if path.exists() or path.is_symlink():
                return None if path.is_dir() else path
        except OSError:  # a name the system refuses (too long): not a file in the way
            continue
    return None


def _remove_temporaries(folder: Path) -> None:
    """Delete ``*.tmp`` files in a key folder whose lock the caller holds.

    Only a build holding the lock writes temporary files there, so any found now were left
    by a build that died. Best effort: a read-only cache still serves verified libraries.
    """
    for leftover in folder.glob(f"*{_TEMPORARY_SUFFIX}"):
        try:
            leftover.unlink()
        except OSError:
            pass


def _record_of(library: Path) -> Path:
    """Where the sha256 of ``library`` is recorded: ``<library>.sha256``."""
    return library.with_name(library.name + _RECORD_SUFFIX)


def _file_sha256(path: Path) -> str:
    """The sha256 of a file's bytes, in hex (about 0.6 ms per MB)."""
    with open(path, "rb") as file:
        return hashlib.file_digest(file, "sha256").hexdigest()


def _key_mark(key: str) -> bytes:
    """The bytes a library built under ``key`` carries (see :func:`_compile`)."""
    return f"cdpr_sym build key {key}".encode()


def _verified(library: Path, key: str) -> bool:
    """Whether ``library`` exists, its sha256 equals the one its record holds, and it was
    built under ``key`` (it carries :func:`_key_mark`): a library of another key copied in
    with a fresh record is not this key's."""
    try:
        fields = _record_of(library).read_text().split()
        if len(fields) != 2 or fields[1] != library.name:
            return False
        data = library.read_bytes()
    except (OSError, UnicodeDecodeError):
        return False
    return hashlib.sha256(data).hexdigest() == fields[0] and _key_mark(key) in data


def _discard(library: Path) -> None:
    """Delete a library that failed verification and its record (both may be missing).

    Unlinking, never truncating, keeps the old file intact for any process that has it
    mapped; the rebuilt library is a new file.
    """
    _record_of(library).unlink(missing_ok=True)
    library.unlink(missing_ok=True)


def write_atomically(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` through a temporary file and a rename (never partial)."""
    handle, name = tempfile.mkstemp(dir=path.parent, suffix=_TEMPORARY_SUFFIX)
    partial = Path(name)
    try:
        with os.fdopen(handle, "w") as file:
            file.write(text)
        os.replace(partial, path)
    finally:
        partial.unlink(missing_ok=True)


def _compile(compiler: str, flags: Sequence[str], source: Path, library: Path, key: str, *,
             timeout: float) -> None:
    """Compile ``source`` into ``library`` and publish it with its sha256 record.

    A second translation unit gives the library the string :func:`_key_mark` of ``key``,
    which :func:`_verified` looks for. The compiler writes a temporary file; its record is
    written before it is renamed to ``library``, so a published library always has one.
    The temporary file is removed on any failure, interruptions included. ``timeout`` is in
    seconds.
    """
    handle, name = tempfile.mkstemp(dir=library.parent, suffix=".so" + _TEMPORARY_SUFFIX)
    os.close(handle)
    partial = Path(name)
    mark = library.with_name(library.stem + "_key.c")
    symbol = "cdpr_sym_build_key_" + "".join(c if c.isalnum() else "_" for c in library.stem)
    write_atomically(mark, f'const char {symbol}[] = "{_key_mark(key).decode()}";\n')
    try:
        run_command([compiler, *flags, *_LINK_FLAGS, str(source), str(mark), "-o",
                     str(partial), "-lm"], timeout=timeout)
        write_atomically(_record_of(library), f"{_file_sha256(partial)}  {library.name}\n")
        os.replace(partial, library)
    finally:
        partial.unlink(missing_ok=True)
