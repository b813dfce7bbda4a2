"""A distribution of robots as built, from which each start/goal pair draws its own.

:class:`AsBuiltDraw` states how far the robot as built may differ from its model: a mass
error and anchor errors drawn uniformly per pair, and the winches, encoders and delay every
draw shares. :data:`DEFAULT_DRAW` is the robustness study's combined "as built"
specification; a TOML file (:func:`load_as_built_draw`) states another:

.. code-block:: toml

    mass_error = 0.10      # plant mass uniform in model mass x [0.9, 1.1]
    anchor_error = 0.005   # each anchor coordinate uniform in +-5 mm
    delay = 1              # control periods
    substeps = 2           # leave out: the fewest the robot's winches need (substeps_for)
    torque_margin = 1.5    # winch torque limit r T_max x 1.5 (when [actuation] gives none)

    [actuation]            # the fields of Actuation; leave the table out for rigid cables
    cable_damping = 4.0    # a field left out is scaled from the robot (as_built.hardware)

    [sensing]              # the fields of Sensing; leave it out for exact state feedback
    resolution = 1e-5      # likewise

The hardware a draw does not state is a plausible build of the robot it draws for
(:mod:`cdpr_sym.as_built.hardware`: the cable, drum, winch inertia, friction and encoder
scaled from the tension box): :class:`FromRobot` holds the fields stated, and
:meth:`AsBuiltDraw.drive` and :meth:`AsBuiltDraw.encoders` give the winches and encoders of a
given robot. :data:`DEFAULT_DRAW` states none.

A draw is (mass scale, :class:`AsBuilt`); pair p of a sweep or study with seed s draws from
``numpy.random.default_rng([s, p, crc32("as built")])``, mass first, then the offsets (m, d)
row by row.
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
import zlib
from pathlib import Path
from typing import Any

import numpy as np

from cdpr_sym.as_built.spec import MAX_DELAY, Actuation, AsBuilt, Sensing
from cdpr_sym.errors import InvalidCase
from cdpr_sym.robot import Robot, robot_key

#: The tag that seeds the "as built" draws apart from other draws of the same pair.
DRAW_TAG = zlib.crc32(b"as built")
#: Largest as-built file read, bytes.
MAX_FILE_BYTES = 1 << 16


@dataclasses.dataclass(frozen=True)
class FromRobot:
    """Hardware scaled from the robot (:mod:`cdpr_sym.as_built.hardware`) but the fields
    stated: ``fields`` is a sorted tuple of (name, value) pairs of :class:`Actuation` or
    :class:`Sensing`."""

    fields: tuple[tuple[str, Any], ...] = ()
    #: Written in a file (a table, however few its fields), not the default's; equal
    #: hardware compares equal whichever way it was given.
    stated: bool = dataclasses.field(default=False, compare=False)

    def actuation(self, robot: Robot) -> Actuation:
        from cdpr_sym.as_built.hardware import scaled_actuation

        return _replaced("actuation", scaled_actuation(robot), self.fields)

    def sensing(self, robot: Robot, actuation: Actuation | None) -> Sensing:
        from cdpr_sym.as_built.hardware import scaled_sensing

        return _replaced("sensing", scaled_sensing(robot, actuation), self.fields)

    def as_dict(self) -> dict[str, Any]:
        return {"from_robot": True, **({"stated": True} if self.stated else {}),
                **dict(self.fields)}


def _replaced(table: str, base: Any, fields: tuple[tuple[str, Any], ...]) -> Any:
    try:
        return dataclasses.replace(base, **dict(fields))
    except InvalidCase as wrong:
        raise InvalidCase(f"{table}.{wrong.field}", wrong.message) from None


@dataclasses.dataclass(frozen=True)
class AsBuiltDraw:
    """How a robot as built differs from its model, per pair.

    Parameters
    ----------
    mass_error : float
        Largest relative mass error: the plant's mass is uniform in the model's times
        [1 - e, 1 + e]. Default 0.10.
    anchor_error : float
        Largest anchor error per coordinate, m, uniform. Default 0.005 m.
    actuation : Actuation, FromRobot or None
        Winches (None: rigid cables). Default :class:`FromRobot`: scaled from each robot
        (:mod:`cdpr_sym.as_built.hardware`), with the torque limit set from
        ``torque_margin``.
    sensing : Sensing, FromRobot or None
        Encoders (None: exact state). Default :class:`FromRobot`.
    delay : int
        Command delay, control periods. Default 1.
    substeps : int or None
        RK4 steps per control period. None (default): from the robot
        (:func:`substeps_for`: the fewest, at least 2, that follow its winches at 1 kHz).
    torque_margin : float
        Where ``actuation`` has no torque limit: r T_max times this. Default 1.5.
    """

    mass_error: float = 0.10
    anchor_error: float = 0.005
    actuation: Actuation | FromRobot | None = dataclasses.field(default_factory=FromRobot)
    sensing: Sensing | FromRobot | None = dataclasses.field(default_factory=FromRobot)
    delay: int = 1
    substeps: int | None = None
    torque_margin: float = 1.5

    def __post_init__(self) -> None:
        for field, top in (("mass_error", 0.9), ("anchor_error", 0.1)):
            value = getattr(self, field)
            if not (isinstance(value, (int, float)) and not isinstance(value, bool)
                    and 0 <= value <= top):
                raise InvalidCase(field, f"expected a number in 0..{top:g}, got {value!r}")
        if not (isinstance(self.torque_margin, (int, float)) and self.torque_margin > 0
                and math.isfinite(self.torque_margin)):
            raise InvalidCase("torque_margin", f"expected a positive factor, got "
                              f"{self.torque_margin!r}")
        AsBuilt(delay=self.delay,  # checks both
                substeps=FEWEST_SUBSTEPS if self.substeps is None else self.substeps)

    def drive(self, robot: Robot) -> Actuation | None:
        """The winches of ``robot``'s draws (scaled from it where the draw states none): a
        torque limit of r T_max x margin unless set."""
        actuation = self.actuation
        if isinstance(actuation, FromRobot):
            actuation = actuation.actuation(robot)
        if actuation is None or actuation.torque_limit is not None:
            return actuation
        limit = self.torque_margin * robot.t_max * actuation.drum_radius
        return dataclasses.replace(actuation, torque_limit=limit)

    def encoders(self, robot: Robot) -> Sensing | None:
        """The encoders of ``robot``'s draws (scaled from its winches where the draw states
        none). A robot with fewer cables than coordinates gets none unless a file states
        them: its m encoder lengths cannot give its n coordinates, so its build is taken to
        sense its pose directly (a camera or motion capture, modelled as exact)."""
        if isinstance(self.sensing, FromRobot):
            if robot.underactuated and not self.sensing.stated:
                return None
            return self.sensing.sensing(robot, self.drive(robot))
        return self.sensing

    def draw(self, rng: np.random.Generator, robot: Robot) -> tuple[float, AsBuilt]:
        """One robot as built: (mass scale, :class:`AsBuilt`)."""
        check_modelled(robot, self)
        mass_scale = float(rng.uniform(1 - self.mass_error, 1 + self.mass_error))
        offsets = rng.uniform(-self.anchor_error, self.anchor_error, (robot.m, robot.dimension))
        drive = self.drive(robot)
        substeps = self.substeps if self.substeps is not None else substeps_for(robot, drive)
        return mass_scale, AsBuilt(actuation=drive, sensing=self.encoders(robot),
                                   delay=self.delay, anchor_offsets=offsets,
                                   substeps=substeps)

    def draw_pair(self, robot: Robot, seed: int, pair: int) -> tuple[float, AsBuilt]:
        """Pair ``pair``'s draw of a sweep or study seeded ``seed``."""
        return self.draw(np.random.default_rng([seed, pair, DRAW_TAG]), robot)

    def as_dict(self) -> dict[str, Any]:
        """Plain numbers (an unlimited torque as None), for a record."""
        return {"mass_error": self.mass_error, "anchor_error": self.anchor_error,
                "actuation": _record(self.actuation), "sensing": _record(self.sensing),
                "delay": self.delay, "substeps": self.substeps,
                "torque_margin": self.torque_margin}


