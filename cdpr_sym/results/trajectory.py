"""Closed-loop trajectories and their metrics."""

from __future__ import annotations

import dataclasses
import html
import json
import math
import os
import stat
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from cdpr_sym.control.flags import FALLBACK_FLAGS, FLAG_NAMES
from cdpr_sym.errors import InvalidCase
from cdpr_sym.results.store import load_arrays, save_arrays
from cdpr_sym.results.summary import SETTLE_TOLERANCE, RunSummary, errors, squared_errors

if TYPE_CHECKING:
    from matplotlib.figure import Figure

_ARRAYS = ("t", "q", "dq", "tau", "alpha", "beta", "j", "flags", "q_goal")


@dataclasses.dataclass(frozen=True, repr=False)
class Trajectory:
    """A simulated closed-loop run.

    Attributes
    ----------
    t : ndarray, shape (N + 1,)
        Sample times, s. Row k of ``q``/``dq`` is the state at t[k]; row k of the per-step
        arrays is the command computed at t[k] and held until t[k + 1].
    q, dq : ndarray, shape (N + 1, n)
        Position (m) and velocity (m/s).
    tau : ndarray, shape (N, m)
        Commanded tension of the m cables, N (the plant may apply it clipped, see ``Plant.slack``).
    alpha, beta : ndarray, shape (N,)
        Scale on the PD part (24) and margin beta of (20), N.
    j : ndarray, shape (N, n(n-1)/2)
        Free entries of J_d.
    flags : ndarray of int, shape (N,)
        Bit set of ``cdpr_sym.control.flags.FLAG_*`` per step.
    q_goal : ndarray, shape (n,)
        Goal, m.
    t_min, t_max : float
        Tension bounds, N.
    stop_reason : str or None
        Why the run ended before its duration (``"singular"``, ``"non_finite"``,
        ``"left_frame"``), or None when it ran to the end.
    info : dict
        Robot, controller, options and integrator, for the record.
    memory : ndarray, shape (N + 1, m)
        The controller's internal state at each sample (m = 0 for memoryless controllers).
    static_tension : ndarray, shape (m,), optional
        The tension holding the robot at rest at the start, N: W^{-1} grad V (m > n: its
        distribution), or the controller's own holding tension where it keeps one
        (:func:`~cdpr_sym.control.interface.holding_tension`).
    command : ndarray, shape (N, m), optional
        Runs on an as-built plant: the controller's tension command, N. ``tau`` is then the
        true tension in the cables at t[k], on which the run is judged.
    q_read : ndarray, shape (N + 1, n), optional
        Runs on an as-built plant whose controller reads the pose from the encoders: the
        pose it read at t[k] (m; rad), beside the true pose ``q``. None for a controller
        that reads the drives (it reads no pose).
    """

    t: np.ndarray
    q: np.ndarray
    dq: np.ndarray
    tau: np.ndarray
    alpha: np.ndarray
    beta: np.ndarray
    j: np.ndarray
    flags: np.ndarray
    q_goal: np.ndarray
    t_min: float
    t_max: float
    stop_reason: str | None = None
    info: dict[str, Any] = dataclasses.field(default_factory=dict)
    memory: np.ndarray | None = None
    static_tension: np.ndarray | None = None
    command: np.ndarray | None = None
    q_read: np.ndarray | None = None

    def __repr__(self) -> str:
        robot, controller = self.info.get("robot", "?"), self.info.get("controller", "?")
        end = f", stopped: {self.stop_reason}" if self.stop_reason else ""
        return (f"<Trajectory {robot} / {controller}: {len(self.t) - 1} steps, "
                f"{self.t[-1] - self.t[0]:.3f} s, n = {self.q.shape[1]}{end}>")

    def _repr_html_(self) -> str:
        """A notebook's view: the run and its main metrics as a small table."""
        m = self.metrics()
        rows = [("tension for t > 0 [N]", f"{_text(m['min_tension'])} .. "
                 f"{_text(m['max_tension'])} (box {self.t_min:g} .. {self.t_max:g})"),
                ("tension feasible", str(m["tension_feasible"])),
                ("settle time [s]", _text(m["settle_time"], "never")),
                ("final error", _text(m["final_error"])),
                ("largest step [N]", _text(m["max_tension_step"])),
                ("stop reason", m["stop_reason"] or "–")]
        cells = "".join(f"<tr><td>{key}</td><td>{value}</td></tr>" for key, value in rows)
        return (f"<p><code>{html.escape(repr(self))}</code></p>"
                f"<table>{cells}</table>")

    def plot(self, *, alpha: bool = False, title: str | None = None,
             ax: Any = None) -> Figure:
        """Positions and tensions against time (and alpha, log scale, if ``alpha``), with
        the goal (dashed) and the tension bounds (dotted) drawn and labelled, units on the
        axes.

        Parameters
        ----------
        alpha : bool
            Add a panel of the paper's alpha (log scale).
        title : str, optional
            Default "robot / controller".
        ax : matplotlib Axes or sequence of Axes, optional
            Draw into these: one Axes gets the tensions alone (to compare runs on one
            plot), else one per panel (positions, tensions, alpha). Default: a new figure
            made through ``matplotlib.pyplot``, so a notebook shows it inline and
            ``plt.show()`` displays it (the backend is not changed).

        Returns
        -------
        matplotlib.figure.Figure
            The figure drawn on (``fig.savefig(path)`` writes it).
        """
        from cdpr_sym.results.figures import run_figure  # matplotlib: 0.3 s, plots only

        if title is None:
            title = f"{self.info.get('robot', '')} / {self.info.get('controller', '')}"
        try:
            return run_figure(self, title=title, alpha=alpha, axes=ax, pyplot=True)
        except ValueError as wrong:
            raise InvalidCase("ax", str(wrong).removeprefix("axes: ")) from None

    def animate(self, robot: Any = None, *, fps: float = 25.0, speed: float = 1.0,
                ax: Any = None) -> Any:
        """The run animated on its robot: the end-effector moving, each cable coloured by
        its tension against the box (red and dashed outside it), the path and the goal, and
        for an as-built run that reads the pose, a ghost where the controller read it
        (:mod:`cdpr_sym.results.animation`).

        Parameters
        ----------
        robot : Robot, optional
            The robot the run is drawn on; default the preset the run names.
        fps : float
            Frames per second of the animation.
        speed : float
            Run seconds per wall-clock second: one frame every round(speed / (fps dt))
            samples, and the last.
        ax : matplotlib Axes, optional
            Draw here (2-D axes for a planar robot, 3-D otherwise); default new ones.

        Returns
        -------
        cdpr_sym.results.animation.RunAnimation
            A matplotlib animation: a notebook shows it; ``.save("run.gif")`` writes it
            (``.gif``, ``.html``; ``.mp4`` with ffmpeg).
        """
        from cdpr_sym.results.animation import animate_run  # matplotlib: pictures only

        return animate_run(self, robot, fps=fps, speed=speed, ax=ax)

    def to_pandas(self) -> Any:
        """One row per sample: t, q_*, dq_* and the command held from that sample
        (tau_*, alpha, beta, j_*, flags; the last sample has none, NaN). Needs pandas
        (``pip install 'cdpr_sym[pandas]'``)."""
        try:
            import pandas as pd
        except ImportError:
            raise InvalidCase("pandas", "to_pandas needs pandas; pip install "
                              "'cdpr_sym[pandas]'") from None
        names = self.info.get("coordinates") or [f"q{i + 1}" for i in range(self.q.shape[1])]
        columns: dict[str, np.ndarray] = {"t": self.t}
        columns.update({f"q_{name}": self.q[:, i] for i, name in enumerate(names)})
        columns.update({f"dq_{name}": self.dq[:, i] for i, name in enumerate(names)})

        def held(values: np.ndarray) -> np.ndarray:
            return np.concatenate([values.astype(float), np.full((1, *values.shape[1:]),
                                                                 np.nan)])
        tau, j = held(self.tau), held(self.j)
        columns.update({f"tau_{i + 1}": tau[:, i] for i in range(tau.shape[1])})
        columns.update({"alpha": held(self.alpha), "beta": held(self.beta)})
        columns.update({f"j_{i + 1}": j[:, i] for i in range(j.shape[1])})
        columns["flags"] = pd.array(np.concatenate([self.flags, [0]]), dtype="Int64")
        frame = pd.DataFrame(columns)
        frame.loc[len(frame) - 1, "flags"] = pd.NA
        return frame

    @property
    def error(self) -> np.ndarray:
        """||q(t) - q_goal||, m, shape (N + 1,)."""
        return errors(self.q - self.q_goal)

    def settle_time(self, tolerance: float = SETTLE_TOLERANCE) -> float | None:
        """First time after which the error stays within ``tolerance`` (m), or None."""
        if self.stop_reason is not None:
            return None
        # compared squared, summed in the order the compiled summary sums (no square root
        # per sample)
        outside = np.flatnonzero(squared_errors(self.q - self.q_goal) > tolerance * tolerance)
        if outside.size == 0:
            return float(self.t[0])
        if outside[-1] == len(self.t) - 1:
            return None
        return float(self.t[outside[-1] + 1])

    def flag_share(self, mask: int) -> float:
        """Share of control steps with any of the bits in ``mask`` set."""
        return float(np.mean((self.flags & mask) != 0)) if len(self.flags) else 0.0

    def flag_counts(self) -> dict[str, int]:
        """Number of control steps per flag name."""
        return {name: int(np.count_nonzero(self.flags & bit)) for bit, name in FLAG_NAMES.items()}

    def metrics(self, *, static_tension: np.ndarray | None = None,
                settle_band: float = SETTLE_TOLERANCE) -> dict[str, Any]:
        """Summary numbers (SI units); tensions are judged over t > 0 (steps k >= 1).

        ``tension_feasible`` is False for a run that stopped early or has no command after
        t = 0 (nothing certifies the remainder); ``min_tension``/``max_tension`` still
        cover the simulated part.

        ``max_tension_step`` and ``tension_total_variation`` cover every change of command,
        |tau_k - tau_{k-1}| for k >= 1 (the first change happens at t = dt > 0).
        ``start_jump`` (N), max_i |tau_0 - tau_static|, uses ``static_tension`` (the
        argument, else the trajectory's own) and is left out when neither is known.
        ``settle_time`` is measured in the band ``settle_band`` (m; the robot's target's
        ``error`` where the run is judged against it).
        """
        return self.summary(static_tension=static_tension, settle_band=settle_band).metrics()

    def summary(self, *, static_tension: np.ndarray | None = None,
                settle_band: float = SETTLE_TOLERANCE) -> RunSummary:
        """The running extremes and counts :meth:`metrics` is made of (see
        :class:`~cdpr_sym.results.summary.RunSummary`), the settle time in ``settle_band``
        (m)."""
        if static_tension is None:
            static_tension = self.static_tension
        after_start = self.tau[1:]
        steps = np.abs(np.diff(self.tau, axis=0))
        return RunSummary(
            commands=len(self.tau),
            min_tension=float(after_start.min()) if after_start.size else math.nan,
            max_tension=float(after_start.max()) if after_start.size else math.nan,
            min_alpha=float(self.alpha.min()) if self.alpha.size else math.nan,
            settle_time=self.settle_time(settle_band),
            final_error=float(errors(self.q[-1] - self.q_goal)),
            # summed in step order, cable by cable, as the compiled summary sums: the same
            # number both ways (numpy's sum is pairwise)
            total_variation=float(np.add.accumulate(steps.ravel())[-1]) if steps.size else 0.0,
            max_step=float(steps.max()) if steps.size else 0.0,
            flag_counts=self.flag_counts(),
            fallback_steps=int(np.count_nonzero(self.flags & FALLBACK_FLAGS)),
            stop_reason=self.stop_reason,
            duration=float(self.t[-1] - self.t[0]),
            start_jump=(float(np.max(np.abs(self.tau[0] - static_tension)))
                        if static_tension is not None and len(self.tau) else None),
            t_min=self.t_min, t_max=self.t_max)

    def save(self, path: str | Path) -> Path:
        """Write the run to an ``.npz`` file that ``numpy.load`` reads directly (``.npz`` is
        appended to a path without it, see :func:`save_path`); :meth:`load` reads it back.
        Returns the path written.

        Raises
        ------
        InvalidCase
            Field ``path``: the target is refused by :func:`save_path` (nothing written).
        OSError
            The write failed (a full disk); its ``filename`` is the path, and a partly
            written regular file is removed.
        """
        target = save_path(path)
        try:
            return save_arrays(target, self._stored())
        except OSError as failure:
            _remove_partial(target)
            if failure.filename is None:
                raise OSError(failure.errno, failure.strerror or str(failure), str(target)
                              ) from None
            raise

    def _stored(self) -> dict[str, Any]:
        """The arrays and metadata :meth:`save` writes."""
        cables = self.tau.shape[1]
        return {
            **{name: getattr(self, name) for name in _ARRAYS},
            "memory": self.memory if self.memory is not None else np.zeros((len(self.t), 0)),
            "static_tension": (self.static_tension if self.static_tension is not None
                               else np.full(cables, np.nan)),
            "t_min": self.t_min, "t_max": self.t_max,
            "stop_reason": self.stop_reason or "", "info": self.info,
            **({} if self.command is None else {"command": self.command}),
            **({} if self.q_read is None else {"q_read": self.q_read})}

    @classmethod
    def load(cls, path: str | Path) -> Trajectory:
        """A run written by :meth:`save`.

        Raises
        ------
        InvalidCase
            The file is missing or is not a stored trajectory.
        """
        data = load_arrays(path)
        missing = [name for name in (*_ARRAYS, "t_min", "t_max", "info") if name not in data]
        if missing:
            raise InvalidCase("path", f"{path} is not a stored trajectory (no {missing[0]})")
        static = data.get("static_tension", np.full(data["tau"].shape[1], np.nan))
        return cls(**{name: data[name] for name in _ARRAYS},
                   t_min=float(data["t_min"]), t_max=float(data["t_max"]),
                   stop_reason=str(data.get("stop_reason", "")) or None,
                   info=json.loads(str(data["info"])), memory=data.get("memory"),
                   static_tension=None if np.isnan(static).all() else static,
                   command=data.get("command"), q_read=data.get("q_read"))


