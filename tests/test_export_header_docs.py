"""The exported header documents each public function in a comment above it: what it does,
and for the step the sizes of its arrays, worked out by hand for planar2 with smooth
(x = q 2 + dq 2 + memory 5 + status 1; p = goal 2 + k 2 + r_d 2 + dt + mass + slack;
log = tau 2 + alpha + beta + j 1 + flags)."""

from __future__ import annotations

import json
import re

import pytest

from cdpr_sym import InvalidCase, SymbolicModel, controller_by_name, preset
from cdpr_sym.closed_loop import Fields, StepLayout, step_layout
from cdpr_sym.export import ExportResult, export_c
from cdpr_sym.export.description import layout_fields
from cdpr_sym.export.documentation import field_list
from cdpr_sym.export.signatures import parameter_arguments


@pytest.fixture(scope="module")
def exported(tmp_path_factory) -> ExportResult:
    return export_c("planar2", "smooth", tmp_path_factory.mktemp("export") / "pkg")


@pytest.fixture(scope="module")
def header(exported) -> str:
    return exported.header.read_text()


def _comment_above(header: str, declaration: str) -> str:
    """The comment right above ``declaration``, its lines joined by single spaces."""
    before = header[: header.index(declaration)]
    comment = before[before.rindex("/*"): before.rindex("*/")]
    lines = [line.strip().lstrip("/*").strip() for line in comment.splitlines()]
    return re.sub(r"\s+", " ", " ".join(lines)).strip()


def test_the_step_says_what_one_period_does_and_its_sizes(header):
    assert _comment_above(header, "int cdpr_planar2_smooth_step(").startswith(
        "One closed-loop period of dt = p[P_DT] s: the tension of the control law, held over "
        "one RK4 step of the plant (x: 11, p: 9, log: 6 doubles; x and x_next must not "
        "overlap).")


def test_the_initial_memory_says_what_it_holds_and_where_it_goes(header):
    assert _comment_above(header, "int cdpr_planar2_smooth_initial_memory(").startswith(
        "The controller's internal state at the start of a move (its plan, computed once per "
        "move; put it into x[X_MEMORY] or pass it to _control).")


def test_the_control_call_says_what_it_commands(header):
    assert _comment_above(header, "int cdpr_planar2_smooth_control(").startswith(
        "One control step: the tension commanded at the state (q, dq) for the goal q_goal.")


def _defines(header: str) -> dict[str, tuple[str, str]]:
    """Each ``#define CDPR_PLANAR2_SMOOTH_<NAME> <value>`` as NAME -> (value, comment), where
    the comment is the one on the same line or, failing that, a one-line comment above."""
    found, above = {}, ""
    for line in header.splitlines():
        define = re.match(r"#define CDPR_PLANAR2_SMOOTH_(\w+) (\S+)(?:\s+/\* (.*) \*/)?$", line)
        if define:
            name, value, comment = define.groups()
            found[name] = (value, comment or above)
        above = line[3:-3] if line.startswith("/* ") and line.endswith(" */") else ""
    return found


def test_the_sizes_and_offsets_are_those_worked_out_by_hand(header):
    defines = _defines(header)
    values = {name: value for name, (value, _) in defines.items()}
    assert {"N": "2", "NJ": "1", "NMEM": "6", "NX": "11", "NP": "9", "NLOG": "6",
            "T_MIN": "1.0", "T_MAX": "30.0"}.items() <= values.items()
    assert {"X_Q": "0", "X_DQ": "2", "X_MEMORY": "4", "X_STATUS": "10",
            "P_GOAL": "0", "P_K": "2", "P_R_D": "4", "P_DT": "6", "P_MASS_SCALE": "7",
            "P_SLACK": "8",
            "LOG_TAU": "0", "LOG_ALPHA": "2", "LOG_BETA": "3", "LOG_J": "4",
            "LOG_FLAGS": "5"}.items() <= values.items()
    assert {"STATUS_SINGULAR": "1", "STATUS_NON_FINITE": "2",
            "STATUS_LEFT_FRAME": "3"}.items() <= values.items()
    assert {"CONTROL_OK": "0", "CONTROL_NULL_ARGUMENT": "(-1)", "CONTROL_INVALID_INPUT": "1",
            "CONTROL_INVALID_OUTPUT": "2"}.items() <= values.items()