#: The control period (s) :func:`substeps_for` sizes the substeps for: the toolkit's 1 kHz
#: (a draw does not know the period of the runs it serves; a run at another period is
#: checked again and refused in one line where the substeps do not suffice).
SUBSTEP_PERIOD = 1e-3
#: Substeps at least: the count the as-built plant was first checked with (the presets need
#: no more).
FEWEST_SUBSTEPS = 2
#: Poses of the static workspace, besides the robot's start and goal, at which the fastest
#: rate is taken, and the headroom over the largest found (a run's poses are others).
RATE_POSES, RATE_HEADROOM = 32, 1.25
#: The share of the frame's size left out on each side where those poses are drawn (the
#: sweeps' pair draw keeps the same margin).
FRAME_MARGIN = 0.05


def check_modelled(robot: Robot, draw: AsBuiltDraw | None = None) -> None:
    """Refuse, naming ``sensing``, a build that cannot be modelled: encoders on a robot
    with fewer cables than degrees of freedom (its m encoder lengths cannot give its n
    coordinates; the default build of such a robot senses its pose instead)."""
    if robot.underactuated and draw is not None and draw.encoders(robot) is not None:
        raise InvalidCase("sensing", f"{robot.name} has fewer cables than degrees of freedom "
                          f"(m = {robot.m} < n = {robot.n}): its m encoder lengths cannot "
                          "give its n coordinates; leave [sensing] out (the pose is then "
                          "sensed directly, as by a camera)")


