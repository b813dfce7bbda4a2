"""The closed loop: plant, declared step layout, generated step, simulator, cross-check.

:class:`Case` checks a run's start, goal and gains; :class:`Plant` says how the plant
differs from the model; :func:`simulate` runs the compiled sampled-data loop and
:func:`simulate_adaptive` the continuous-time cross-check; :func:`run_many` advances many
runs at once in vectorised compiled code, and :func:`summarise_many` keeps only their
metrics.
"""

import lazy_loader

# Names are imported on first use, so a command loads only the stages it needs
# (the stub beside this file lists them)
__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
