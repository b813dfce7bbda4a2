"""The declared layout of the closed-loop step: its state x, parameters p and log.

One :class:`StepLayout` describes the vectors that the generated step reads and writes; the
step, the simulator, the C rollout and the exported header all take their offsets from it,
so the layout is written down once::

    x   = [q (n), dq (n), memory, applied (m, rate-limited plants only), plant, status (1)]
    p   = [q_goal (n), k (n), r_d (n), dt, mass_scale, slack, rate_limit (rate-limited only),
           plant]
    log = [tau (m), alpha, beta, j (n(n-1)/2), flags, plant]

for n degrees of freedom and m >= n cables; the ``plant`` fields are those an as-built plant
adds (:mod:`cdpr_sym.closed_loop.effects`), none for the ideal plant.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Mapping

import casadi as ca
import numpy as np


@dataclasses.dataclass(frozen=True)
class Fields:
    """Named, contiguous fields of one flat vector, in order: ((name, size), ...)."""

    fields: tuple[tuple[str, int], ...]

    @functools.cached_property
    def size(self) -> int:
        """Total length of the vector."""
        return sum(size for _, size in self.fields)

    @functools.cached_property
    def names(self) -> tuple[str, ...]:
        return tuple(name for name, _ in self.fields)

    @functools.cached_property
    def _slices(self) -> dict[str, slice]:
        slices, start = {}, 0
        for name, size in self.fields:
            slices[name] = slice(start, start + size)
            start += size
        return slices

    def offset(self, name: str) -> int:
        """Index of the first entry of field ``name``."""
        return self.slice(name).start

    def width(self, name: str) -> int:
        """Number of entries of field ``name``."""
        return dict(self.fields)[name]

    def slice(self, name: str) -> slice:
        """The entries of field ``name``."""
        try:
            return self._slices[name]
        except KeyError:
            raise KeyError(f"no field {name!r} in {self.names}") from None

    def offsets(self) -> dict[str, int]:
        """Every field's offset, in order."""
        return {name: part.start for name, part in self._slices.items()}

    def split(self, vector: ca.SX | np.ndarray) -> dict[str, ca.SX | np.ndarray]:
        """The fields of a symbolic or numeric vector (numeric: along its last axis)."""
        if isinstance(vector, np.ndarray):
            return {name: vector[..., part] for name, part in self._slices.items()}
        return {name: vector[part] for name, part in self._slices.items()}

    def pack(self, values: Mapping[str, object]) -> np.ndarray:
        """A numeric vector from one value per field: an array of its size, or a float,
        which fills every entry of the field."""
        # gathered as Python floats and converted once: a third faster than concatenating
        # an array per field, and every run packs two vectors
        flat: list[float] = []
        for name, size in self.fields:
            value = values[name]
            entries = ([value] * size if isinstance(value, float)
                       else np.asarray(value, dtype=float).ravel().tolist())
            if len(entries) != size:
                raise ValueError(f"field {name}: expected {size} values, got {len(entries)}")
            flat.extend(entries)
        return np.array(flat, dtype=float)


@dataclasses.dataclass(frozen=True)
class StepLayout:
    """The layout of one robot and controller's closed-loop step (see the module docstring).

    Parameters
    ----------
    n, n_j : int
        Degrees of freedom and free entries of J_d.
    n_memory : int
        Length of the controller's internal state.
    rate_limited : bool
        Whether the plant limits the applied tension's rate (then x holds the applied
        tension and p the rate limit, N/s).
    m : int, optional
        Number of cables (default n).
    plant_x, plant_p, plant_log : tuple of (name, size)
        Fields an as-built plant adds to x (before the status), p and the log.
    """

    n: int
    n_j: int
    n_memory: int = 0
    rate_limited: bool = False
    m: int | None = None
    plant_x: tuple[tuple[str, int], ...] = ()
    plant_p: tuple[tuple[str, int], ...] = ()
    plant_log: tuple[tuple[str, int], ...] = ()

    @property
    def cables(self) -> int:
        """Number of cables: ``m``, or n when not given (fully actuated)."""
        return self.n if self.m is None else self.m

    @functools.cached_property
    def x(self) -> Fields:
        """The state: q (m, rad), dq, the controller's memory, applied tension (N), status."""
        return Fields((("q", self.n), ("dq", self.n), ("memory", self.n_memory),
                       ("applied", self.cables if self.rate_limited else 0), *self.plant_x,
                       ("status", 1)))

    @functools.cached_property
    def p(self) -> Fields:
        """The parameters: goal, gains, dt (s), plant mass factor, slack switch, rate limit."""
        return Fields((("q_goal", self.n), ("k", self.n), ("r_d", self.n), ("dt", 1),
                       ("mass_scale", 1), ("slack", 1),
                       ("rate_limit", 1 if self.rate_limited else 0), *self.plant_p))

    @functools.cached_property
    def log(self) -> Fields:
        """Per step: tau (N), alpha, beta (N), j, flags."""
        return Fields((("tau", self.cables), ("alpha", 1), ("beta", 1), ("j", self.n_j),
                       ("flags", 1), *self.plant_log))

    @functools.cached_property
    def status_index(self) -> int:
        """Offset of the stop status in x."""
        return self.x.offset("status")

    def parameters(self, goal: np.ndarray, k: np.ndarray, r_d: np.ndarray, dt: float, *,
                   mass_scale: float = 1.0,
                   slack: bool = False, rate_limit: float | None = None,
                   plant: Mapping[str, object] | None = None) -> np.ndarray:
        """p for one run (``rate_limit`` in N/s, used by a rate-limited layout only;
        ``plant`` the values of the ``plant_p`` fields)."""
        return self.p.pack({"q_goal": goal, "k": k, "r_d": r_d, "dt": dt,
                            "mass_scale": mass_scale, "slack": float(slack),
                            "rate_limit": [rate_limit or 0.0] if self.rate_limited else [],
                            **(plant or {})})

    def split_log(self, log: np.ndarray) -> dict[str, np.ndarray]:
        """The per-step columns of a log array of shape (N, log size)."""
        fields = self.log.split(log)
        return {"tau": fields["tau"], "alpha": fields["alpha"][..., 0],
                "beta": fields["beta"][..., 0], "j": fields["j"],
                "flags": fields["flags"][..., 0].astype(np.int64)}