def substeps_for(robot: Robot, actuation: Actuation | None) -> int:
    """The fewest RK4 substeps per 1 ms period (at least :data:`FEWEST_SUBSTEPS`) with
    which the taut cables and drums of ``robot`` on ``actuation`` stay inside RK4's
    stability region: rho h <= TORQUE_LOOP_STEP_LIMIT with rho the fastest rate
    (:func:`cdpr_sym.as_built.stability.fastest_rate`) at the robot's start and goal and at
    :data:`RATE_POSES` poses of its static workspace (seeded), times :data:`RATE_HEADROOM`.
    A 0.27 kg robot on its scaled winches (drums of 16 g at the cable) moves at up to
    5,700 1/s and needs 3; with a fixed 2, 3 of its 40 pairs were refused. None (rigid
    cables): the fewest."""
    if actuation is None:
        return FEWEST_SUBSTEPS
    key = (robot_key(robot), actuation)
    if key not in _SUBSTEPS:
        _SUBSTEPS[key] = _substeps_for(robot, actuation)
    return _SUBSTEPS[key]


_SUBSTEPS: dict[tuple[str, Actuation], int] = {}


def _substeps_for(robot: Robot, actuation: Actuation) -> int:
    from cdpr_sym.as_built.spec import SUBSTEP_RANGE, TORQUE_LOOP_STEP_LIMIT
    from cdpr_sym.as_built.stability import fastest_rates
    from cdpr_sym.model import SymbolicModel

    model = SymbolicModel(robot)
    poses = [robot.start, robot.goal, *_held_poses(robot, model)]
    rate = float(fastest_rates(model, actuation, np.array(poses, dtype=float)).max())
    needed = RATE_HEADROOM * rate * SUBSTEP_PERIOD / TORQUE_LOOP_STEP_LIMIT
    if not math.isfinite(needed):
        return FEWEST_SUBSTEPS  # the run's own check names the implausible number
    return int(min(max(FEWEST_SUBSTEPS, math.ceil(needed)), SUBSTEP_RANGE[1]))


