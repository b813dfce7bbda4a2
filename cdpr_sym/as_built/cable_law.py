"""The elastic cable's law, in one place: stretch, lengths and the pull on the drum.

A cable of axial stiffness EA (N) whose unstretched (paid-out) length is l0, stretched to
the length l, carries the spring tension T = EA (l - l0) / l0 (stiffness EA / l0 per metre
of stretch, CONVENTIONS). So at tension T:

* its strain is T / EA (:func:`strain`);
* its length is l = l0 (1 + T / EA) (:func:`stretched_length`), and the unstretched length
  that carries T at the length l is l0 = l / (1 + T / EA) (:func:`unstretched_length`): what
  an encoder on the drum counts when the platform is at l;
* it pulls its drum with p = -dU/dl0 = T + T_s^2 / (2 EA) (:func:`drum_pull`), U = EA (l -
  l0)^2 / (2 l0) the elastic energy and T_s the spring part of T (T itself without cable
  damping): the stiffness EA / l0 changes as cable is paid out, and a drum pulled by T
  alone would create T_s^2 / (2 EA) of energy per metre it reels in (the derivation and the
  energy balance that checks it are in docs/as_built_energy.md).

The plant (:mod:`cdpr_sym.as_built.actuation`, :mod:`cdpr_sym.closed_loop.effects`), the
controllers at the motors (:mod:`cdpr_sym.control.winch_level`), the pose readers, the
calibration and the encoder export all use these functions. Arguments are numbers, numpy
arrays or CasADi expressions (the functions only multiply, add and divide).
"""

from __future__ import annotations

from typing import Any


def strain(tension: Any, stiffness: Any) -> Any:
    """T / EA, dimensionless: the stretch per metre of unstretched cable at ``tension``
    (N) on a cable of axial stiffness ``stiffness`` (N)."""
    return tension / stiffness


def stretched_length(unstretched: Any, tension: Any, stiffness: Any) -> Any:
    """l = l0 (1 + T / EA), m: the length of ``unstretched`` m of cable carrying
    ``tension`` N."""
    return unstretched * (1 + tension / stiffness)


def unstretched_length(length: Any, tension: Any, stiffness: Any) -> Any:
    """l0 = l / (1 + T / EA), m: the unstretched cable that carries ``tension`` N when
    stretched to ``length`` m."""
    return length / (1 + tension / stiffness)


def drum_pull(tension: Any, stiffness: Any, spring: Any = None) -> Any:
    """p = T + T_s^2 / (2 EA), N: the force a cable carrying ``tension`` (N; its spring
    part ``spring``, the whole tension when None) pulls its drum with."""
    spring = tension if spring is None else spring
    return tension + spring * spring / (2 * stiffness)
