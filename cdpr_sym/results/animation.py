"""A run animated: the robot of :mod:`cdpr_sym.robot.picture` moved through a trajectory.

Each frame shows one sample of the run: the end-effector at the sampled pose q(t_k), each
cable coloured by the tension it carries over the step that starts there (the true tension
of an as-built run; red and dashed outside [T_min, T_max]), the path so far, the goal, and,
for an as-built run whose controller reads the pose from the encoders, a ghost of the pose
it read. A frame is drawn every ``stride`` samples so that the animation plays ``speed``
times real time at ``fps`` frames per second; the last sample is always shown.

The animation is matplotlib's (:class:`matplotlib.animation.FuncAnimation`); a notebook
shows it as JavaScript (``to_jshtml``), and :meth:`RunAnimation.save` writes ``.gif``
(Pillow, which matplotlib needs anyway), ``.html`` (the same JavaScript) or ``.mp4`` (needs
ffmpeg on the PATH; refused in one line naming the format when it is missing).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Protocol

import numpy as np
from matplotlib.animation import FuncAnimation

from cdpr_sym.errors import InvalidCase
from cdpr_sym.robot import Robot
from cdpr_sym.robot.picture import RobotPicture, legend, new_axes


class Trajectory(Protocol):
    """What an animation reads of a run (a :class:`cdpr_sym.results.Trajectory` has it all;
    named here so that the run, which animates itself, is not imported back)."""

    t: np.ndarray
    q: np.ndarray
    tau: np.ndarray
    q_goal: np.ndarray
    q_read: np.ndarray | None
    t_min: float
    t_max: float
    info: dict[str, Any]

#: The files an animation is written to, and what writes each.
ANIMATION_SUFFIXES = {".gif": "pillow", ".mp4": "ffmpeg", ".html": "html"}
#: Most frames an animation may have: a writer holds them all (a GIF of 1,000 frames took
#: 2 GB); a longer run asks for a lower ``fps`` or a higher ``speed``.
MAX_FRAMES = 600
#: MB of frames a JavaScript player may embed (matplotlib's own limit, 20 MB, cut the
#: default 10 s run at 6 s without an error); :data:`MAX_FRAMES` bounds what it holds.
EMBED_LIMIT_MB = 400.0


class RunAnimation(FuncAnimation):
    """A run's animation: a :class:`~matplotlib.animation.FuncAnimation` with one frame
    per sample index of :attr:`steps`, shown as JavaScript in a notebook."""

    def __init__(self, run: Trajectory, robot: Robot, *, fps: float, speed: float,
                 ax: Any = None) -> None:
        self.run, self.robot = run, robot
        self.steps = frame_steps(len(run.t), float(run.t[1] - run.t[0]) if len(run.t) > 1
                                 else 1.0, fps=fps, speed=speed)
        self.fps = fps
        own = ax is None
        ax = new_axes(robot) if own else ax
        if own:  # room under the axes for the legend
            ax.figure.subplots_adjust(bottom=0.16)
        self.picture = RobotPicture(robot, ax, tensions=True)
        self.picture.trace.set_label("path")
        if run.q_read is not None:
            self.picture.ghost.set_label("pose the controller read")
        self.picture.colour_bar()
        ax.scatter(*_reference(robot, run.q_goal)[:, None], marker="*", s=160,
                   color="tab:orange", label="goal")
        self.clock = ax.set_title("")
        legend(ax)
        super().__init__(ax.figure, self._frame, frames=list(self.steps),
                         interval=1000.0 / fps, blit=False, repeat=False)

    def _frame(self, step: int) -> list[Any]:
        run = self.run
        tensions = run.tau[min(step, len(run.tau) - 1)] if len(run.tau) else None
        read = run.q_read[step] if run.q_read is not None else None
        path = run.q[: step + 1]
        artists = self.picture.show(run.q[step], tensions, read=read, path=path)
        label = f"{run.info.get('robot', self.robot.name)} / {run.info.get('controller', '')}"
        self.clock.set_text(f"{label}: t = {run.t[step]:.2f} s")
        return [*artists, self.clock]

    def _repr_html_(self) -> str:
        """A notebook shows the animation as JavaScript whatever ``animation.html`` says,
        every frame embedded (:data:`EMBED_LIMIT_MB`)."""
        return self.javascript()

    def javascript(self, fps: float | None = None) -> str:
        """The JavaScript player of the animation (HTML), with every frame."""
        import matplotlib as mpl

        with mpl.rc_context({"animation.embed_limit": EMBED_LIMIT_MB}):
            return self.to_jshtml(fps=fps)

    def save(self, filename: str | Path, *args: Any, **kwargs: Any) -> None:  # type: ignore[override]
        """Write the animation to ``filename``: ``.gif`` (Pillow), ``.html`` (JavaScript)
        or ``.mp4`` (ffmpeg), at this animation's frame rate unless ``fps`` is given.

        Raises
        ------
        InvalidCase
            Field ``animate``: another suffix, or ``.mp4`` without ffmpeg.
        """
        if "writer" in kwargs:  # matplotlib's own calls (to_jshtml) name their writer
            super().save(filename, *args, **kwargs)
            return
        path = Path(filename)
        writer = animation_writer(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        if writer == "html":
            path.write_text(self.javascript(fps=kwargs.get("fps", self.fps)))
            return
        kwargs.setdefault("fps", self.fps)
        super().save(path, *args, writer=writer, **kwargs)


def animation_writer(path: Path, field: str = "animate") -> str:
    """The writer of an animation file (:data:`ANIMATION_SUFFIXES`), checked before any
    work: a suffix it cannot write, or ``.mp4`` without ffmpeg, is refused naming
    ``field``."""
    from matplotlib import animation

    suffix = Path(path).suffix.lower()
    writer = ANIMATION_SUFFIXES.get(suffix)
    if writer is None:
        raise InvalidCase(field, f"expected an animation file ({', '.join(ANIMATION_SUFFIXES)}), "
                          f"got {path}")
    if writer == "ffmpeg" and not animation.writers.is_available("ffmpeg"):
        raise InvalidCase(field, f"writing {suffix} needs ffmpeg on the PATH; install it or "
                          "write a .gif or .html (no extra software)")
    return writer


def frame_steps(samples: int, dt: float, *, fps: float, speed: float) -> np.ndarray:
    """The sample indices shown: every ``stride`` = max(1, round(speed / (fps dt))) of
    ``samples`` (run time ``speed`` times faster than the wall clock at ``fps`` frames per
    second), and the last one."""
    for field, value in (("fps", fps), ("speed", speed)):
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
            raise InvalidCase(field, f"expected a positive number, got {value!r}")
    stride = max(1, round(speed / (fps * dt)))
    steps = np.arange(0, samples, stride)
    if steps[-1] != samples - 1:
        steps = np.append(steps, samples - 1)
    if len(steps) > MAX_FRAMES:
        raise InvalidCase("fps", f"{len(steps)} frames ({samples * dt:.3g} s of run at {fps:g} "
                          f"frames per second, {speed:g} times real time); at most "
                          f"{MAX_FRAMES}: ask for a lower fps or a higher speed")
    return steps


def animate_run(run: Trajectory, robot: Robot | None = None, *, fps: float = 25.0,
                speed: float = 1.0, ax: Any = None) -> RunAnimation:
    """:meth:`Trajectory.animate <cdpr_sym.results.Trajectory.animate>`: ``run`` on
    ``robot`` (default: the preset the run names)."""
    robot = run_robot(run, robot)
    return RunAnimation(run, robot, fps=fps, speed=speed, ax=ax)


def run_robot(run: Trajectory, robot: Robot | None) -> Robot:
    """The robot a run is drawn on: ``robot``, else the preset its ``info`` names (with the
    run's own tension box); checked to have the run's coordinates and cables."""
    from cdpr_sym.robot import PRESET_NAMES, UNDERACTUATED_PRESETS, preset

    if robot is None:
        name = run.info.get("robot")
        if name not in PRESET_NAMES + UNDERACTUATED_PRESETS:
            raise InvalidCase("robot", f"this run's robot {name!r} is not a preset; pass the "
                              "Robot it ran on (animate(robot=...))")
        robot = preset(name)
        if (robot.t_min, robot.t_max) != (run.t_min, run.t_max):
            raise InvalidCase("robot", f"this run's tension box [{run.t_min:g}, {run.t_max:g}] "
                              f"N is not the preset {name}'s: pass the Robot it ran on "
                              "(animate(robot=...))")
    if robot.n != run.q.shape[1] or robot.m != run.tau.shape[1]:
        raise InvalidCase("robot", f"{robot.name} has n = {robot.n} and m = {robot.m}; the "
                          f"run has {run.q.shape[1]} coordinates and {run.tau.shape[1]} "
                          "cables")
    if (robot.t_min, robot.t_max) != (run.t_min, run.t_max):  # coloured against the run's box
        robot = robot.with_case(t_min=run.t_min, t_max=run.t_max)
    return robot


def _reference(robot: Robot, pose: np.ndarray) -> np.ndarray:
    """The reference point's position of ``pose``, shape (d,)."""
    return np.asarray(pose, dtype=float)[: robot.dimension]
