# The names this package exports, read by type checkers and by lazy_loader at import
# time: each is imported from its module on first use (see __init__.py).

from .build import (
    BACKENDS,
    BuildOptions,
    CompiledLibrary,
    build,
    build_recipe,
    built_recipe,
    default_cache_dir,
    find_compiler,
    require_compiler,
    run_command,
)
from .generate import generate_c, renamed
from .lanes import (
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
from .names import c_array, c_double, c_identifier, is_c_identifier, plain_text
from .native import NativeFunction, NativeLibrary
from .templates import render

__all__ = ["BACKENDS", "MAX_LANES", "VECTOR_FLAGS", "BuildOptions", "CompiledLibrary",
           "NativeFunction", "NativeLibrary", "build", "build_recipe", "built_recipe", "c_array",
           "c_double", "c_identifier", "check_lanes", "default_cache_dir", "find_compiler",
           "generate_c", "is_c_identifier", "lanes_preamble", "lanes_source", "native_lanes",
           "plain_text", "renamed", "render", "require_compiler", "resolve_lanes", "run_command",
           "unsupported_operations", "vector_build_options"]
