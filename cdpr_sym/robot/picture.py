"""A picture of a robot: its frame, anchors, cables and end-effector, in 2-D or 3-D.

:class:`RobotPicture` draws a robot once and moves it (:meth:`RobotPicture.show`), so a
still picture (:meth:`Robot.draw <cdpr_sym.robot.Robot.draw>`, ``cdpr-sym view``) and an
animation of a run (:mod:`cdpr_sym.results.animation`) are the same drawing.

What is drawn, in world coordinates (m; x to the right, the last axis up):

* the frame box (positions only), dotted grey; the anchors, black triangles;
* each cable a line from its anchor to its attachment. Given tensions, a cable in the box
  [T_min, T_max] takes its tension's colour (viridis, T_min dark to T_max yellow, a colour
  bar beside); a cable outside the box is red and dashed (below T_min: slack; above T_max:
  over the motor's limit);
* the end-effector: a point mass as a dot, a body as the outline of its attachment points
  (:func:`cdpr_sym.robot.scene.body_faces`) with its centre of mass as a cross;
* optionally a goal (a star), the path so far (a line), feasible poses of a workspace
  (small green dots) and the boxes of a certificate (green proven, red disproven, grey
  undecided).

Planar robots are drawn in the (x, z) plane, spatial ones on matplotlib's 3-D axes.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from cdpr_sym.robot.scene import Robot, Scene, checked_pose, scene

#: Colours of the picture.
FRAME_COLOUR, ANCHOR_COLOUR, BODY_COLOUR = "0.55", "black", "tab:blue"
OUT_OF_BOX_COLOUR, NEUTRAL_CABLE_COLOUR, GOAL_COLOUR = "tab:red", "0.25", "tab:orange"
WORKSPACE_COLOUR = "tab:green"
#: Certificate boxes by verdict code (1 proven feasible, 0 undecided, -1 proven infeasible).
BOX_COLOURS = {1: "tab:green", 0: "0.6", -1: "tab:red"}
#: Most boxes drawn as cuboids on 3-D axes (each is six faces); beyond it, their centres.
MAX_SOLID_BOXES = 2000
#: The colour map of tensions in the box.
TENSION_MAP = "viridis"


class RobotPicture:
    """A robot drawn on one Axes, moved pose by pose.

    Parameters
    ----------
    robot : Robot
        What is drawn (a point in 2 or 3 dimensions, a planar or a spatial body).
    ax : matplotlib Axes
        2-D axes for a robot in the plane, 3-D axes (``projection="3d"``) otherwise; see
        :func:`new_axes`.
    tensions : bool
        Whether cables are coloured by tension (and a colour bar is drawn).
    """

    def __init__(self, robot: Robot, ax: Any, *, tensions: bool = True) -> None:
        self.robot, self.ax, self.coloured = robot, ax, tensions
        self.flat = robot.dimension == 2
        if self.flat == (getattr(ax, "name", "") == "3d"):
            from cdpr_sym.errors import InvalidCase

            wanted = "2-D" if self.flat else "3-D (projection='3d')"
            raise InvalidCase("ax", f"{robot.name} is drawn on {wanted} axes, got "
                              f"{getattr(ax, 'name', type(ax).__name__)} axes")
        self._frame()
        self.anchors = _scatter(ax, robot.anchors, marker="^", s=60, color=ANCHOR_COLOUR,
                                zorder=5, label="anchors")
        self.cables = self._cables()
        self.body = self._body()
        self.point = _line(ax, self.flat, marker="o", markersize=8, color=BODY_COLOUR,
                           linestyle="none", zorder=6,
                           label="end-effector" if robot.kind == "point" else None)
        self.com = _line(ax, self.flat, marker="x", markersize=7, color="black",
                         linestyle="none", zorder=7,
                         label="centre of mass" if robot.kind != "point" else None)
        self.ghost = _line(ax, self.flat, marker="o", markersize=7, markerfacecolor="none",
                           color="tab:purple", linestyle="none", zorder=7)
        self.trace = _line(ax, self.flat, color="tab:purple", linewidth=1.0, alpha=0.8)
        self.colour_map = None
        if tensions:
            import matplotlib as mpl

            self.colour_map = mpl.cm.ScalarMappable(
                norm=mpl.colors.Normalize(robot.t_min, robot.t_max), cmap=TENSION_MAP)
        _limits(ax, robot)

    def show(self, pose: np.ndarray, tensions: np.ndarray | None = None, *,
             read: np.ndarray | None = None, path: np.ndarray | None = None) -> list[Any]:
        """Place the robot at ``pose``, its cables coloured by ``tensions`` (m; N), a ghost
        of the end-effector at ``read`` (a pose the controller read, if any) and the
        reference point's ``path`` (k, d) so far. Returns the artists changed."""
        parts = scene(self.robot, pose)
        self._move_cables(parts, tensions)
        self._move_body(parts)
        _set_points(self.point, parts.reference[None, :] if self.robot.kind == "point"
                    else np.empty((0, self.robot.dimension)), self.flat)
        _set_points(self.com, parts.center_of_mass[None, :] if self.robot.kind != "point"
                    else np.empty((0, self.robot.dimension)), self.flat)
        ghost = (np.empty((0, self.robot.dimension)) if read is None
                 else scene(self.robot, read).reference[None, :])
        _set_points(self.ghost, ghost, self.flat)
        _set_points(self.trace, np.empty((0, self.robot.dimension)) if path is None
                    else np.asarray(path)[:, : self.robot.dimension], self.flat)
        return [self.cables, *self.body, self.point, self.com, self.ghost, self.trace]

    def colour_bar(self) -> None:
        """A colour bar of the tension box beside the axes."""
        if self.colour_map is not None:
            bar = self.ax.figure.colorbar(self.colour_map, ax=self.ax, shrink=0.7, pad=0.08)
            bar.set_label("cable tension [N] (red dashed: outside the box)")

    def _frame(self) -> None:
        lower = self.robot.frame_lower[: self.robot.dimension]
        upper = self.robot.frame_upper[: self.robot.dimension]
        for segment in _box_edges(lower, upper):
            self.ax.plot(*segment.T, color=FRAME_COLOUR, linestyle=":", linewidth=1.0)

    def _cables(self) -> Any:
        segments = np.zeros((self.robot.m, 2, self.robot.dimension))
        if self.flat:
            from matplotlib.collections import LineCollection

            lines = LineCollection(segments, linewidths=1.6, zorder=4)
            self.ax.add_collection(lines)
            return lines
        from mpl_toolkits.mplot3d.art3d import Line3DCollection

        lines = Line3DCollection(segments, linewidths=1.6)
        self.ax.add_collection3d(lines)
        return lines

    def _body(self) -> list[Any]:
        if self.robot.kind == "point":
            return []
        faces = scene(self.robot).outline
        style = {"facecolor": BODY_COLOUR, "edgecolor": "navy", "alpha": 0.5, "linewidth": 2.0}
        if self.flat:
            from matplotlib.patches import Polygon

            return [self.ax.add_patch(Polygon(face, closed=True, zorder=3, **style))
                    for face in faces]
        from mpl_toolkits.mplot3d.art3d import Poly3DCollection

        if len(faces) > 1:  # a solid's hull triangles: no edges across its flat faces
            style["edgecolor"] = "none"
        plate = Poly3DCollection(list(faces), **style)
        self.ax.add_collection3d(plate)
        return [plate]

    def _move_cables(self, parts: Scene, tensions: np.ndarray | None) -> None:
        self.cables.set_segments(list(parts.cables))
        if tensions is None or self.colour_map is None:
            self.cables.set_color(NEUTRAL_CABLE_COLOUR)
            self.cables.set_linestyle("solid")
            return
        tensions = np.asarray(tensions, dtype=float)
        outside = out_of_box(self.robot, tensions)
        colours = self.colour_map.to_rgba(tensions)
        colours[outside] = _rgba(OUT_OF_BOX_COLOUR)
        self.cables.set_color(colours)
        self.cables.set_linestyle(["--" if flag else "-" for flag in outside])

    def _move_body(self, parts: Scene) -> None:
        if not self.body:
            return
        if self.flat:
            for patch, face in zip(self.body, parts.outline, strict=True):
                patch.set_xy(face)
        else:
            self.body[0].set_verts(list(parts.outline))


