"""Where the options of the planned designs, the NMPC and the plant turn from accepted to
refused.

Each boundary is probed on both sides; a refusal names the field and says what it got.
"""

from __future__ import annotations

import math

import pytest

from cdpr_sym import Nmpc, Plant, preset
from cdpr_sym.closed_loop.simulator import Simulator
from cdpr_sym.control.nmpc.design import MAX_INTERVALS
from cdpr_sym.control.nmpc.problem import EXPANDED_BUDGET_BYTES, EXPANDED_BYTES, NmpcProblem
from cdpr_sym.control.planned import SmoothReference, VirtualReferenceIdaPbc
from cdpr_sym.errors import InvalidCase
from cdpr_sym.model import SymbolicModel


@pytest.mark.parametrize(("field", "value"), [
    ("start_share", 1.0), ("start_share", 1e-3), ("lam", 0.0), ("lam", 0.5),
    ("lam", math.inf), ("goal_stiffness", 0.5), ("goal_stiffness", None),
    ("delta", 0.5), ("boost", 1e-3), ("brake", 0.25), ("ramp", 2.0)])
def test_ida_ref_accepts_values_at_and_inside_its_bounds(field, value):
    design = VirtualReferenceIdaPbc(**{field: value})
    assert getattr(design, field) == value


@pytest.mark.parametrize(("field", "value", "shown"), [
    ("start_share", 1.5, "1.5"), ("start_share", 0.0, "0.0"),
    ("start_share", -0.5, "-0.5"),
    ("lam", -0.5, "-0.5"), ("lam", math.nan, "nan"),
    ("goal_stiffness", 0.0, "0.0"), ("goal_stiffness", -2.0, "-2.0"),
    ("goal_stiffness", math.inf, "inf"),
    ("delta", 0.0, "0.0"), ("boost", -1.0, "-1.0"), ("brake", math.inf, "inf"),
    ("ramp", math.nan, "nan"), ("plan", "smooth", "'smooth'")])
def test_ida_ref_refuses_values_outside_naming_field_and_value(field, value, shown):
    with pytest.raises(InvalidCase) as raised:
        VirtualReferenceIdaPbc(**{field: value})
    assert raised.value.field == field
    message = str(raised.value)
    assert message.startswith(f"{field}: expected ")
    assert message.endswith(f"got {shown}")


def test_ida_ref_takes_its_plan_from_the_dictionary_options_writes():
    plan = SmoothReference(durations=(2.0, 4.0), max_rate=300.0)
    design = VirtualReferenceIdaPbc(plan=plan.options())
    assert design.plan == plan
    assert VirtualReferenceIdaPbc(**design.options()) == design


@pytest.mark.parametrize(("field", "value"), [
    ("durations", (0.5,)), ("margins", (0.0, 5.0)), ("max_rate", 1e-3), ("samples", 3)])
def test_smooth_accepts_values_at_and_inside_its_bounds(field, value):
    assert getattr(SmoothReference(**{field: value}), field) == value


@pytest.mark.parametrize(("cls", "field", "value", "shown"), [
    (SmoothReference, "durations", (), "()"),
    (SmoothReference, "durations", (1.0, -1.0), "(1.0, -1.0)"),
    (SmoothReference, "margins", (), "()"), (SmoothReference, "margins", (-1.0,), "(-1.0,)"),
    (SmoothReference, "max_rate", 0.0, "0.0"), (SmoothReference, "max_rate", math.inf, "inf"),
    (SmoothReference, "samples", 2, "2"), (SmoothReference, "samples", True, "True"),
    (SmoothReference, "samples", 3.0, "3.0"),
    (Plant, "mass_scale", 0.0, "0.0"), (Plant, "mass_scale", math.nan, "nan"),
    (Plant, "rate_limit", -5.0, "-5.0"), (Plant, "rate_limit", math.inf, "inf")])
def test_smooth_and_plant_refuse_values_outside_naming_field_and_value(cls, field, value,
                                                                        shown):
    with pytest.raises(InvalidCase) as raised:
        cls(**{field: value})
    assert raised.value.field == field
    assert str(raised.value).startswith(f"{field}: expected ")
    assert str(raised.value).endswith(f"got {shown}")


# -- NMPC: every weight and option, and the size of its problem ----------------------------
@pytest.mark.parametrize(("field", "value"), [
    ("horizon", 4.0), ("horizon", 1e-9), ("rate", 1e-300), ("tension_weight", 0.0),
    ("substeps", 20), ("observer_rate", None), ("terminal_factor", 1e-3)])
def test_nmpc_accepts_values_at_and_inside_its_bounds(field, value):
    assert getattr(Nmpc(**{field: value}), field) == value


