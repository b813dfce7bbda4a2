"""Plant effects: each registered, laid out in registry order, and a new one composes.

A new effect is one class (its fields and the hooks it needs) handed to the step builder;
here a command scale ``s`` on the tension reaching the cables, checked against what it must
do: s = 1 is the ideal plant to the bit, s = 0 lets the point mass fall freely (RK4 is exact
for a constant acceleration, so one period moves it ballistically).
"""

from __future__ import annotations

import dataclasses
import importlib
from pathlib import Path
from typing import ClassVar

import numpy as np
import pytest

from cdpr_sym.as_built import Actuation, AsBuilt, AsBuiltStructure, Sensing
from cdpr_sym.closed_loop import Plant, get_simulator
from cdpr_sym.closed_loop.effects import REGISTRY, PlantEffect, plant_effects
from cdpr_sym.closed_loop.plant_kind import PlantKind
from cdpr_sym.closed_loop.step import plant_layout, step_function
from cdpr_sym.control import CONTROLLERS
from cdpr_sym.model import SymbolicModel

EFFECTS = Path(__file__).parents[1] / "cdpr_sym" / "closed_loop" / "effects"


def test_every_effect_module_is_registered():
    """One module an effect, each registered (the interface and the numbers are not
    effects)."""
    found = set()
    for path in EFFECTS.glob("*.py"):
        if path.stem in ("__init__", "base", "readout"):
            continue
        module = importlib.import_module(f"cdpr_sym.closed_loop.effects.{path.stem}")
        found |= {value for value in vars(module).values() if isinstance(value, type)
                  and issubclass(value, PlantEffect) and value is not PlantEffect
                  and value.__module__ == module.__name__}
    assert found == set(REGISTRY)
    assert len({effect.name for effect in REGISTRY}) == len(REGISTRY)


@pytest.mark.parametrize("structure", [
    AsBuiltStructure(), AsBuiltStructure(actuation=True, sensing=True, delay=2, anchors=True)])
def test_the_as_built_layout_is_the_effects_fields_in_registry_order(structure, aras3_model):
    effects = plant_effects(PlantKind(as_built=structure))
    assert [type(effect) for effect in effects] == [
        kind for kind in REGISTRY if any(type(effect) is kind for effect in effects)]
    layout = plant_layout(aras3_model, CONTROLLERS["smooth"], effects)
    declared = [field for effect in effects for field in effect.state_fields(aras3_model)]
    assert list(layout.plant_x) == declared
    n, m = aras3_model.n, aras3_model.m
    expected = ([("payout", m), ("drum_speed", m), ("motor_torque", m)]
                if structure.actuation else []) + [("pending", structure.delay * m)] + (
        [("q_read", n), ("dq_read", n)] if structure.sensing else [])
    assert declared == expected
    assert layout.plant_p == (((("actuation", 8),) if structure.actuation else ())
                              + ((("sensing", 3), ("encoder_offsets", m))
                                 if structure.sensing else ())
                              + ((("anchor_offsets", m * 3),) if structure.anchors else ()))
    assert layout.plant_log == (("tension", m),)


def test_a_rate_limit_on_an_as_built_plant_is_refused(aras3, build_options):
    from cdpr_sym.closed_loop import Simulator
    from cdpr_sym.errors import InvalidCase

    with pytest.raises(InvalidCase, match=r"^plant: an as-built plant limits the tension"):
        Simulator(aras3, CONTROLLERS["pd"], build_options=build_options, rate_limited=True,
                  as_built=AsBuiltStructure(actuation=True))


@dataclasses.dataclass(frozen=True)
class CommandScale(PlantEffect):
    """The cables receive ``s`` times the command (a parameter)."""

    name: ClassVar[str] = "command_scale"

    def parameter_fields(self, model):
        return (("command_scale", 1),)

    def deliver(self, build, command):
        return build.par["command_scale"] * command


def _step(model, effects, x, p):
    step = step_function(model, CONTROLLERS["pd"], effects=effects)
    x_next, log = step(x, p)
    return np.array(x_next).ravel(), np.array(log).ravel()


def test_a_new_effect_composes_with_the_step(aras3, build_options):
    model = SymbolicModel(aras3)
    simulator = get_simulator(aras3, CONTROLLERS["pd"], build_options=build_options)
    x = simulator.initial_state(aras3.start, aras3.goal, aras3.k, aras3.r_d)
    x[model.n: 2 * model.n] = [0.1, -0.2, 0.3]
    p = simulator.parameters(aras3.goal, aras3.k, aras3.r_d, 1e-3, Plant())
    layout = plant_layout(model, CONTROLLERS["pd"], (CommandScale(),))
    assert layout.p.names[-1] == "command_scale"
    ideal = _step(model, (), x, p)
    scaled = _step(model, (CommandScale(),), x, np.append(p, 1.0))
    for got, expected in zip(scaled, ideal, strict=True):
        np.testing.assert_array_equal(got, expected)
    falling, _ = _step(model, (CommandScale(),), x, np.append(p, 0.0))
    dt, gravity = 1e-3, np.array([0.0, 0.0, -aras3.gravity])
    q, dq = x[: model.n], x[model.n: 2 * model.n]
    np.testing.assert_allclose(falling[model.n: 2 * model.n], dq + gravity * dt, atol=1e-15)
    np.testing.assert_allclose(falling[: model.n], q + dq * dt + 0.5 * gravity * dt ** 2,
                               atol=1e-15)


@pytest.mark.parametrize("plant, effects", [
    (Plant(), []),
    (Plant(mass_scale=1.1, slack=True), []),
    (Plant(rate_limit=600.0), ["RateLimit"]),
    (Plant(as_built=AsBuilt(actuation=Actuation(), sensing=Sensing(), delay=2,
                            anchor_offsets=np.zeros((3, 3)))),
     ["TrueCables", "Winches", "Delay", "Encoders", "AnchorErrors"]),
    (Plant(as_built=AsBuilt(actuation=None, sensing=None, delay=0)), ["TrueCables", "Delay"]),
])
def test_a_plant_names_its_kind_and_its_kind_gives_the_effects(plant, effects):
    """The kind holds what changes the step's code (a rate limit, the as-built structure),
    never the numbers, and the registry turns it into the effects, in layout order."""
    assert [type(effect).__name__ for effect in plant_effects(plant.kind)] == effects
    numbers_apart = dataclasses.replace(plant, mass_scale=0.9)
    assert numbers_apart.kind == plant.kind
    suffix = plant.kind.library_suffix()
    expected = ("" if not effects else "_rate" if plant.rate_limited else "_built_")
    assert suffix.startswith(expected) and (suffix == "") == (not effects)