def out_of_box(robot: Robot, tensions: np.ndarray) -> np.ndarray:
    """Which cables' tensions (N) are outside [T_min, T_max] (or not finite)."""
    tensions = np.asarray(tensions, dtype=float)
    return ~((tensions >= robot.t_min) & (tensions <= robot.t_max))


def new_axes(robot: Robot, *, pyplot: bool = False, size: tuple[float, float] = (7.0, 5.5)
             ) -> Any:
    """Fresh axes for ``robot``: 2-D for a robot in the plane, 3-D otherwise; through
    ``matplotlib.pyplot`` when ``pyplot`` (a notebook shows it), else on a bare
    ``Figure`` (nothing left open in a long run)."""
    if pyplot:
        import matplotlib.pyplot as plt

        figure = plt.figure(figsize=size)
    else:
        from matplotlib.figure import Figure

        figure = Figure(figsize=size)
    if robot.dimension == 2:
        return figure.add_subplot()
    return figure.add_subplot(projection="3d")


def draw_robot(robot: Robot, *, pose: Sequence[float] | np.ndarray | None = None,
               ax: Any = None, tensions: Sequence[float] | np.ndarray | None = None,
               goal: Sequence[float] | np.ndarray | None = None,
               points: np.ndarray | None = None, boxes: Sequence[Any] | None = None,
               title: str | None = None, pyplot: bool = True,
               points_label: str = "static workspace") -> Any:
    """Draw ``robot`` at ``pose`` (default its case's start) and return the Axes.

    Parameters
    ----------
    robot : Robot
    pose : sequence of float, optional
        n coordinates (m; rad), default the case's start.
    ax : matplotlib Axes, optional
        2-D axes for a planar robot, 3-D for a spatial one; default new ones
        (:func:`new_axes`, through pyplot unless ``pyplot`` is False).
    tensions : sequence of float, optional
        The m cable tensions (N): cables coloured by tension, those outside the box red,
        dashed and labelled. Omitted: cables in one grey.
    goal : sequence of float, optional
        A goal pose, drawn as a star at its reference point.
    points : ndarray, shape (k, >= d), optional
        Feasible poses of a workspace (their positions are drawn), labelled
        ``points_label``.
    boxes : sequence of (lower, upper, verdict), optional
        A certificate's boxes: position corners (m) and the verdict code (1 proven
        feasible, -1 proven infeasible, 0 undecided).
    title : str, optional
        Default: the robot's name and the pose.

    Raises
    ------
    InvalidCase
        ``pose``, ``goal`` or ``tensions`` of the wrong size, or a robot in more than three
        dimensions.
    """
    pose = checked_pose(robot, robot.start if pose is None else pose)
    if ax is None:
        ax = new_axes(robot, pyplot=pyplot)
    picture = RobotPicture(robot, ax, tensions=tensions is not None)
    if points is not None and len(points):
        _scatter(ax, np.asarray(points)[:, : robot.dimension], s=3, alpha=0.25,
                 color=WORKSPACE_COLOUR, label=points_label, zorder=1)
    if boxes:
        draw_boxes(ax, boxes, flat=picture.flat)
    checked = None if tensions is None else _checked_tensions(robot, tensions)
    picture.show(pose, checked)
    if checked is not None:
        _label_out_of_box(robot, ax, scene(robot, pose), checked, flat=picture.flat)
        picture.colour_bar()
    shown = [scene(robot, pose).attachments]
    if goal is not None:
        target = scene(robot, checked_pose(robot, goal, "goal")).reference
        _scatter(ax, target[None, :], marker="*", s=160, color=GOAL_COLOUR, zorder=8,
                 label="goal")
        shown.append(target[None, :])
    _limits(ax, robot, np.vstack(shown))  # a pose outside the frame stays in view
    ax.set_title(title if title is not None else
                 f"{robot.name} at ({', '.join(f'{v:.3g}' for v in pose)})")
    legend(ax)
    return ax


