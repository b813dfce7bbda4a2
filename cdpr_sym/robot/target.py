"""The design target a robot's runs are judged against: settled in time, smooth tension.

A run meets the target when it finishes, its (true) cable tensions stay in the box
[T_m, T_M] for t > 0, its error ||q - q_goal|| stays within ``error`` from ``settle_time``
on, and no change of the held tension command, the first one from the static tension
included (the start jump), is larger than ``step``, stated per :data:`STEP_PERIOD`.

The studies judged every robot by the paper's robot's numbers: within 1 cm by 5 s, steps of
at most 1 N. 1 N is 1.7 % of that robot's box [2, 60] N; on a robot whose box is
[10, 5000] N it is 0.02 %, a smoothness no actuator asks for. A robot leaves the target to
the rule of :meth:`Target.derived`,

    step = max(1 N, 1 % of (T_M - T_m)),   error = 1 cm,   settle_time = 5 s,

so a step limit proportional to the box asks the same relative smoothness of every robot,
and the 1 N floor keeps the old limit where 1 % of the box is smaller (the paper's robot,
1 % = 0.58 N, keeps 1 N and its results). A robot file may state its own in a ``[target]``
table (``settle_time`` s, ``error`` m, ``step`` N per 1 ms; any of them, the rest derived).

The step is a slew rate: ``step`` newtons per millisecond. At another control period dt a
change of the held command is judged against ``step * dt / 1 ms`` (:meth:`Target.step_limit`):
2 N per step at 500 Hz, 0.1 N at 10 kHz. So the limit is a property of the tension signal in
time, what the cable and its winch see, and does not tighten or loosen with the control rate;
at the toolkit's 1 kHz it is ``step`` itself.

The error is the norm of q - q_goal over every coordinate (m, and rad for a rigid body's
angles), the band :meth:`~cdpr_sym.results.Trajectory.settle_time` measures.
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from typing import Any

from cdpr_sym.errors import InvalidRobot

#: The period a target's ``step`` is stated per, s (1 ms: the toolkit's 1 kHz control).
STEP_PERIOD = 1e-3
#: The rule's floor on the step, N, and its share of the box width T_M - T_m, per cent.
STEP_FLOOR, STEP_PERCENT = 1.0, 1.0
#: The studies' settling time (s) and band (m), kept by the rule.
SETTLE_TIME, SETTLE_ERROR = 5.0, 0.01

#: The fields of a ``[target]`` table, in order, and their units.
TARGET_FIELDS = {"settle_time": "s", "error": "m", "step": "N per 1 ms"}


@dataclasses.dataclass(frozen=True)
class Target:
    """A design target: settled within ``error`` by ``settle_time``, steps of at most ``step``.

    Parameters
    ----------
    settle_time : float
        Time by which ||q - q_goal|| must have entered the band for good, s (> 0).
    error : float
        The settling band on ||q - q_goal||, m (rad for angles; > 0).
    step : float
        Largest change of the held tension command (and of the first command from the
        static tension) per :data:`STEP_PERIOD`, N (> 0); see :meth:`step_limit`.

    Raises
    ------
    InvalidRobot
        A field is not a finite number > 0; the field is named as in a robot file
        (``target.step``).

    Examples
    --------
    >>> Target.derived(10.0, 5000.0).step
    49.9
    >>> Target().describe()
    'within 1 cm of the goal by 5 s, tension steps ≤ 1 N per ms'
    """

    settle_time: float = SETTLE_TIME
    error: float = SETTLE_ERROR
    step: float = STEP_FLOOR

    def __post_init__(self) -> None:
        for name in TARGET_FIELDS:
            object.__setattr__(self, name, _positive(name, getattr(self, name)))

    @classmethod
    def derived(cls, t_min: float, t_max: float, **stated: float) -> Target:
        """The target of a robot with tension box [t_min, t_max] (N): the rule of the module
        notes, step = max(:data:`STEP_FLOOR`, :data:`STEP_PERCENT` % of (t_max - t_min)),
        with the ``stated`` fields (``settle_time``, ``error``, ``step``) in place of the
        rule's. (The width is divided by 100, not multiplied by 0.01: 710 N gives 7.1 N, not
        7.1000000000000005.)"""
        unknown = sorted(set(stated) - set(TARGET_FIELDS))
        if unknown:
            raise InvalidRobot(f"target.{unknown[0]}", "unknown field; expected one of "
                               f"{', '.join(TARGET_FIELDS)}")
        share = STEP_PERCENT * (t_max - t_min) / 100
        return cls(**{"step": max(STEP_FLOOR, share), **stated})

    def step_limit(self, dt: float) -> float:
        """The largest change of the command allowed per control step of ``dt`` s, N:
        ``step * dt / STEP_PERIOD`` (``step`` itself, bit for bit, at dt = 1 ms)."""
        return self.step * (dt / STEP_PERIOD)

    def as_dict(self) -> dict[str, float]:
        """The fields as a ``[target]`` table holds them (s, m, N per 1 ms)."""
        return dataclasses.asdict(self)

    def describe(self, dt: float = STEP_PERIOD) -> str:
        """One line naming the target, as rows and reports state what they judged:
        ``within 1 cm of the goal by 5 s, tension steps ≤ 1 N per ms`` (and, at a control
        period other than 1 ms, what that allows per step)."""
        text = (f"within {length_text(self.error)} of the goal by {self.settle_time:g} s, "
                f"tension steps ≤ {self.step:g} N per ms")
        if dt != STEP_PERIOD:
            text += f" ({self.step_limit(dt):.4g} N per {dt * 1e3:g} ms step)"
        return text


def length_text(metres: float) -> str:
    """A length for a sentence: ``1 cm``, ``5 mm``, ``1.5 cm``, ``2 m``."""
    if metres >= 1:
        return f"{metres:g} m"
    if metres >= 0.01:
        return f"{round(metres * 100, 9):g} cm"
    return f"{round(metres * 1000, 9):g} mm"


def _positive(name: str, value: Any) -> float:
    """``value`` as a finite float > 0, or a one-line refusal naming ``target.<name>``."""
    field = f"target.{name}"
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise InvalidRobot(field, f"expected a number ({TARGET_FIELDS[name]}), got "
                           f"{_shown(value)}")
    number = float(value) if abs(value) < 1e308 else math.inf
    if not math.isfinite(number) or number <= 0:
        raise InvalidRobot(field, f"expected a finite number > 0 ({TARGET_FIELDS[name]}), "
                           f"got {value!r}")
    return number


def _shown(value: Any, limit: int = 60) -> str:
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."
