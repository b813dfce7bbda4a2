"""The exported header documents each public function in a comment above it: what it does,
and for the step the sizes of its arrays, worked out by hand for planar2 with smooth
(x = q 2 + dq 2 + memory 5 + status 1; p = goal 2 + k 2 + r_d 2 + dt + mass + slack;
log = tau 2 + alpha + beta + j 1 + flags)."""

from __future__ import annotations

import re

import pytest

from cdpr_sym.export import export_c


@pytest.fixture(scope="module")
def header(tmp_path_factory) -> str:
    result = export_c("planar2", "smooth", tmp_path_factory.mktemp("export") / "pkg")
    return result.header.read_text()


def _comment_above(header: str, declaration: str) -> str:
    """The comment right above ``declaration``, its lines joined by single spaces."""
    before = header[: header.index(declaration)]
    comment = before[before.rindex("/*"): before.rindex("*/")]
    lines = [line.strip().lstrip("/*").strip() for line in comment.splitlines()]
    return re.sub(r"\s+", " ", " ".join(lines)).strip()


def test_the_step_says_what_one_period_does_and_its_sizes(header):
    assert _comment_above(header, "int cdpr_planar2_smooth_step(").startswith(
        "One closed-loop period of dt = p[P_DT] s: the tension of the control law, held over "
        "one RK4 step of the plant (x: 10, p: 9, log: 6 doubles; x and x_next must not "
        "overlap).")


def test_the_initial_memory_says_what_it_holds_and_where_it_goes(header):
    assert _comment_above(header, "int cdpr_planar2_smooth_initial_memory(").startswith(
        "The controller's internal state at the start of a move (its plan, computed once per "
        "move; put it into x[X_MEMORY] or pass it to _control).")


def test_the_control_call_says_what_it_commands(header):
    assert _comment_above(header, "int cdpr_planar2_smooth_control(").startswith(
        "One control step: the tension commanded at the state (q, dq) for the goal q_goal.")
