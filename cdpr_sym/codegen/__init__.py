"""Generated code: CasADi functions to C, compiled, cached and called from Python.

:mod:`~cdpr_sym.codegen.generate` is the one code-generation driver,
:mod:`~cdpr_sym.codegen.build` compiles and caches, :mod:`~cdpr_sym.codegen.native` calls
the result through ctypes, :mod:`~cdpr_sym.codegen.names` makes free text safe for C, and
:mod:`~cdpr_sym.codegen.templates` renders hand-written C from template files and
:mod:`~cdpr_sym.codegen.lanes` writes an SX function for many inputs at once (SIMD).
"""

import lazy_loader

# Names are imported on first use, so a command loads only the stages it needs
# (the stub beside this file lists them)
__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
