"""Sweeps: many start/goal pairs, run locally or on Dask, written row by row, resumable."""

import lazy_loader

# Names are imported on first use, so a command loads only the stages it needs
# (the stub beside this file lists them)
__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