def legend(ax: Any) -> None:
    """The legend under the axes, out of the robot's way."""
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.13), ncol=4, fontsize="small",
              frameon=False)


def draw_boxes(ax: Any, boxes: Sequence[Any], *, flat: bool) -> None:
    """A certificate's boxes (lower, upper, verdict code) on ``ax``: rectangles in the
    plane; cuboids in space, or their centres beyond :data:`MAX_SOLID_BOXES`."""
    by_verdict: dict[int, list[tuple[np.ndarray, np.ndarray]]] = {}
    for lower, upper, verdict in boxes:
        by_verdict.setdefault(int(verdict), []).append(
            (np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)))
    names = {1: "proven feasible", 0: "undecided", -1: "proven infeasible"}
    for verdict, corners in sorted(by_verdict.items(), reverse=True):
        colour, label = BOX_COLOURS.get(verdict, "0.6"), names.get(verdict, str(verdict))
        if flat:
            from matplotlib.collections import PatchCollection
            from matplotlib.patches import Rectangle

            patches = [Rectangle(lo[:2], *(hi - lo)[:2]) for lo, hi in corners]
            ax.add_collection(PatchCollection(patches, facecolor=colour, edgecolor="none",
                                              alpha=0.3, zorder=0, label=label))
        elif len(corners) <= MAX_SOLID_BOXES:
            from mpl_toolkits.mplot3d.art3d import Poly3DCollection

            faces = [face for lo, hi in corners for face in _cuboid_faces(lo, hi)]
            ax.add_collection3d(Poly3DCollection(faces, facecolor=colour, edgecolor="none",
                                                 alpha=0.08, label=label))
        else:
            centres = np.array([(lo + hi) / 2 for lo, hi in corners])
            _scatter(ax, centres[:, :3], s=2, alpha=0.2, color=colour, label=label)


