"""Hand-written peers of cdpr_sym's closed-loop simulation of the aras3 point mass.

Three independent implementations of the same sampled-data loop (C, numba, JAX), used as
reference points for cdpr_sym's own speed; they read the robot's data from its preset file
and share no code with cdpr_sym. ``check`` compares them with cdpr_sym, ``timing`` times
them.
"""
