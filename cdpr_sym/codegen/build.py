"""Building generated C: the compiler, its options, and an on-disk cache of libraries.

Staged like a build: CasADi generates one C file for a set of functions
(:func:`~cdpr_sym.codegen.generate.generate_c`), its text is hashed (with the compiler,
flags and CasADi version) into a cache key, and only a key that is not yet on disk is
compiled. The compiled library is loaded either as ``ca.external`` functions (CasADi's own
call path) or through ctypes (:mod:`cdpr_sym.codegen.native`), which avoids CasADi's
per-call overhead in hot loops.

Concurrency: a build holds an exclusive file lock on its key and publishes the library by
an atomic rename, so two processes building the same model never see a partial file.
"""

from __future__ import annotations

import dataclasses
import hashlib
import os
import shutil
import subprocess
import tempfile
from collections.abc import Sequence
from pathlib import Path

import casadi as ca

try:  # POSIX; elsewhere builds are not locked (publishing stays atomic)
    import fcntl
except ImportError:  # pragma: no cover - Windows
    fcntl = None

from cdpr_sym.codegen.generate import generate_c
from cdpr_sym.codegen.native import NativeLibrary
from cdpr_sym.errors import CompilationFailed, CompilerNotFound, InvalidCase

BACKENDS = ("auto", "c", "casadi")
# -Bsymbolic: calls between generated functions bind inside the library, never to a
# same-named symbol another loaded library exports (e.g. a ``step`` elsewhere in the process).
_LINK_FLAGS = ("-fPIC", "-shared", "-Wl,-Bsymbolic", "-std=c99")


def default_cache_dir() -> Path:
    """``$XDG_CACHE_HOME/cdpr_sym`` (or ``~/.cache/cdpr_sym``): where libraries are kept."""
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "cdpr_sym"


def find_compiler(preferred: str | None = None) -> str | None:
    """``preferred`` if given and found, else the first of $CC, cc, gcc, clang; or None.

    A ``preferred`` compiler that is not found gives None (never a silent substitute).
    """
    if preferred:
        return shutil.which(preferred)
    for candidate in (os.environ.get("CC"), "cc", "gcc", "clang"):
        if candidate and shutil.which(candidate):
            return shutil.which(candidate)
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


def run_command(command: Sequence[str]) -> str:
    """Run a compiler (or a program it built); its stdout, or :class:`CompilationFailed`."""
    try:
        return subprocess.run(list(command), check=True, capture_output=True,
                              text=True).stdout
    except subprocess.CalledProcessError as failure:
        raise CompilationFailed(
            f"{' '.join(command)} failed with exit code {failure.returncode}:\n"
            f"{failure.stderr[-4000:]}") from None


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
        Optimisation flags passed to the compiler. The default allows re-association and
        reciprocals (about 30 % faster here; results move by round-off only) but keeps
        IEEE infinities and NaN, which the simulator's stop checks rely on.
    """

    backend: str = "auto"
    cache_dir: Path | None = None
    compiler: str | None = None
    flags: tuple[str, ...] = ("-O2", "-fno-math-errno", "-fno-trapping-math",
                              "-fassociative-math", "-fno-signed-zeros", "-freciprocal-math")

    def __post_init__(self) -> None:
        if self.backend not in BACKENDS:
            raise InvalidCase("backend", f"expected one of {BACKENDS}, got {self.backend!r}")

    def resolved_backend(self) -> str:
        """``"c"`` or ``"casadi"``, after looking for a compiler when ``backend="auto"``."""
        if self.backend == "casadi":
            return "casadi"
        if find_compiler(self.compiler) is not None:
            return "c"
        if self.backend == "c" or self.compiler:
            require_compiler(self.compiler)
        return "casadi"


@dataclasses.dataclass(frozen=True)
class CompiledLibrary:
    """A compiled shared library of generated functions.

    Attributes
    ----------
    path : Path
        The shared library.
    source : Path
        The generated C file it was built from.
    key : str
        The cache key (hash of source, compiler, flags and CasADi version).
    compiled_now : bool
        True when this build ran the compiler; False when the cache already had it.
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
    """Generate, compile (unless cached) and return the library holding ``functions``.

    ``extra_source`` is C appended to the generated file (e.g. a loop over a generated
    function); it can call every function in ``functions`` by name.

    Raises
    ------
    CompilerNotFound
        No C compiler is available.
    CompilationFailed
        The compiler rejected the generated code (its output is in the message).
    """
    compiler = require_compiler(options.compiler)
    source_text = generate_c(functions, name) + extra_source
    key = _cache_key(source_text, compiler, options.flags)
    folder = (options.cache_dir or default_cache_dir()) / f"{name}-{key}"
    folder.mkdir(parents=True, exist_ok=True)
    library = folder / f"{name}.so"
    source = folder / f"{name}.c"
    with open(folder / ".lock", "w") as lock:
        if fcntl is not None:
            fcntl.flock(lock, fcntl.LOCK_EX)
        if library.exists():
            return CompiledLibrary(library, source, key, compiled_now=False)
        _write_atomically(source, source_text)
        _compile(compiler, options.flags, source, library)
    return CompiledLibrary(library, source, key, compiled_now=True)


def _cache_key(source_text: str, compiler: str, flags: Sequence[str]) -> str:
    digest = hashlib.sha256()
    for part in (source_text, compiler, " ".join((*flags, *_LINK_FLAGS)), ca.__version__):
        digest.update(part.encode())
        digest.update(b"\0")
    return digest.hexdigest()[:20]


def _write_atomically(path: Path, text: str) -> None:
    with tempfile.NamedTemporaryFile("w", dir=path.parent, delete=False, suffix=".tmp") as f:
        f.write(text)
    os.replace(f.name, path)


def _compile(compiler: str, flags: Sequence[str], source: Path, library: Path) -> None:
    handle, partial = tempfile.mkstemp(dir=library.parent, suffix=".so.tmp")
    os.close(handle)
    try:
        run_command([compiler, *flags, *_LINK_FLAGS, str(source), "-o", partial, "-lm"])
    except CompilationFailed:
        os.unlink(partial)
        raise
    os.replace(partial, library)