def _held_poses(robot: Robot, model: Any) -> np.ndarray:
    """Up to :data:`RATE_POSES` poses of the frame shrunk by :data:`FRAME_MARGIN` of its
    size on each side (uniform, seeded) that the model holds at rest with tensions in the
    box: where runs start and end (sweeps draw their pairs there); for fewer cables than
    coordinates, admissible equilibria (seeded)."""
    rng = np.random.default_rng(0)
    if robot.underactuated:  # at rest only on its equilibrium manifold
        from cdpr_sym.underactuated import EquilibriumManifold

        return EquilibriumManifold(robot, model).sample(RATE_POSES, rng, partial=True)
    lower = np.asarray(robot.frame_lower, dtype=float)
    upper = np.asarray(robot.frame_upper, dtype=float)
    inset = FRAME_MARGIN * (upper - lower)
    lower, upper = lower + inset, upper - inset
    tries = rng.uniform(lower, upper, (20 * RATE_POSES, robot.n))
    held = np.array(model.static_distribution_function.map(len(tries))(tries.T)[1]).ravel()
    return tries[held > 0.5][:RATE_POSES]


def _record(part: Any) -> dict[str, Any] | None:
    if part is None:
        return None
    return part.as_dict() if isinstance(part, FromRobot) else dataclasses.asdict(part)


#: The robustness study's combined "as built" specification.
DEFAULT_DRAW = AsBuiltDraw()

_TOP_FIELDS = {"mass_error", "anchor_error", "delay", "substeps", "torque_margin",
               "actuation", "sensing"}


def as_built_draw_from_dict(data: dict[str, Any], source: str = "<dict>") -> AsBuiltDraw:
    """An :class:`AsBuiltDraw` from the file layout (see the module notes); unknown or
    misspelt fields are refused naming them."""
    unknown = sorted(set(data) - _TOP_FIELDS)
    if unknown:
        raise InvalidCase(unknown[0], f"unknown field in {source}; expected one of "
                          f"{', '.join(sorted(_TOP_FIELDS))}")
    parts: dict[str, Any] = {key: value for key, value in data.items()
                             if key not in ("actuation", "sensing")}
    for table, kind in (("actuation", Actuation), ("sensing", Sensing)):
        if table not in data:
            parts[table] = None
            continue
        fields = data[table]
        if not isinstance(fields, dict):
            raise InvalidCase(table, f"expected a table in {source}")
        known = {f.name for f in dataclasses.fields(kind)}
        bad = sorted(set(fields) - known)
        if bad:
            raise InvalidCase(f"{table}.{bad[0]}", f"unknown field in {source}; expected one "
                              f"of {', '.join(sorted(known))}")
        try:
            kind(**fields)  # each stated value checked now, the rest scaled per robot
        except InvalidCase as wrong:
            raise InvalidCase(f"{table}.{wrong.field}", wrong.message) from None
        except TypeError as wrong:
            raise InvalidCase(table, f"{wrong} in {source}") from None
        parts[table] = FromRobot(tuple(sorted(fields.items())), stated=True)
    if not isinstance(parts.get("delay", 1), int) or parts.get("delay", 1) > MAX_DELAY:
        raise InvalidCase("delay", f"expected a whole number of periods in 0..{MAX_DELAY}")
    return AsBuiltDraw(**parts)


def load_as_built_draw(name_or_path: str | Path) -> AsBuiltDraw:
    """``default`` (:data:`DEFAULT_DRAW`) or an as-built TOML file."""
    if str(name_or_path) == "default":
        return DEFAULT_DRAW
    path = Path(name_or_path)
    if not path.is_file():
        raise InvalidCase("as_built", f"expected 'default' or an as-built TOML file; no file "
                          f"at {path}")
    if path.stat().st_size > MAX_FILE_BYTES:
        raise InvalidCase("as_built", f"{path} is larger than {MAX_FILE_BYTES >> 10} KiB")
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise InvalidCase("as_built", f"{path} is not a UTF-8 text file") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as bad:
        raise InvalidCase("as_built", f"{path} is not valid TOML: {bad}") from None
    return as_built_draw_from_dict(data, str(path))