def _checked_tensions(robot: Robot, tensions: Sequence[float] | np.ndarray) -> np.ndarray:
    from cdpr_sym.errors import InvalidCase

    values = np.asarray(tensions, dtype=float).ravel()
    if values.size != robot.m:
        raise InvalidCase("tensions", f"expected {robot.m} tensions (one per cable), got "
                          f"{values.size}")
    return values


def _label_out_of_box(robot: Robot, ax: Any, parts: Scene, tensions: np.ndarray, *,
                      flat: bool) -> None:
    """Name each cable outside the box at its middle: its number, tension and which bound."""
    for i in np.flatnonzero(out_of_box(robot, tensions)):
        middle = parts.cables[i].mean(axis=0)
        bound = (f"< T_min {robot.t_min:g}" if tensions[i] < robot.t_min
                 else f"> T_max {robot.t_max:g}")
        text = f"cable {i + 1}: {tensions[i]:.3g} N {bound}"
        if flat:
            ax.annotate(text, middle, color=OUT_OF_BOX_COLOUR, fontsize="small")
        else:
            ax.text(*middle, text, color=OUT_OF_BOX_COLOUR, fontsize="small")


def _limits(ax: Any, robot: Robot, extra: np.ndarray | None = None) -> None:
    """Axes spanning the anchors, the frame and the ``extra`` points (5 % margin), equal
    scales, labelled."""
    d = robot.dimension
    points = np.vstack([robot.anchors, robot.frame_lower[:d], robot.frame_upper[:d],
                        *([] if extra is None else [np.asarray(extra)[:, :d]])])
    low, high = points.min(axis=0), points.max(axis=0)
    pad = 0.05 * max(float((high - low).max()), 1e-9)
    low, high = low - pad, high + pad
    names = ("x [m]", "z [m]") if d == 2 else ("x [m]", "y [m]", "z [m]")
    if d == 2:
        ax.set_xlim(low[0], high[0])
        ax.set_ylim(low[1], high[1])
        ax.set_aspect("equal")
        ax.set_xlabel(names[0])
        ax.set_ylabel(names[1])
        return
    ax.set_xlim(low[0], high[0])
    ax.set_ylim(low[1], high[1])
    ax.set_zlim(low[2], high[2])
    ax.set_box_aspect(high - low)
    ax.set_xlabel(names[0])
    ax.set_ylabel(names[1])
    ax.set_zlabel(names[2])


def _box_edges(lower: np.ndarray, upper: np.ndarray) -> list[np.ndarray]:
    """The edges of an axis-aligned box as segments (2, d)."""
    d = len(lower)
    corners = [np.where([(k >> i) & 1 for i in range(d)], upper, lower) for k in range(1 << d)]
    return [np.array([corners[a], corners[b]]) for a in range(1 << d) for b in range(a + 1, 1 << d)
            if bin(a ^ b).count("1") == 1]


def _cuboid_faces(lower: np.ndarray, upper: np.ndarray) -> list[np.ndarray]:
    """The six faces of a box in space, each four corners in order."""
    x0, y0, z0 = lower[:3]
    x1, y1, z1 = upper[:3]
    return [np.array(face) for face in (
        [(x0, y0, z0), (x1, y0, z0), (x1, y1, z0), (x0, y1, z0)],
        [(x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)],
        [(x0, y0, z0), (x1, y0, z0), (x1, y0, z1), (x0, y0, z1)],
        [(x0, y1, z0), (x1, y1, z0), (x1, y1, z1), (x0, y1, z1)],
        [(x0, y0, z0), (x0, y1, z0), (x0, y1, z1), (x0, y0, z1)],
        [(x1, y0, z0), (x1, y1, z0), (x1, y1, z1), (x1, y0, z1)])]


def _scatter(ax: Any, points: np.ndarray, **style: Any) -> Any:
    points = np.asarray(points)
    if points.shape[1] == 3:
        style.setdefault("depthshade", False)
    return ax.scatter(*points.T, **style)


def _line(ax: Any, flat: bool, **style: Any) -> Any:
    if flat:
        return ax.plot([], [], **style)[0]
    return ax.plot([], [], [], **style)[0]


def _set_points(line: Any, points: np.ndarray, flat: bool) -> None:
    if flat:
        line.set_data(points[:, 0], points[:, 1])
    else:
        line.set_data_3d(points[:, 0], points[:, 1], points[:, 2])


def _rgba(colour: str) -> tuple[float, float, float, float]:
    from matplotlib.colors import to_rgba

    return to_rgba(colour)
