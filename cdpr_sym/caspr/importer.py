"""A CASPR model imported: read (:mod:`~cdpr_sym.caspr.xml_model`), converted
(:mod:`~cdpr_sym.caspr.convert`), given a case (:mod:`~cdpr_sym.caspr.case`)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy.typing as npt

from cdpr_sym.caspr.case import ChosenCase, choose_case
from cdpr_sym.caspr.convert import RULES, converted_robot, pose_from_caspr
from cdpr_sym.caspr.xml_model import CasprModel, read_caspr
from cdpr_sym.robot import Robot


@dataclasses.dataclass(frozen=True)
class CasprImport:
    """The imported robot with its account: what was read, the map used, the case chosen."""

    robot: Robot
    model: CasprModel
    case: ChosenCase

    @property
    def rule(self) -> str:
        """The coordinate map used (:data:`cdpr_sym.caspr.convert.RULES`)."""
        return RULES[self.model.joint]

    def summary(self) -> dict:
        """What was imported, as plain Python (JSON)."""
        robot = self.robot
        return {"robot": robot.name, "kind": robot.kind, "n": robot.n, "m": robot.m,
                "coordinates": list(robot.coordinate_names), "mass_kg": robot.mass,
                "tension_N": [robot.t_min, robot.t_max], "caspr_joint": self.model.joint,
                "cable_set": self.model.cable_set, "conversion": self.rule,
                "frame": {"lower": robot.frame_lower.tolist(),
                          "upper": robot.frame_upper.tolist()},
                "case": self.case.as_dict()}


def default_name(bodies: str | Path) -> str:
    """The bodies file's stem without a trailing ``_bodies`` (``IPAnema_1_bodies.xml`` ->
    ``IPAnema_1``)."""
    stem = Path(bodies).stem
    return stem.removesuffix("_bodies") or stem


def caspr_import(bodies: str | Path, cables: str | Path, *, cable_set: str | None = None,
                 name: str | None = None, start: npt.ArrayLike | None = None,
                 goal: npt.ArrayLike | None = None) -> CasprImport:
    """:func:`import_caspr` with its account (the model read and the case's reasons)."""
    model = read_caspr(bodies, cables, cable_set=cable_set)
    robot = converted_robot(model, default_name(bodies) if name is None else name)
    case = choose_case(robot, pose_from_caspr(model, model.q_initial), start=start, goal=goal)
    return CasprImport(robot.with_case(start=case.start, goal=case.goal), model, case)


def import_caspr(bodies: str | Path, cables: str | Path, *, cable_set: str | None = None,
                 name: str | None = None, start: npt.ArrayLike | None = None,
                 goal: npt.ArrayLike | None = None) -> Robot:
    """The :class:`~cdpr_sym.robot.Robot` a CASPR bodies file and cables file describe.

    Parameters
    ----------
    bodies, cables : str or Path
        CASPR's ``*_bodies.xml`` and ``*_cables.xml`` (:func:`read_caspr`).
    cable_set : str, optional
        The cable set's ``id``; default the cables file's ``default_cable_set``.
    name : str, optional
        The robot's name; default :func:`default_name` of ``bodies``.
    start, goal : array_like, shape (n,), optional
        The case's start and goal in cdpr_sym's coordinates (m, rad;
        :mod:`cdpr_sym.model.kinematics`), not CASPR's; chosen by
        :func:`~cdpr_sym.caspr.case.choose_case` when not given.

    Returns
    -------
    Robot
        Mapped exactly (:mod:`cdpr_sym.caspr.convert`), gravity 9.81 m/s^2 along -z, the
        tension box CASPR's force_min..force_max, gains derived from the robot
        (:mod:`cdpr_sym.robot.gains`).

    Raises
    ------
    InvalidRobot
        A file is refused or describes what cdpr_sym cannot represent (the field names the
        file and element: ``bodies.joint``, ``cables.attachments``, ...).
    InvalidCase
        ``start`` or ``goal`` refused, or no pose of the frame statically feasible.

    Examples
    --------
    >>> robot = import_caspr("IPAnema_1_bodies.xml", "IPAnema_1_cables.xml")  # doctest: +SKIP
    >>> robot.kind, robot.m  # doctest: +SKIP
    ('spatial', 8)
    """
    return caspr_import(bodies, cables, cable_set=cable_set, name=name, start=start,
                        goal=goal).robot
