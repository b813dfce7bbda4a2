"""The closed loop: plant, declared step layout, generated step, simulator, cross-check.

:class:`Case` checks a run's start, goal and gains; :class:`Plant` says how the plant
differs from the model; :func:`simulate` runs the compiled sampled-data loop and
:func:`simulate_adaptive` the continuous-time cross-check; :func:`run_many` advances many
runs at once in vectorised compiled code, and :func:`summarise_many` keeps only their
metrics.
"""

from cdpr_sym.closed_loop.adaptive import simulate_adaptive
from cdpr_sym.closed_loop.batch import run_many, summarise_many
from cdpr_sym.closed_loop.case import Case
from cdpr_sym.closed_loop.layout import Fields, StepLayout
from cdpr_sym.closed_loop.plant import Plant
from cdpr_sym.closed_loop.simulator import Simulator, get_simulator, simulate
from cdpr_sym.closed_loop.step import STOP_REASONS, step_function, step_layout
from cdpr_sym.model import rk4  # re-exported: it lived here before the NMPC needed it

__all__ = ["STOP_REASONS", "Case", "Fields", "Plant", "Simulator", "StepLayout",
           "get_simulator", "rk4", "run_many", "simulate", "simulate_adaptive", "step_function",
           "step_layout", "summarise_many"]