def save_path(path: str | Path, *, field: str = "path") -> Path:
    """The file :meth:`Trajectory.save` writes for ``path``, checked before any work.

    The name gets ``.npz`` unless it ends so already (``run`` -> ``run.npz``). Refused,
    naming ``field``: an empty name, a folder, an existing device or FIFO given without
    ``.npz`` (the run would land beside it), a folder that does not exist or cannot be
    written in, and an existing file that cannot be written.

    Raises
    ------
    InvalidCase
        Named ``field``; nothing is written.
    """
    given = Path(path)
    if not given.name or given.is_dir():
        raise InvalidCase(field, f"expected a file name ending .npz, got the folder {given}")
    target = given if given.suffix == ".npz" else given.with_name(given.name + ".npz")
    if target != given and given.exists() and not given.is_file():
        raise InvalidCase(field, f"{given} is not a regular file (a device or FIFO); a "
                          f"trajectory is an .npz file and would go to {target}: give a "
                          "file name ending .npz")
    if target.is_dir():
        raise InvalidCase(field, f"expected a file, got the folder {target}")
    folder = target.parent
    if not folder.is_dir():
        raise InvalidCase(field, f"no folder {folder} to write the trajectory in")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise InvalidCase(field, f"no permission to write in the folder {folder}")
    if target.exists() and not os.access(target, os.W_OK):
        raise InvalidCase(field, f"no permission to overwrite {target}")
    return target


def _remove_partial(target: Path) -> None:
    """Delete a regular file left torn by a failed write (never a device or a link)."""
    try:
        if stat.S_ISREG(os.lstat(target).st_mode):
            target.unlink()
    except OSError:
        pass


def _text(value: float | None, missing: str = "–") -> str:
    return missing if value is None else f"{value:.4g}"