def test_every_size_and_flag_says_what_it_holds(header):
    defines = _defines(header)
    comments = {name: comment for name, (_, comment) in defines.items()}
    assert comments["NX"] == "step state x = [q, dq, memory, status]"
    assert comments["NP"] == "step parameters p, see CDPR_PLANAR2_SMOOTH_P_*"
    assert comments["NLOG"] == "step log = [tau, alpha, beta, j, flags]"
    assert comments["NJ"] == "free entries of J_d, n(n-1)/2"
    assert comments["T_MIN"] == "tension bounds, N"
    flags = {name: value for name, (value, _) in defines.items() if name.startswith("FLAG_")}
    assert sorted(int(value) for value in flags.values()) == [1 << bit for bit in range(8)]
    for name in flags:
        assert comments[name] and comments[name] != name.lower(), name
    assert "an input is NaN or infinite" in comments["FLAG_INVALID_INPUT"]
    assert "the law gave NaN or infinity" in comments["FLAG_INVALID_OUTPUT"]


def _declaration(header: str, start: str) -> str:
    """The declaration in ``header`` that begins with ``start``, on one line."""
    declaration = header[header.index(start):]
    return re.sub(r"\s+", " ", declaration[: declaration.index(";")])


def test_the_parameters_function_is_declared_as_documented(header):
    declaration = _declaration(header, "int cdpr_planar2_smooth_parameters(")
    assert declaration == ("int cdpr_planar2_smooth_parameters(const double q_goal[2], "
                           "const double k[2], const double r_d[2], double dt, "
                           "double mass_scale, int slack, double p[9])")


def test_the_control_call_refuses_exactly_its_required_null_pointers(header):
    comment = _comment_above(header, "int cdpr_planar2_smooth_control(")
    assert ("CDPR_PLANAR2_SMOOTH_CONTROL_NULL_ARGUMENT (-1) if q, dq, q_goal, memory, tau, "
            "memory_next or work is NULL") in comment
    assert "k[2] stiffness gains K (diagonal), N/m, N m/rad; NULL: the robot's case gains" \
        in comment


def test_every_argument_of_a_model_function_has_its_own_words(header):
    # an argument without its own entry would repeat the function's one-line summary
    functions = list(re.finditer(r"/\* (.+?)\.\n \* \d+ straight-line operations(.*?)\*/",
                                 header, re.S))
    # every generated function but _control states its operation count: step, the planner,
    # the 17 model terms and forward kinematics
    assert len(functions) == 20
    for function in functions:
        summary, arguments = function.group(1), function.group(2)
        summary = re.sub(r"\s*\n \*\s*", " ", summary)[:40]  # its opening words, one line
        for name, words in re.findall(r" \* in  (\w+)\[\d+\]: (.*)", arguments):
            assert not words.startswith(summary), (summary, name)
            assert words.strip() not in ("", "None"), (summary, name)  # no missing entry


def test_matrices_and_only_matrices_are_documented_as_row_major(header):
    comment = _comment_above(header, "int cdpr_planar2_smooth_structure_matrix(")
    assert comment.endswith("out W[4]: structure matrix W = -(dl/dq)^T (point mass: unit "
                            "vectors), - (2 x 2, row-major)")
    for vector_function in ("cable_lengths", "grad_potential", "static_tension", "p_matrix",
                            "a_matrix"):
        comment = _comment_above(header, f"int cdpr_planar2_smooth_{vector_function}(")
        assert "row-major" not in comment and " x " not in comment, vector_function


def test_the_header_bounds_the_real_time_functions_by_their_own_operation_counts(exported,
                                                                                 header):
    functions = json.loads(exported.manifest.read_text())["functions"]
    bound = max(functions["control"]["operations"], functions["step"]["operations"])
    assert functions["initial_memory"]["operations"] > bound  # the planner is not bounded
    text = re.sub(r"\s*\n \*\s*", " ", header)
    assert f"(control and step: at most {bound} operations;" in text
    # the package's symbols take the visibility its user builds with, not CasADi's export
    assert "CASADI_SYMBOL_EXPORT" not in exported.generated.read_text()


def test_the_planner_is_declared_with_the_argument_names_it_documents(header):
    declaration = _declaration(header, "int cdpr_planar2_smooth_initial_memory(")
    assert declaration == ("int cdpr_planar2_smooth_initial_memory(const double q0[2], "
                           "const double q_goal[2], const double k[2], const double r_d[2], "
                           "double memory[6], cdpr_planar2_smooth_work *work)")


# -- the layout tables: every field of the declared layout, with its unit -------------------
#: The unit of every field a step layout declares, written out by hand: positions, then
#: angles where they differ (None: no unit).
FIELD_UNITS = {
    "q": ("m", "rad"), "dq": ("m/s", "rad/s"), "memory": None, "applied": ("N",),
    "status": None, "q_goal": ("m", "rad"), "k": ("N/m", "N m/rad"),
    "r_d": ("N s/m", "N m s/rad"), "dt": ("s",), "mass_scale": None, "slack": None,
    "rate_limit": ("N/s",), "tau": ("N",), "alpha": None, "beta": ("N",),
    "j": ("N s/m", "N m s/rad"), "flags": None,
}


