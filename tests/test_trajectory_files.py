"""A stored run comes back as it was: its stop reason, and files written without the
optional static tension or stop reason (as older versions wrote them)."""

from __future__ import annotations

import numpy as np

from cdpr_sym import PD, Plant, Trajectory, get_simulator


def _stopped_run(planar2):
    """A run that leaves the frame after a few steps (started moving out at 3 m/s)."""
    start = planar2.goal.copy()
    start[0] = planar2.frame_lower[0] + 0.02
    dq0 = np.array([-3.0, 0.0])
    soft = np.ones(2)
    return get_simulator(planar2, PD()).run(start, planar2.goal, soft, soft, duration=0.2,
                                            dt=1e-3, plant=Plant(), dq0=dq0)


def test_a_stopped_run_keeps_its_stop_reason_and_static_tension(planar2, tmp_path):
    run = _stopped_run(planar2)
    assert run.stop_reason == "left_frame"
    loaded = Trajectory.load(run.save(tmp_path / "run"))
    assert loaded.stop_reason == "left_frame"
    np.testing.assert_array_equal(loaded.static_tension, run.static_tension)
    np.testing.assert_array_equal(loaded.q, run.q)


def test_a_file_without_the_optional_arrays_loads_with_none(planar2, tmp_path):
    path = _stopped_run(planar2).save(tmp_path / "run")
    with np.load(path) as stored:
        kept = {name: stored[name] for name in stored.files
                if name not in ("static_tension", "stop_reason")}
    np.savez(path, **kept)
    loaded = Trajectory.load(path)
    assert loaded.stop_reason is None and loaded.static_tension is None
