"""A sweep's configuration: each refusal names its field and says what was expected, and
robot references resolve to a name or file a resume can read again."""

from __future__ import annotations

import pytest

from cdpr_sym.errors import InvalidCase
from cdpr_sym.robot import preset
from cdpr_sym.sweep import SweepConfig
from cdpr_sym.sweep.config import MAX_PAIRS, check_pairs, check_seed, robot_reference


def _refused(field: str, text: str, call, *args, **kwargs) -> None:
    with pytest.raises(InvalidCase) as error:
        call(*args, **kwargs)
    assert error.value.field == field
    assert text in str(error.value)


def test_pairs_up_to_the_cap_inclusive_are_accepted():
    assert check_pairs(1) == 1
    assert check_pairs(MAX_PAIRS) == MAX_PAIRS == 100_000


@pytest.mark.parametrize("pairs", [0, -1, MAX_PAIRS + 1, 2.0, True, "3"])
def test_other_pairs_are_refused_naming_the_cap(pairs):
    _refused("pairs", f"expected a positive number of pairs up to 100,000, got {pairs}",
             check_pairs, pairs)


@pytest.mark.parametrize("seed", [-1, 1.5, False, "0"])
def test_bad_seeds_are_refused(seed):
    _refused("seed", f"expected a whole number >= 0, got {seed}", check_seed, seed)


def test_seed_zero_and_large_are_accepted():
    assert check_seed(0) == 0 and check_seed(2**40) == 2**40


def test_no_controller_is_refused():
    _refused("controllers", "expected at least one controller",
             SweepConfig, robot="aras3", controllers=(), pairs=2)


def test_each_repeated_controller_is_named_once_in_order():
    _refused("controllers", "pd-sat, smooth listed more than once; each controller gives "
             "one row per pair", SweepConfig, robot="aras3",
             controllers=("smooth", "pd-sat", "smooth", "pd-sat", "l2"), pairs=2)


def test_an_unchanged_preset_object_is_referenced_by_name():
    robot = preset("aras3")
    resolved, reference = robot_reference(robot)
    assert resolved is robot and reference == "aras3"


def test_a_changed_preset_object_is_refused():
    changed = preset("aras3").as_dict()
    changed["mass"] = changed["mass"] * 2
    robot = type(preset("aras3"))(**changed)
    _refused("robot", "'aras3' is not an unchanged preset; pass its TOML file instead",
             robot_reference, robot)


def test_a_preset_name_resolves_to_its_robot():
    robot, reference = robot_reference("aras3")
    assert reference == "aras3" and robot.as_dict() == preset("aras3").as_dict()


def test_a_controller_whose_gains_the_period_cannot_hold_is_refused(monkeypatch):
    # ida-winch's gains come from the robot and the period (control.tuning), but its filter
    # stages are chosen at 1 kHz: at 0.2 s its loop has a growing mode (0.17 Hz; run, it
    # rings 2-5 cm about the goal for 200 s), so the sweep is refused before it starts ...
    _refused("feedback_stages", "the 4 filter stages the rule chose", SweepConfig,
             robot="aras3", controllers=("l2", "ida-winch"), pairs=2, duration=10.0, dt=0.2)
    # ... and a registered design with fixed gains is refused where the period cannot
    # hold them: k_p = 500 N/m on aras3 (4.1 kg) needs dt < 0.18 s
    from cdpr_sym.control import registry
    from cdpr_sym.control.winch_level import WinchIdaPbc

    # (its stages stated: the rule's are checked at the period, above)
    monkeypatch.setitem(registry.CONTROLLERS, "ida-winch",
                        WinchIdaPbc(stiffness=500.0, feedback_stages=4))
    _refused("stiffness", "expected k_p below", SweepConfig, robot="aras3",
             controllers=("l2", "ida-winch"), pairs=2, duration=10.0, dt=0.2)
    SweepConfig(robot="aras3", controllers=("l2", "ida-winch"), pairs=2, duration=10.0,
                dt=0.1)
