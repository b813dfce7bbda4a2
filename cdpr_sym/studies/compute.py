"""What each design costs per control step, measured for the study reports.

Every design's whole 1 ms step (law and RK4 plant, in the compiled loop) is a run's wall time
over its steps: an upper bound of the law's own cost. A design that optimises at its own
rate (NMPC) adds its solves, whose median and worst wall-clock time (the call included)
each run records. The reports print them with ``reporting/templates/costs.md.j2``.
"""

from __future__ import annotations

import time
from collections.abc import Iterable
from typing import Any

from cdpr_sym.closed_loop import Plant, get_simulator
from cdpr_sym.control import controller_by_name
from cdpr_sym.robot import Robot

#: The case run timed per design: 5 s at 1 kHz, the second of two (the first builds).
DURATION, DT = 5.0, 1e-3


def control_costs(robot: Robot, names: Iterable[str]) -> dict[str, dict[str, Any]]:
    """Per design: ``step_us`` (µs per 1 ms step, whole closed loop), and for a sampled
    design ``solve_ms_median``, ``solve_ms_max`` and ``solves`` (its second case run)."""
    costs: dict[str, dict[str, Any]] = {}
    for name in names:
        simulator = get_simulator(robot, controller_by_name(name))
        steps = round(DURATION / DT)
        simulator.run(robot.start, robot.goal, robot.k, robot.r_d, duration=DURATION, dt=DT,
                      plant=Plant())
        start = time.perf_counter()
        run = simulator.run(robot.start, robot.goal, robot.k, robot.r_d, duration=DURATION,
                            dt=DT, plant=Plant())
        cost: dict[str, Any] = {"step_us": (time.perf_counter() - start) / steps * 1e6}
        record = run.info.get("solver")
        if record is not None:
            cost.update(solve_ms_median=record["solve_time_median"] * 1e3,
                        solve_ms_max=record["solve_time_max"] * 1e3,
                        solves=record["samples"])
        costs[name] = cost
    return costs