@pytest.fixture(scope="module")
def layout() -> StepLayout:
    return step_layout(SymbolicModel(preset("planar2")), controller_by_name("smooth"))


def _listed(fields: Fields, keep: tuple[str, ...] = ()) -> list[str]:
    """``name (unit, unit)`` of every field with entries (or in ``keep``), in order."""
    return [f"{name} ({', '.join(FIELD_UNITS[name])})" if FIELD_UNITS[name] else name
            for name in fields.names if fields.width(name) or name in keep]


def _bracket(text: str, opening: str) -> list[str]:
    """The comma-separated items of the ``[...]`` that follows ``opening`` in ``text``,
    commas inside parentheses kept."""
    inside = text[text.index(opening) + len(opening):]
    inside = inside[: inside.index("]")]
    return [item.strip() for item in re.split(r",\s*(?![^()]*\))", inside)]


def test_the_step_lists_every_field_of_x_and_the_log_with_its_unit(header, layout):
    comment = _comment_above(header, "int cdpr_planar2_smooth_step(")
    assert _bracket(comment, "x[11]: state [") == _listed(layout.x, keep=("memory",))
    assert _bracket(comment, "log_out[6]: this period's [") == _listed(
        layout.log, keep=layout.log.names)
    comments = {name: comment for name, (_, comment) in _defines(header).items()}
    assert _bracket(comments["NX"], "x = [") == [
        item.split(" (")[0] for item in _listed(layout.x, keep=("memory",))]
    assert _bracket(comments["NLOG"], "log = [") == [
        item.split(" (")[0] for item in _listed(layout.log, keep=layout.log.names)]


def test_the_parameters_function_takes_and_documents_every_field_of_p(header, layout):
    fields = [name for name in layout.p.names if layout.p.width(name)]
    declaration = _declaration(header, "int cdpr_planar2_smooth_parameters(")
    assert re.findall(r"(\w+)(?:\[\d+\])?(?:, |\))", declaration) == [*fields, "p"]
    comment = _comment_above(header, "int cdpr_planar2_smooth_parameters(")
    comment, returns = comment.split(". p is always written; ")
    assert returns.startswith("returns 0, or -1 when") and "dt <= 0" in returns
    case = re.search(r"above\)\. ([\w, ]+): ([^(]+) \(([^)]+) for angles\), each NULL for the "
                     r"robot's case values; ", comment)
    names, positions, angles = (part.split(", ") for part in case.groups())
    assert names == ["q_goal", "k", "r_d"]
    assert positions == [FIELD_UNITS[name][0] for name in names]
    assert angles == [FIELD_UNITS[name][1] for name in names]
    others = comment[case.end():].split("; ")
    assert [piece.split(":")[0].strip() for piece in others] == fields[len(names):]
    for name, piece in zip(fields[len(names):], others, strict=True):
        if FIELD_UNITS[name]:
            assert piece.endswith(f", {FIELD_UNITS[name][0]}"), piece


def test_the_case_arrays_state_their_units(header):
    units = dict(re.findall(r"_case_(\w+)\[CDPR_PLANAR2_SMOOTH_N\];\s+/\* (.*) \*/", header))
    assert units == {"start": "m (rad for angles)", "goal": "m (rad for angles)",
                     "k": "N/m (N m/rad for angles)", "r_d": "N s/m (N m s/rad for angles)"}


def test_every_field_a_layout_can_declare_is_documented_with_its_unit():
    """A rate-limited layout has the fields an export does not (yet) have: the applied
    tension in x and the rate limit in p; each has its unit and words all the same."""
    model = SymbolicModel(preset("planar2"))
    layout = step_layout(model, controller_by_name("smooth"), rate_limited=True)
    fields = layout_fields(layout)
    assert "applied" in fields["x"] and "rate_limit" in fields["p"]
    for vector in (layout.x, layout.p, layout.log):
        assert set(vector.names) <= set(FIELD_UNITS)
    assert field_list(fields["x"]).split(", ")[-3:] == ["memory", "applied (N)", "status"]
    rate_limit = next(a for a in parameter_arguments(layout.p, fields["p"])
                      if a.name == "rate_limit")
    assert rate_limit.by_value and rate_limit.doc.endswith(", N/s")
    with pytest.raises(InvalidCase, match=r"^controller: the step's field or argument 'mystery'"):
        field_list(["q", "mystery"])
