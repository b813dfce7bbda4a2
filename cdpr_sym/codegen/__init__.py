"""Generated code: CasADi functions to C, compiled, cached and called from Python.

:mod:`~cdpr_sym.codegen.generate` is the one code-generation driver,
:mod:`~cdpr_sym.codegen.build` compiles and caches, :mod:`~cdpr_sym.codegen.native` calls
the result through ctypes, :mod:`~cdpr_sym.codegen.names` makes free text safe for C, and
:mod:`~cdpr_sym.codegen.templates` renders hand-written C from template files and
:mod:`~cdpr_sym.codegen.lanes` writes an SX function for many inputs at once (SIMD).
"""

from cdpr_sym.codegen.build import (
    BACKENDS,
    BuildOptions,
    CompiledLibrary,
    build,
    default_cache_dir,
    find_compiler,
    require_compiler,
    run_command,
)
from cdpr_sym.codegen.generate import generate_c
from cdpr_sym.codegen.lanes import (
    MAX_LANES,
    VECTOR_FLAGS,
    check_lanes,
    lanes_preamble,
    lanes_source,
    native_lanes,
    resolve_lanes,
    unsupported_operations,
    vector_build_options,
)
from cdpr_sym.codegen.names import c_identifier, is_c_identifier, plain_text
from cdpr_sym.codegen.native import NativeFunction, NativeLibrary
from cdpr_sym.codegen.templates import render

__all__ = ["BACKENDS", "MAX_LANES", "VECTOR_FLAGS", "BuildOptions", "CompiledLibrary",
           "NativeFunction", "NativeLibrary", "build", "c_identifier", "check_lanes",
           "default_cache_dir", "find_compiler", "generate_c", "is_c_identifier",
           "lanes_preamble", "lanes_source", "native_lanes", "plain_text", "render",
           "require_compiler", "resolve_lanes", "run_command", "unsupported_operations",
           "vector_build_options"]
