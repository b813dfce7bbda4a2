"""Workspaces: poses where the weight (static) or a box of wrenches (wrench-feasible) can be
held with tensions in the box, and wrench closure; classified in generated C, several poses
at once in SIMD lanes."""

import lazy_loader

# Names are imported on first use, so a command loads only the stages it needs
# (the stub beside this file lists them)
__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
