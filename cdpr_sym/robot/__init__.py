"""The robot description: geometry, mass, bounds and default case; TOML files and presets.

This is the first room of the flow and knows no CasADi: :class:`Robot` validates every field
with numpy, :func:`load_robot` reads the TOML layout, :func:`preset` the bundled robots.
"""

import lazy_loader

# Names are imported on first use, so a command loads only the stages it needs
# (the stub beside this file lists them)
__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
