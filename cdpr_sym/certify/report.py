"""A certified workspace written out: its boxes, its summary, a figure, and the sampled check.

``DIR/boxes.csv`` (one row per box: ``lower_<name>``, ``upper_<name>`` per position
coordinate, ``verdict``), ``DIR/certificate.json`` (the shares of the frame's volume, the
time, the sampled check) and ``DIR/workspace.png`` (the boxes cut by a plane through the
case's start, or the boxes themselves for a planar robot).

The sampled check draws poses uniformly over the frame in two steps (a box with probability
proportional to its volume, then a point uniform in it), so each pose's box is known; it
tests each pose by the property's pointwise test (``holds`` of
:class:`~cdpr_sym.certify.registry.WorkspaceProperty`: for static feasibility a numeric solve
of W T = grad V, CasADi's model functions evaluated at points and LU in numpy, not the
interval code, with a wrench box the tension's spread |W^-1 J^T| h over it; with more cables
than degrees of freedom the sampled workspace's hyperplane-shifting test) and counts the
poses whose box's verdict it contradicts. Over an orientation range each pose's angles
are drawn uniformly over the range, or over the witness piece in an infeasible box (there
every orientation must fail); ``sampled_feasible_share`` is then the share among those
draws, not an estimate of the total orientation workspace. A proof is sound only if that
count is zero.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from cdpr_sym.certify.budget import STOPS
from cdpr_sym.certify.registry import method_for, workspace_property
from cdpr_sym.certify.workspace import WorkspaceCertificate


def sampled_check(certificate: WorkspaceCertificate, samples: int,
                  rng: np.random.Generator) -> dict[str, Any]:
    """The sampled check of the module docstring: poses, disagreements by verdict, and the
    share of sampled poses found feasible in undecided boxes."""
    robot = certificate.robot
    volumes = certificate.volumes()
    boxes = rng.choice(len(volumes), size=samples, p=volumes / volumes.sum())
    lower, upper = certificate.lower[boxes], certificate.upper[boxes]
    positions = lower + (upper - lower) * rng.random(lower.shape)
    angles = sampled_orientations(certificate, boxes, rng)
    held = workspace_property(certificate.prop).holds(robot, np.hstack([positions, angles]),
                                                      certificate.half_widths)
    return _counts(certificate, boxes, held)


def sampled_orientations(certificate: WorkspaceCertificate, boxes: np.ndarray,
                         rng: np.random.Generator) -> np.ndarray:
    """The orientation of each sampled pose (rows, rad): the fixed one; over a range, uniform
    in the range, except in an infeasible box, where it is uniform in the piece that proved
    the box infeasible (every orientation there must be infeasible; elsewhere in the range
    some may not be)."""
    samples = len(boxes)
    if certificate.orientation_range is None:
        return np.tile(certificate.orientation, (samples, 1))
    lower, upper = (np.tile(corner, (samples, 1)) for corner in certificate.orientation_range)
    witness = certificate.witness[boxes]
    infeasible = witness >= 0
    lower[infeasible] = certificate.pieces[0][witness[infeasible]]
    upper[infeasible] = certificate.pieces[1][witness[infeasible]]
    return lower + (upper - lower) * rng.random(lower.shape)


def _counts(certificate: WorkspaceCertificate, boxes: np.ndarray, feasible: np.ndarray
            ) -> dict[str, Any]:
    """Disagreements of the sampled poses (in ``boxes``) with their boxes' verdicts."""
    samples = len(boxes)
    verdicts = certificate.verdicts[boxes]
    return {"samples": int(samples),
            "disagreements_feasible": int(np.sum((verdicts == "feasible") & ~feasible)),
            "disagreements_infeasible": int(np.sum((verdicts == "infeasible") & feasible)),
            "sampled_feasible_share": float(feasible.mean()),
            "undecided_sampled": int(np.sum(verdicts == "undecided"))}


