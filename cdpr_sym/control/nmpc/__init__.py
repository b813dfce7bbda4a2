"""Nonlinear model predictive control with hard tension bounds: the engineer's alternative.

:mod:`~cdpr_sym.control.nmpc.design` holds the options and the part that runs in the 1 kHz
step (playing back the planned tension ramp); :mod:`~cdpr_sym.control.nmpc.problem` the
optimal control problem and its solvers, which :mod:`cdpr_sym.closed_loop.sampled` calls at
the design's own rate.
"""

from cdpr_sym.control.nmpc.design import SOLVERS, Nmpc
from cdpr_sym.control.nmpc.problem import RESIDUAL_TOLERANCE, NmpcProblem

__all__ = ["RESIDUAL_TOLERANCE", "SOLVERS", "Nmpc", "NmpcProblem"]
