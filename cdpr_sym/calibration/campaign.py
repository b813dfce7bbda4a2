"""A calibration campaign: what was measured at each static pose, and how well.

Three kinds, told apart by what the table holds besides the encoder readings:

* ``tracker``: each pose measured in the world frame by an external instrument (a laser
  tracker or a camera system) of noise ``pose_noise``; every unknown is identifiable and the
  frame is the instrument's.
* ``self``: encoder readings alone (needs m > n: each pose adds n unknowns and m readings).
  A rigid motion of all anchors and poses together changes no reading (with stretch, the
  tilt changes only the modelled tensions, a weak effect); the frame is fixed by the nominal
  anchors: the calibrated anchors differ from them by no translation or rotation (the
  linearised inner constraints of :mod:`cdpr_sym.calibration.gauge`).
* ``load cells``: encoder readings and measured tensions, no poses: the statics
  W(q) T = grad V add n equations a pose. Gravity fixes the tilt, so the gauge is the
  translations and the rotation about the vertical.

The stretch of each cable needs its tension. Measured by load cells, the tension is an
unknown with its own noise. Otherwise the table may give the tensions the controller
commanded at each pose (``tension_source="commanded"``: taken as exact, the torque loop
delivering them at rest, friction neglected); a robot with as many cables as degrees of
freedom needs none (its tension is the statics' W^{-1} grad V, recomputed from the
estimate), while one with more cables must give them: at rest it holds any of many tension
sets, and the one a distribution rule would pick moves by hundreds of newtons for a
millimetre of geometry near the tension bounds.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from cdpr_sym.errors import InvalidCase

#: The campaign kinds (see the module notes).
KINDS = ("tracker", "self", "load cells")
#: Where a campaign's tensions come from.
TENSION_SOURCES = ("commanded", "load cells")


@dataclasses.dataclass(frozen=True)
class Noise:
    """Standard deviations of the measurements.

    Parameters
    ----------
    reading : float
        Encoder reading, m. Default: the 1e-5 m resolution of the as-built default encoder
        as a uniform rounding error, 1e-5 / sqrt(12) = 2.9e-6 m.
    position : float
        Tracker position, per coordinate, m. Default 1e-4 m (0.1 mm).
    angle : float
        Tracker orientation, per angle, rad. Default 1e-3 rad: the position noise over a
        0.1 m spread of targets on the platform (derived, not a datasheet value).
    tension : float
        Load cell, N. Default 0.5 N.
    """

    reading: float = 1e-5 / math.sqrt(12)
    position: float = 1e-4
    angle: float = 1e-3
    tension: float = 0.5

    def __post_init__(self) -> None:
        for field in ("reading", "position", "angle", "tension"):
            value = getattr(self, field)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise InvalidCase(f"noise.{field}", f"expected a positive standard deviation, "
                                  f"got {value!r}")


@dataclasses.dataclass(frozen=True)
class Campaign:
    """The measurements at N static poses.

    Parameters
    ----------
    readings : ndarray, shape (N, m)
        Encoder readings, m.
    poses : ndarray, shape (N, n), optional
        The tracker's poses in the world frame (m; rad for angles).
    tensions : ndarray, shape (N, m), optional
        Tensions at each pose, N: commanded or measured (``tension_source``). Without them
        (m = n only) the stretch uses the statics' tension, recomputed from the estimate.
    tension_source : str
        ``commanded`` (exact, for the stretch) or ``load cells`` (measured with
        ``noise.tension``; with no poses, the campaign is a ``load cells`` one).
    noise : Noise
    stiffness : float
        Axial cable stiffness EA, N, for the stretch; ``math.inf`` for rigid cables.
    """

    readings: np.ndarray
    poses: np.ndarray | None = None
    tensions: np.ndarray | None = None
    tension_source: str = "commanded"
    noise: Noise = Noise()
    stiffness: float = math.inf

    def __post_init__(self) -> None:
        readings = _table("readings", self.readings)
        object.__setattr__(self, "readings", readings)
        for field in ("poses", "tensions"):
            value = getattr(self, field)
            if value is not None:
                value = _table(field, value)
                if value.shape[0] != readings.shape[0]:
                    raise InvalidCase(field, f"expected {readings.shape[0]} rows (one per "
                                      f"pose), got {value.shape[0]}")
                object.__setattr__(self, field, value)
        if self.tensions is not None and self.tensions.shape[1] != readings.shape[1]:
            raise InvalidCase("tensions", f"expected {readings.shape[1]} columns (one per "
                              f"cable), got {self.tensions.shape[1]}")
        if self.tension_source not in TENSION_SOURCES:
            raise InvalidCase("tension_source", f"expected one of {TENSION_SOURCES}, got "
                              f"{self.tension_source!r}")
        if self.tension_source == "load cells" and self.tensions is None:
            raise InvalidCase("tensions", "a load-cell campaign needs the measured tensions")
        if self.tension_source == "load cells" and self.poses is not None:
            raise InvalidCase("load_cells", "a campaign with measured poses is a tracker "
                              "campaign, whose tensions count as commanded; load cells "
                              "calibrate without poses")
        if self.tensions is not None and (self.tensions < 0).any():
            row, cable = np.argwhere(self.tensions < 0)[0]
            raise InvalidCase("tensions", f"row {row + 1}: tension_{cable + 1} = "
                              f"{self.tensions[row, cable]:g} N; a cable only pulls (>= 0)")
        if not (isinstance(self.stiffness, (int, float)) and self.stiffness > 0):
            raise InvalidCase("stiffness", f"expected a positive EA in N (inf: rigid "
                              f"cables), got {self.stiffness!r}")

    @property
    def kind(self) -> str:
        """``tracker`` (poses measured), ``load cells`` (tensions, no poses) or ``self``."""
        if self.poses is not None:
            return "tracker"
        return "load cells" if self.tension_source == "load cells" else "self"

    @property
    def size(self) -> int:
        """Number of poses N."""
        return self.readings.shape[0]

    def check_robot(self, n: int, m: int) -> None:
        """Raise :class:`InvalidCase` unless the tables fit a robot with n degrees of
        freedom and m cables."""
        if self.readings.shape[1] != m:
            raise InvalidCase("readings", f"expected {m} columns (one per cable), got "
                              f"{self.readings.shape[1]}")
        if self.poses is not None and self.poses.shape[1] != n:
            raise InvalidCase("poses", f"expected {n} columns (one per coordinate), got "
                              f"{self.poses.shape[1]}")
        if self.kind == "self" and m <= n:
            raise InvalidCase("readings", f"encoder readings alone cannot calibrate a robot "
                              f"with as many cables as degrees of freedom (m = n = {n}: "
                              "every reading fits some pose); measure the poses or the "
                              "tensions too")
        if (m > n and self.tensions is None and math.isfinite(self.stiffness)):
            raise InvalidCase("tensions", f"a robot with more cables than degrees of freedom "
                              f"({m} > {n}) holds a pose with any of many tension sets; give "
                              "the tensions commanded at each pose (or rigid cables: "
                              "stiffness inf)")


def _table(field: str, value: object) -> np.ndarray:
    """A finite 2-D float array, read-only, or InvalidCase naming ``field``."""
    try:
        array = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise InvalidCase(field, "expected a table of numbers") from None
    if array.ndim != 2 or array.shape[0] == 0:
        raise InvalidCase(field, f"expected a (poses x columns) table, got shape {array.shape}")
    bad = np.argwhere(~np.isfinite(array))
    if bad.size:
        row, column = bad[0]
        raise InvalidCase(field, f"expected finite numbers, got {array[row, column]} in row "
                          f"{row + 1}, column {column + 1}")
    array.setflags(write=False)
    return array