def summary(certificate: WorkspaceCertificate, check: dict[str, Any] | None) -> dict[str, Any]:
    """certificate.json's content."""
    shares = certificate.shares()
    wrench = certificate.half_widths
    robot = certificate.robot
    prop = workspace_property(certificate.prop).statement(robot, bool(wrench.size))
    if certificate.orientation_range is not None:
        prop += (" at every orientation of the range (the total orientation workspace; an "
                 "infeasible box is infeasible over one piece of the range)")
    if certificate.anchor_tolerance:
        prop += (f", for every anchor within {certificate.anchor_tolerance:g} m of the robot's "
                 f"on every axis")
    method = method_for(robot, bool(wrench.size), certificate.prop)
    lower = certificate.lower.min(axis=0) if len(certificate.lower) else np.zeros(0)
    upper = certificate.upper.max(axis=0) if len(certificate.upper) else np.zeros(0)
    return {"robot": robot.name, "property": prop, "method": method.description,
            "anchor_tolerance_m": certificate.anchor_tolerance,
            "region": {"lower": lower.tolist(), "upper": upper.tolist()},
            "wrench_half_widths": wrench.tolist(),
            "coordinates": list(certificate.names),
            "orientation": (certificate.orientation.tolist()
                            if certificate.orientation_range is None else None),
            "orientation_range": (None if certificate.orientation_range is None else
                                  [corner.tolist() for corner in certificate.orientation_range]),
            "orientation_pieces": (None if certificate.pieces is None
                                   else len(certificate.pieces[0])),
            "orientation_pieces_per_angle": (
                None if certificate.pieces is None
                else [len(np.unique(column)) for column in certificate.pieces[0].T]),
            "min_width_m": certificate.min_width, "until": certificate.until,
            "time_limit_s": (None if math.isinf(certificate.time_limit)
                             else certificate.time_limit),
            "stopped": certificate.stopped, "stopped_because": STOPS[certificate.stopped],
            "boxes": len(certificate.verdicts),
            "boxes_evaluated": certificate.evaluated, "seconds": certificate.seconds,
            "feasible_share": shares["feasible"], "infeasible_share": shares["infeasible"],
            "undecided_share": shares["undecided"],
            "decided_share": shares["feasible"] + shares["infeasible"],
            "sampled_check": check}


def write_certificate(certificate: WorkspaceCertificate, out: Path,
                      check: dict[str, Any] | None) -> dict[str, Any]:
    """boxes.csv, certificate.json and workspace.png in ``out``; returns the summary."""
    out.mkdir(parents=True, exist_ok=True)
    certificate.write_csv(out / "boxes.csv")
    content = summary(certificate, check)
    (out / "certificate.json").write_text(json.dumps(content, indent=2) + "\n")
    figure(certificate, out / "workspace.png")
    return content


_COLOURS = {"feasible": "#4c9a2a", "infeasible": "#d9d9d9", "undecided": "#d62728"}


def figure(certificate: WorkspaceCertificate, path: Path) -> None:
    """The boxes in the plane of the first two position coordinates, cut at the case's
    start height for a spatial robot."""
    from matplotlib.collections import PolyCollection
    from matplotlib.figure import Figure

    lower, upper, verdicts = certificate.lower, certificate.upper, certificate.verdicts
    prop = workspace_property(certificate.prop)
    what = prop.title
    title = f"{certificate.robot.name}: {what}" + (
        f" against the wrench box {certificate.half_widths.tolist()}"
        if certificate.half_widths.size else "")
    if lower.shape[1] == 3:
        height = certificate.robot.start[2]
        cut = (lower[:, 2] <= height) & (upper[:, 2] >= height)
        lower, upper, verdicts = lower[cut], upper[cut], verdicts[cut]
        title += f" at {certificate.names[2]} = {height:g} m"
    if certificate.orientation_range is not None:
        low, high = certificate.orientation_range
        angles = ", ".join(f"[{a:g}, {b:g}]" for a, b in zip(low, high, strict=True))
        title += f"\nat every orientation of {angles} rad"
    fig = Figure(figsize=(6.5, 5.5))
    ax = fig.add_subplot()
    for verdict, colour in _COLOURS.items():
        chosen = verdicts == verdict
        lo, hi = lower[chosen], upper[chosen]
        corners = np.stack([np.column_stack([lo[:, 0], lo[:, 1]]),
                            np.column_stack([hi[:, 0], lo[:, 1]]),
                            np.column_stack([hi[:, 0], hi[:, 1]]),
                            np.column_stack([lo[:, 0], hi[:, 1]])], axis=1)
        # one collection per verdict: a patch per box took seconds for thousands of boxes
        ax.add_collection(PolyCollection(corners, facecolors=colour, edgecolors="none",
                                         linewidths=0))
        shown = dict(zip(("feasible", "infeasible"), prop.legend, strict=True))
        ax.plot([], [], "s", color=colour, label=shown.get(verdict, verdict))
    frame_lower, frame_upper = certificate.robot.frame_lower, certificate.robot.frame_upper
    ax.set_xlim(frame_lower[0], frame_upper[0])
    ax.set_ylim(frame_lower[1], frame_upper[1])
    ax.set_aspect("equal")
    ax.set_xlabel(f"{certificate.names[0]} (m)")
    ax.set_ylabel(f"{certificate.names[1]} (m)")
    ax.set_title(title, fontsize=10)
    ax.legend(loc="upper right", fontsize=8)
    fig.savefig(path, dpi=110)


