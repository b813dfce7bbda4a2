"""What a user sees of a Trajectory: repr, the notebook table, the figure, the data frame.

Every run is built by hand with a few samples; the expected strings and numbers are worked
out from the definitions in ``cdpr_sym/results/trajectory.py`` (see the comments).
"""

from __future__ import annotations

import sys

import numpy as np
import pytest

from cdpr_sym import Trajectory
from cdpr_sym.errors import InvalidCase

T_MIN, T_MAX = 2.0, 60.0


def make_run(t, errors, tau, *, stop_reason=None, info=None, flags=None, j=None):
    """A 2-DOF run with goal (0, 0) whose q is (errors[k], 0) at t[k]."""
    t = np.asarray(t, dtype=float)
    errors = np.asarray(errors, dtype=float)
    tau = np.asarray(tau, dtype=float)
    steps = len(t) - 1
    q = np.column_stack([errors, np.zeros_like(errors)])
    return Trajectory(
        t=t, q=q, dq=0.5 * q, tau=tau,
        alpha=np.linspace(1.0, 0.5, steps), beta=np.full(steps, 3.0),
        j=np.zeros((steps, 1)) if j is None else np.asarray(j, dtype=float),
        flags=np.zeros(steps, dtype=np.int64) if flags is None else flags,
        q_goal=np.zeros(2), t_min=T_MIN, t_max=T_MAX, stop_reason=stop_reason,
        info={"robot": "hand-made", "controller": "pd"} if info is None else info)


def settled_run() -> Trajectory:
    # t starts at 0.5 (not 0) so the duration is t[-1] - t[0] = 1.25 - 0.5 = 0.75 s.
    # errors 0.5, 0.2 are outside the 1 cm band, 0.005, 0.003 inside: settles at t[2] = 1.0.
    # tau for t > 0 (rows 1, 2): min 12.5, max 41.25. Steps |tau_k - tau_{k-1}|:
    # (7.5, 25) and (7.5, 11.25): the largest is 25.
    return make_run([0.5, 0.75, 1.0, 1.25], [0.5, 0.2, 0.005, 0.003],
                    [[5.0, 5.0], [12.5, 30.0], [20.0, 41.25]])


def stopped_run() -> Trajectory:
    # no robot/controller in info; stopped early: never settles, not feasible
    return make_run([0.0, 0.1, 0.2], [0.5, 0.3, 0.25], [[10.0, 10.0], [10.0, 14.0]],
                    stop_reason="singular", info={})


def one_step_run() -> Trajectory:
    # a single command (at t = 0): no tension for t > 0, no step between commands
    return make_run([0.0, 0.2], [0.5, 0.5], [[10.0, 10.0]])


def table(*rows: tuple[str, str]) -> str:
    return "<table>" + "".join(f"<tr><td>{k}</td><td>{v}</td></tr>" for k, v in rows) + "</table>"


# -- repr ---------------------------------------------------------------------------------

def test_repr_names_robot_controller_steps_duration_and_size():
    assert repr(settled_run()) == "<Trajectory hand-made / pd: 3 steps, 0.750 s, n = 2>"


def test_repr_of_a_stopped_run_without_names_shows_question_marks_and_the_reason():
    assert repr(stopped_run()) == "<Trajectory ? / ?: 2 steps, 0.200 s, n = 2, stopped: singular>"


# -- notebook table -----------------------------------------------------------------------

def test_html_of_a_settled_run():
    expected = ("<p><code>&lt;Trajectory hand-made / pd: 3 steps, 0.750 s, n = 2&gt;</code></p>"
                + table(("tension for t > 0 [N]", "12.5 .. 41.25 (box 2 .. 60)"),
                        ("tension feasible", "True"),
                        ("settle time [s]", "1"),
                        ("final error", "0.003"),
                        ("largest step [N]", "25"),
                        ("stop reason", "–")))
    assert settled_run()._repr_html_() == expected


def test_html_of_a_stopped_run_says_never_settled_and_why_it_stopped():
    # tau for t > 0 is the one row (10, 14); the one step is (0, 4); final error 0.25
    expected = ("<p><code>&lt;Trajectory ? / ?: 2 steps, 0.200 s, n = 2, stopped: singular&gt;"
                "</code></p>"
                + table(("tension for t > 0 [N]", "10 .. 14 (box 2 .. 60)"),
                        ("tension feasible", "False"),
                        ("settle time [s]", "never"),
                        ("final error", "0.25"),
                        ("largest step [N]", "4"),
                        ("stop reason", "singular")))
    assert stopped_run()._repr_html_() == expected


def test_html_shows_a_dash_for_tensions_that_do_not_exist():
    expected = ("<p><code>&lt;Trajectory hand-made / pd: 1 steps, 0.200 s, n = 2&gt;</code></p>"
                + table(("tension for t > 0 [N]", "– .. – (box 2 .. 60)"),
                        ("tension feasible", "False"),
                        ("settle time [s]", "never"),
                        ("final error", "0.5"),
                        ("largest step [N]", "0"),
                        ("stop reason", "–")))
    assert one_step_run()._repr_html_() == expected


# -- figure -------------------------------------------------------------------------------

def test_plot_has_two_panels_titled_robot_and_controller_by_default():
    figure = settled_run().plot()
    assert len(figure.axes) == 2
    assert figure.axes[0].get_title() == "hand-made / pd"