@pytest.mark.parametrize(("field", "value", "shown"), [
    ("tension_weight", math.inf, "inf"), ("tension_weight", -1.0, "-1.0"),
    ("tension_weight", math.nan, "nan"), ("position_weight", math.inf, "inf"),
    ("velocity_weight", 0.0, "0.0"), ("rate_weight", math.nan, "nan"),
    ("terminal_factor", math.inf, "inf"), ("max_rate", math.inf, "inf"),
    ("observer_rate", math.inf, "inf"), ("observer_rate", 0.0, "0.0"),
    ("rate", math.inf, "inf"), ("rate", 1e-320, "1e-320"), ("horizon", math.nan, "nan"),
    ("substeps", 21, "21"), ("substeps", 10**9, "1000000000"), ("substeps", True, "True"),
    ("horizon", 4.02, "4.02 s at 50 Hz = 201"), ("horizon", 1e6, "1000000.0 s at 50 Hz = 5e+07"),
    ("horizon", 1e308, "1e+308 s at 50 Hz = inf")])
def test_nmpc_refuses_values_outside_naming_field_and_value(field, value, shown):
    with pytest.raises(InvalidCase) as raised:
        Nmpc(**{field: value})
    assert raised.value.field == field
    assert str(raised.value).startswith(f"{field}: expected ")
    assert str(raised.value).endswith(f"got {shown}")


def test_nmpc_horizon_counts_intervals_at_its_own_rate():
    assert Nmpc(horizon=2.0, rate=100.0).intervals == MAX_INTERVALS == 200
    with pytest.raises(InvalidCase, match="at 200 Hz") as raised:
        Nmpc(horizon=2.0, rate=200.0)
    assert raised.value.field == "horizon"


def test_expanded_nmpc_problem_is_refused_by_its_estimated_memory(aras3_model, spatial6):
    # the estimate: intervals x prediction instructions x states x 700 B, counted here from
    # the model's own right-hand side rather than read back from the problem
    spatial6_model = SymbolicModel(spatial6)
    instructions = NmpcProblem(spatial6_model, Nmpc()).prediction.n_instructions()
    per_interval = instructions * (2 * spatial6.n + spatial6.m) * EXPANDED_BYTES
    most = EXPANDED_BUDGET_BYTES // per_interval
    assert 25 <= most < 200  # spatial6's derived horizon fits; the longest allowed does not
    accepted = NmpcProblem(spatial6_model, Nmpc(solver="ipopt", horizon=most / 50))
    assert accepted.expanded_bytes() == most * per_interval
    with pytest.raises(InvalidCase, match=rf"limit is 2 GiB \({most} intervals\)") as raised:
        NmpcProblem(spatial6_model, Nmpc(solver="sqp", horizon=(most + 1) / 50))
    assert raised.value.field == "horizon"
    # the real-time iteration's QP is not expanded: the same horizon is built
    NmpcProblem(spatial6_model, Nmpc(horizon=(most + 1) / 50))
    # aras3's prediction is small: the longest horizon fits with either solver
    NmpcProblem(aras3_model, Nmpc(solver="ipopt", horizon=4.0))


def test_a_derived_horizon_the_expanded_problem_cannot_afford_is_cut_to_it():
    """ipanema8's derived horizon (68 intervals) is more than its converged solvers' expanded
    problem affords: it is cut to the most intervals the memory budget affords, counted here
    from the prediction's instructions, as the real-time iteration's is cut to
    MAX_INTERVALS; a horizon the user gives is refused instead (above)."""
    ipanema8 = preset("ipanema8")
    model = SymbolicModel(ipanema8)
    instructions = NmpcProblem(model, Nmpc()).prediction.n_instructions()
    most = EXPANDED_BUDGET_BYTES // (instructions * (2 * ipanema8.n + ipanema8.m)
                                     * EXPANDED_BYTES)
    assert Nmpc(solver="ipopt").tuned(ipanema8, model).intervals > most
    for solver in ("ipopt", "sqp"):
        problem = NmpcProblem(model, Nmpc(solver=solver))
        assert problem.intervals == most and problem.tuning.horizon == most / 50
        assert problem.expanded_bytes() <= EXPANDED_BUDGET_BYTES


def test_a_simulator_refuses_an_oversized_nmpc_before_compiling(monkeypatch, spatial6):
    def compiled(*args, **kwargs):
        raise AssertionError("compiled before the size check")

    monkeypatch.setattr(Simulator, "_compiled_library", compiled)
    monkeypatch.setattr("cdpr_sym.closed_loop.simulator.chunk_function", compiled)
    with pytest.raises(InvalidCase) as raised:
        Simulator(spatial6, Nmpc(solver="ipopt", horizon=4.0))
    assert raised.value.field == "horizon" and "GiB" in str(raised.value)
