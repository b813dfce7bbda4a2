"""Every registered controller meets the one interface, validates and round-trips its options,
and is documented."""

from __future__ import annotations

import inspect

import casadi as ca
import numpy as np
import pytest

from cdpr_sym import InvalidCase, SymbolicModel, preset
from cdpr_sym.control import (
    CONTROLLERS,
    ControlLaw,
    Controller,
    capabilities,
    controller_from_options,
    initial_memory_function,
    law_function,
    step_with_drives,
    tension,
)
from cdpr_sym.control.planned import SmoothReference, VirtualReferenceIdaPbc

NAMES = list(CONTROLLERS)


@pytest.mark.parametrize("name", NAMES)
def test_registered_controller_meets_the_interface(name, aras3_model):
    controller = CONTROLLERS[name]
    if not capabilities(controller).fully_actuated:  # runs only m < n: bar2 has n = 3 too
        aras3_model = SymbolicModel(preset("bar2"))
    assert isinstance(controller, Controller) and name.startswith(controller.name)
    n, size = aras3_model.n, controller.memory_size(aras3_model)
    symbols = [ca.SX.sym(label, n) for label in ("q", "dq", "q_goal", "k", "r_d")]
    memory = controller.initial_memory(aras3_model, symbols[0], *symbols[2:])
    assert memory.shape == (size, 1)
    law, memory_next = step_with_drives(controller, aras3_model, *symbols,
                                        ca.SX.sym("m", size), ca.SX.sym("dt"))
    assert isinstance(law, ControlLaw) and memory_next.shape == (size, 1)
    assert law.tau.shape == (aras3_model.m, 1) and law.j.shape == (aras3_model.n_j, 1)


@pytest.mark.parametrize("name", NAMES)
def test_options_round_trip_to_an_equal_controller(name):
    controller = CONTROLLERS[name]
    rebuilt = controller_from_options(name, controller.options())
    assert rebuilt == controller and hash(rebuilt) == hash(controller)


@pytest.mark.parametrize("name", NAMES)
def test_controller_is_documented(name):
    """The class says what it guarantees, and every option is named in its documentation
    (its own docstring or a base class's)."""
    cls = type(CONTROLLERS[name])
    assert cls.__doc__ and len(inspect.cleandoc(cls.__doc__).splitlines()) >= 2
    docs = " ".join(klass.__doc__ or "" for klass in cls.__mro__)
    for field in inspect.signature(cls).parameters:
        assert f"``{field}``" in docs or f"{field} :" in docs, field


@pytest.mark.parametrize(("cls", "field", "value"), [
    (SmoothReference, "durations", (0.0,)), (SmoothReference, "samples", 2),
    (SmoothReference, "max_rate", float("nan")),
    (VirtualReferenceIdaPbc, "delta", -1.0), (VirtualReferenceIdaPbc, "start_share", 0.0),
    (VirtualReferenceIdaPbc, "lam", float("nan")),
    (VirtualReferenceIdaPbc, "goal_stiffness", 0.0), (VirtualReferenceIdaPbc, "plan", 3),
    (SmoothReference, "command_cutoff", 0.0), (SmoothReference, "command_cutoff", "15"),
    (SmoothReference, "guard", -1.0), (SmoothReference, "guard", float("nan")),
    (VirtualReferenceIdaPbc, "observer_rate", -1.0),
    (VirtualReferenceIdaPbc, "command_cutoff", float("inf"))])
def test_bad_option_is_refused_naming_it(cls, field, value):
    with pytest.raises(InvalidCase) as raised:
        cls(**{field: value})
    assert raised.value.field == field


def test_stateless_and_stateful_laws_share_one_function_signature(aras3_model):
    functions = [law_function(aras3_model, CONTROLLERS[name]) for name in ("pd", "smooth")]
    assert functions[0].name_in() == functions[1].name_in()
    assert functions[0].name_out() == functions[1].name_out()


def test_first_smooth_command_at_rest_is_the_static_tension(aras3, aras3_model):
    """tension() starts a stateful law from its own plan: at rest that is W^-1 grad V."""
    out = tension(aras3_model, CONTROLLERS["smooth"], aras3.start, np.zeros(3))
    static = np.array(aras3_model.functions["static_tension"](aras3.start)).ravel()
    np.testing.assert_allclose(out.tau, static, rtol=1e-12)
    plan = initial_memory_function(aras3_model, CONTROLLERS["smooth"])
    assert plan.size1_out(0) == CONTROLLERS["smooth"].memory_size(SymbolicModel(aras3))


#: What the tour (docs/guide/tour.md) says each design supports beyond its law: the designs
#: for robots with more cables than degrees of freedom, and the one that optimises at its
#: own rate.
ANY_CABLES = {"pd-td", "smooth", "smooth-lp", "l2", "ida-winch", "nmpc", "nmpc-sqp", "nmpc-ipopt",
              "nmpc-of"}
SAMPLED = {"nmpc", "nmpc-sqp", "nmpc-ipopt", "nmpc-of"}


@pytest.mark.parametrize("name", NAMES)
def test_capabilities_are_declared_and_read_in_one_place(name):
    from cdpr_sym.control import Capabilities, capabilities

    controller = CONTROLLERS[name]
    declared = controller.capabilities()
    assert isinstance(declared, Capabilities) and capabilities(controller) == declared
    assert declared.any_cables == (name in ANY_CABLES)
    assert declared.sampled == (name in SAMPLED)
    if declared.sampled:
        assert declared.sample_period == pytest.approx(1.0 / controller.rate)


@pytest.mark.parametrize("name", NAMES)
def test_planned_is_declared_for_the_designs_that_follow_a_smooth_reference(name):
    """``Capabilities.planned`` (read by the encoder package's guard) says what the type
    test it replaced said: the design is a SmoothReference or holds one as its plan."""
    from cdpr_sym.control import capabilities

    design = CONTROLLERS[name]
    follows_a_plan = isinstance(design, SmoothReference) or isinstance(
        getattr(design, "plan", None), SmoothReference)
    assert capabilities(design).planned == follows_a_plan


def test_a_controller_without_capabilities_inverts_w_every_period():
    from cdpr_sym.control import SQUARE_STEPWISE, capabilities, check_cables

    class Outside:
        name = "outside"

    assert capabilities(Outside()) == SQUARE_STEPWISE
    check_cables(Outside(), 3, 3)
    with pytest.raises(InvalidCase, match=r"^controller: outside needs as many cables"):
        check_cables(Outside(), 3, 4)


def test_names_and_objects_are_coerced_in_one_place(aras3):
    from cdpr_sym.control import controller_by_name
    from cdpr_sym.robot import resolve_robot

    assert resolve_robot(aras3) is aras3 and resolve_robot("aras3") == aras3
    assert controller_by_name(CONTROLLERS["l2"]) is CONTROLLERS["l2"]
    assert controller_by_name("l2") is CONTROLLERS["l2"]