def test_plot_title_leaves_unknown_names_empty():
    figure = stopped_run().plot()  # info is empty
    assert figure.axes[0].get_title() == " / "


def test_plot_uses_the_given_title_and_adds_an_alpha_panel_on_request():
    figure = settled_run().plot(alpha=True, title="my run")
    assert len(figure.axes) == 3
    assert figure.axes[0].get_title() == "my run"


# -- data frame ---------------------------------------------------------------------------

def test_to_pandas_columns_values_and_the_missing_last_command():
    pytest.importorskip("pandas")
    import pandas as pd
    run = make_run([0.0, 0.1, 0.2], [0.5, 0.3, 0.25], [[10.0, 11.0], [12.0, 13.0]],
                   flags=np.array([8, 3], dtype=np.int64), j=[[0.25], [0.75]])
    frame = run.to_pandas()
    assert list(frame.columns) == ["t", "q_q1", "q_q2", "dq_q1", "dq_q2", "tau_1", "tau_2",
                                   "alpha", "beta", "j_1", "flags"]
    assert len(frame) == 3
    np.testing.assert_allclose(frame["t"], [0.0, 0.1, 0.2])
    np.testing.assert_allclose(frame["q_q1"], [0.5, 0.3, 0.25])
    np.testing.assert_allclose(frame["dq_q1"], [0.25, 0.15, 0.125])
    np.testing.assert_allclose(frame["tau_1"], [10.0, 12.0, np.nan])
    np.testing.assert_allclose(frame["tau_2"], [11.0, 13.0, np.nan])
    np.testing.assert_allclose(frame["alpha"], [1.0, 0.5, np.nan])
    np.testing.assert_allclose(frame["beta"], [3.0, 3.0, np.nan])
    np.testing.assert_allclose(frame["j_1"], [0.25, 0.75, np.nan])
    assert frame["flags"].dtype == pd.Int64Dtype()
    assert frame["flags"].iloc[0] == 8 and frame["flags"].iloc[1] == 3
    assert frame["flags"].iloc[2] is pd.NA


def test_to_pandas_uses_the_coordinate_names_of_the_info():
    pytest.importorskip("pandas")
    run = make_run([0.0, 0.1], [0.5, 0.3], [[10.0, 11.0]],
                   info={"robot": "r", "coordinates": ["x", "z"]})
    assert list(run.to_pandas().columns)[:5] == ["t", "q_x", "q_z", "dq_x", "dq_z"]


def test_to_pandas_flags_stay_integers_for_unsigned_bit_sets():
    pytest.importorskip("pandas")
    import pandas as pd
    run = make_run([0.0, 0.1, 0.2], [0.5, 0.3, 0.25], [[10.0, 11.0], [12.0, 13.0]],
                   flags=np.array([8, 0], dtype=np.uint64))
    flags = run.to_pandas()["flags"]
    assert flags.dtype == pd.Int64Dtype()
    assert flags.iloc[0] == 8 and flags.iloc[1] == 0 and flags.iloc[2] is pd.NA


def test_to_pandas_without_pandas_says_how_to_install_it(monkeypatch):
    monkeypatch.setitem(sys.modules, "pandas", None)  # makes `import pandas` fail
    with pytest.raises(InvalidCase) as caught:
        settled_run().to_pandas()
    assert caught.value.field == "pandas"
    assert str(caught.value) == "pandas: to_pandas needs pandas; pip install 'cdpr_sym[pandas]'"


# -- figure manners: pyplot, axes, labels ---------------------------------------------------

@pytest.fixture()
def pyplot():
    import matplotlib.pyplot as plt

    plt.close("all")
    yield plt
    plt.close("all")


def test_plot_makes_its_figure_through_pyplot_so_notebooks_show_it(pyplot):
    figure = settled_run().plot()
    assert pyplot.get_fignums() == [figure.number]
    assert pyplot.gcf() is figure


def test_plot_labels_the_goal_and_the_tension_bounds_with_units(pyplot):
    run = settled_run()
    positions, tensions = run.plot().axes
    labels = [text.get_text() for text in tensions.get_legend().get_texts()]
    assert f"T_min = {run.t_min:g} N" in labels and f"T_max = {run.t_max:g} N" in labels
    assert "goal" in [text.get_text() for text in positions.get_legend().get_texts()]
    assert tensions.get_ylabel() == "tension [N]" and tensions.get_xlabel() == "time [s]"
    assert positions.get_ylabel() == "position [m]"


def test_plot_draws_into_the_callers_axes(pyplot):
    figure, ax = pyplot.subplots()
    run = settled_run()
    assert run.plot(ax=ax) is figure
    assert ax.get_ylabel() == "tension [N]" and len(ax.lines) == run.tau.shape[1] + 2
    figure, axes = pyplot.subplots(3, 1)
    assert settled_run().plot(ax=axes, alpha=True) is figure
    assert axes[0].get_ylabel() == "position [m]" and axes[2].get_ylabel() == "α (log)"
    assert pyplot.get_fignums() == [1, 2]  # nothing else opened


def test_plot_refuses_axes_of_the_wrong_count(pyplot):
    _figure, axes = pyplot.subplots(2, 1)
    with pytest.raises(InvalidCase) as refused:
        settled_run().plot(ax=axes, alpha=True)
    assert refused.value.field == "ax"
