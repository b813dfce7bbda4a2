"""Geometry design: where to put a robot's anchors (and attachments) so that a task region
is statically feasible with margin, robust to the build's tolerance, and proven so.

:mod:`~cdpr_sym.geometry.task` holds the task region and its sample poses;
:mod:`~cdpr_sym.geometry.variables` which coordinates vary and within what;
:mod:`~cdpr_sym.geometry.surrogate` the smooth sampled problem CasADi and IPOPT solve;
:mod:`~cdpr_sym.geometry.sampled` the pointwise margins every candidate is judged by;
:mod:`~cdpr_sym.geometry.design` the design run (optimise, then certify with the interval
engine, anchors as intervals); :mod:`~cdpr_sym.geometry.baseline` the same sampled objective
handed to a derivative-free optimiser.
"""
