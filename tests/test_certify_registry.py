"""The certify registry: which proof method decides which robot, and that a new property with
its own method is one class each plus its registration, which the command line then offers."""

from __future__ import annotations

import json
import types

import numpy as np
import pytest

from cdpr_sym.certify import registry
from cdpr_sym.certify.cramer import CramerVerdicts
from cdpr_sym.certify.static import StaticFeasibility
from cdpr_sym.certify.verdict import Verdict
from cdpr_sym.cli import main
from cdpr_sym.errors import InvalidCase
from cdpr_sym.model import SymbolicModel
from cdpr_sym.robot import preset


@pytest.mark.parametrize("wrench", [False, True])
@pytest.mark.parametrize("n", [2, 3, 4, 6])
@pytest.mark.parametrize("extra", [0, 1, 2])
def test_exactly_one_static_method_covers_each_robot(n, extra, wrench):
    """The static property's methods split the robots between them: one and only one covers
    each cable count, dimension and wrench box (so their order cannot matter)."""
    robot = types.SimpleNamespace(m=n + extra, n=n, name="drawn")
    methods = registry.proof_methods()
    covering = [key for key in registry.workspace_property("static").methods
                if methods[key].covers(robot, wrench)]
    assert len(covering) == 1, covering
    expected = ("anchored" if extra and n > 3 else "facets" if extra or (wrench and n > 3)
                else "cramer-wrench" if wrench else "cramer" if n <= 3 else "krawczyk")
    assert covering == [expected]


def test_a_property_no_method_covers_is_refused_naming_the_property():
    with pytest.raises(InvalidCase) as refused:
        registry.method_for(preset("spatial6"), False, "assumption-1")
    assert refused.value.field == "property" and "m = n <= 3" in str(refused.value)
    with pytest.raises(InvalidCase) as unknown:
        registry.method_for(preset("aras3"), False, "nonsense")
    assert unknown.value.field == "property"
    with pytest.raises(InvalidCase) as design:
        registry.pair_property("pd")
    assert design.value.field == "controller"


MARGIN = 2.0  # N kept from both tension bounds by the property below


def _inside(robot):
    return robot.with_case(t_min=robot.t_min + MARGIN, t_max=robot.t_max - MARGIN)


class _InsideMethod:
    """Cramer's margins of the robot with its box shrunk by MARGIN."""

    key = "cramer-inside"
    description = "Cramer's margins of the box shrunk by 2 N"

    def covers(self, robot, wrench):
        return robot.m == robot.n <= 3 and not wrench

    def verdicts(self, model, orientation, compiled, wrench):
        return CramerVerdicts(SymbolicModel(_inside(model.robot)), orientation, compiled)


class _Inside(StaticFeasibility):
    """Static feasibility with 2 N to spare on both bounds."""

    key = "inside"
    help = "static feasibility 2 N inside the box"
    methods = ("cramer-inside",)
    title = "held 2 N inside the box"

    def statement(self, robot, wrench):
        return "the unique tension 2 N inside [T_min, T_max]"

    def holds(self, robot, poses, half_widths):
        return super().holds(_inside(robot), poses, half_widths)


def test_a_new_property_and_method_are_one_class_each_and_the_command_offers_them(
        monkeypatch, tmp_path, capsys):
    methods = {**registry.proof_methods(), "cramer-inside": _InsideMethod()}
    properties = {**registry.workspace_properties(), "inside": _Inside()}
    monkeypatch.setattr(registry, "proof_methods", lambda: methods)
    monkeypatch.setattr(registry, "workspace_properties", lambda: properties)
    shares = {}
    for prop in ("static", "inside"):
        status = main(["certify", "workspace", "--robot", "planar2", "--property", prop,
                       "--min-width", "0.01", "--samples", "20000", "-q", "--json",
                       "--out", str(tmp_path / prop)])
        content = json.loads(capsys.readouterr().out)
        assert status == 0
        check = content["sampled_check"]
        assert check["disagreements_feasible"] == check["disagreements_infeasible"] == 0
        shares[prop] = content["feasible_share"]
    assert content["property"] == "the unique tension 2 N inside [T_min, T_max]"
    assert content["method"] == "Cramer's margins of the box shrunk by 2 N"
    assert 0 < shares["inside"] < shares["static"]


def test_every_method_answers_in_the_one_vocabulary(rng):
    robot = preset("planar2")
    model = SymbolicModel(robot)
    method = registry.method_for(robot, False)
    lower = rng.uniform(robot.frame_lower[:2], robot.frame_upper[:2] - 0.05, (500, 2))
    codes = method.verdicts(model, np.zeros(0), True, None)(lower, lower + 0.05)
    assert set(np.unique(codes)) <= {Verdict.PROVEN, Verdict.DISPROVEN, Verdict.UNDECIDED}
    assert {Verdict.PROVEN, Verdict.DISPROVEN} <= set(np.unique(codes))