#: A box's verdict word in ``boxes.csv`` as a picture's code (1 proven feasible, -1 proven
#: infeasible, 0 undecided; :func:`cdpr_sym.robot.picture.draw_boxes`).
VERDICT_CODES = {"feasible": 1, "infeasible": -1, "undecided": 0}


def read_boxes(folder: Path, robot: Any, pose: np.ndarray | None = None
               ) -> list[tuple[np.ndarray, np.ndarray, int]]:
    """The boxes of the certificate ``folder/boxes.csv`` (:meth:`WorkspaceCertificate.
    write_csv`) as (lower, upper, verdict code) over ``robot``'s position coordinates, m.

    Raises
    ------
    InvalidCase
        Field ``certificate``: no such certificate, not one of ``robot`` (its
        certificate.json names another robot, or its boxes have other coordinates), proven
        at another orientation than ``pose``'s (a rigid body), or a malformed row.
    """
    from cdpr_sym.errors import InvalidCase

    folder = Path(folder)
    table, record = folder / "boxes.csv", folder / "certificate.json"
    if not table.is_file() or not record.is_file():
        raise InvalidCase("certificate", f"no workspace certificate in {folder} (expected "
                          "boxes.csv and certificate.json, as `cdpr-sym certify workspace "
                          "--out DIR` writes)")
    try:
        content = json.loads(record.read_text())
        named = content.get("robot")
    except (ValueError, UnicodeDecodeError, AttributeError):
        raise InvalidCase("certificate", f"{record} is not a certificate's JSON") from None
    if named != robot.name:
        raise InvalidCase("certificate", f"the certificate in {folder} is of robot "
                          f"{named!r}, not {robot.name!r}")
    if pose is not None:
        _check_orientation(content, np.asarray(pose, dtype=float)[robot.dimension:], folder)
    names = list(robot.coordinate_names[: robot.dimension])
    try:
        lines = table.read_text().splitlines()
    except UnicodeDecodeError:
        raise InvalidCase("certificate", f"{table} is not a text file") from None
    expected = [f"lower_{n}" for n in names] + [f"upper_{n}" for n in names] + ["verdict"]
    if not lines or lines[0].split(",")[: len(expected)] != expected:
        raise InvalidCase("certificate", f"{table} does not start with the columns "
                          f"{','.join(expected)}")
    d, boxes = len(names), []
    for number, line in enumerate(lines[1:], start=2):
        cells = line.split(",")
        try:
            corners = np.array(cells[: 2 * d], dtype=float)
            code = VERDICT_CODES[cells[2 * d]]
            if not (np.all(np.isfinite(corners)) and np.all(corners[:d] <= corners[d:])):
                raise ValueError
        except (ValueError, KeyError, IndexError):
            raise InvalidCase("certificate", f"{table} line {number} is not a box "
                              f"({line[:60]!r})") from None
        boxes.append((corners[:d], corners[d:], code))
    return boxes


def _check_orientation(content: dict[str, Any], angles: np.ndarray, folder: Path) -> None:
    """Refuse a picture at ``angles`` (rad) of a certificate proven at another fixed
    orientation, or over a range that does not hold them."""
    from cdpr_sym.errors import InvalidCase

    if not angles.size:
        return
    fixed, span = content.get("orientation"), content.get("orientation_range")
    if span is not None:
        lower, upper = (np.asarray(corner, dtype=float) for corner in span)
        if np.all(angles >= lower) and np.all(angles <= upper):
            return
        held = f"over the range {lower.tolist()} to {upper.tolist()}"
    elif fixed is not None and np.allclose(angles, fixed, rtol=0, atol=1e-9):
        return
    else:
        held = f"at the orientation {fixed}"
    raise InvalidCase("certificate", f"the certificate in {folder} was proven {held} rad; the "
                      f"pose drawn has the angles {angles.tolist()}: draw it at one it proves")
