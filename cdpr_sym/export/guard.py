"""The guard of an encoder-level package: what it checks each sample, and its limits.

The exported ``<prefix>_sample`` (:mod:`cdpr_sym.export.encoder_package`) checks, in one
sample, everything the issue of hardware getting hurt lists, and on any failure writes a
defined safe command and latches a fault code until ``<prefix>_clear_fault``. The checks
and their codes (bits of the status, :data:`FAULTS`) are written in C in the package's
source (``templates/encoders/source.c.j2``); this module holds their names, their words and
the default limits, which the package compiles in and a caller may change at run time
(``<prefix>_limits``).

The safe command: the tension ramps linearly, over ``ramp_time``, from the last command
written with status 0 to the static tension at the last pose read with status 0 (m = n:
W^{-1} grad V; m > n: the default distribution of the weight; clipped to [T_min, T_max]);
the motor torque is what holds a drum at rest with that tension, r (T + T^2 / (2 EA)),
clipped to the torque limit. The ramp counts samples, not the caller's time, which may be
what failed.
"""

from __future__ import annotations

import dataclasses

from cdpr_sym.checks import positive_number
from cdpr_sym.errors import InvalidCase

#: Fault bits of the status, by name, with their words (the header's comments).
FAULTS: dict[str, tuple[int, str]] = {
    "deadline": (1 << 0, "the caller reported a missed deadline"),
    "time": (1 << 1, "the time is not finite, did not advance, or advanced more than "
                     "late_periods control periods"),
    "reading": (1 << 2, "a reading is NaN or infinite"),
    "range": (1 << 3, "a cable length read lies outside what the frame allows"),
    "pose": (1 << 4, "forward kinematics found no pose that explains the readings "
                     "(or, on the first sample, none from any seed)"),
    "jump": (1 << 5, "the pose read moved more than max_speed dt since the last sample"),
    "frame": (1 << 6, "the pose read left the frame shrunk by frame_margin"),
    "tension": (1 << 7, "a tension command is not finite or outside [t_min, t_max] (a cable "
                        "would go slack or be over-tensioned)"),
    "rate": (1 << 8, "a tension command changed by more than rate_limit dt in one sample"),
    "design": (1 << 9, "the design reported a singular structure matrix (a planned design: "
                       "or no admissible plan)"),
}
#: Status bits that are not faults.
NOT_ARMED = 1 << 15
#: Return value of a call given a NULL pointer or an argument out of its range.
INVALID_ARGUMENT = -1


@dataclasses.dataclass(frozen=True)
class GuardLimits:
    """The guard's limits, compiled into the package as the defaults of ``<prefix>_limits``.

    Parameters
    ----------
    max_speed : float
        Largest speed of any coordinate the pose may show between two samples, m/s (rad/s
        for angles): a larger jump of the pose read is a fault. Default 2.
    frame_margin : float
        m: the position coordinates read must stay this far inside the robot's frame box.
        Default 0.01 m.
    rate_limit : float or None
        Largest change of a tension command, N/s. None (default): (T_max - T_min) / 0.02 s,
        the whole box in twenty milliseconds.
    late_periods : float
        The time between two samples may exceed the control period by this factor at most.
        Default 1.5.
    ramp_time : float
        s: how long the safe command takes to ramp to the holding tension (0: at once).
        Default 0.2 s.
    """

    max_speed: float = 2.0
    frame_margin: float = 0.01
    rate_limit: float | None = None
    late_periods: float = 1.5
    ramp_time: float = 0.2

    def __post_init__(self) -> None:
        for field, unit, zero in (("max_speed", "m/s", False), ("frame_margin", "m", True),
                                  ("late_periods", "control periods", False),
                                  ("ramp_time", "s", True)):
            _check(field, getattr(self, field), unit, zero)
        if self.late_periods < 1:
            raise InvalidCase("late_periods", f"expected at least 1 control period, got "
                              f"{self.late_periods!r}")
        if self.rate_limit is not None:
            _check("rate_limit", self.rate_limit, "N/s", False)

    def rate(self, t_min: float, t_max: float) -> float:
        """The tension rate limit, N/s."""
        return (t_max - t_min) / 0.02 if self.rate_limit is None else float(self.rate_limit)


def _check(field: str, value: object, unit: str, zero: bool) -> None:
    positive_number(field, value, unit, zero=zero)
