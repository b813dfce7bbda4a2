"""Runs animated (``Trajectory.animate``, ``cdpr-sym simulate --animate``): one frame per
sample shown, each frame the run's state at that sample, files written frame for frame."""

from __future__ import annotations

import matplotlib
import numpy as np
import pytest
from PIL import Image

from cdpr_sym import Trajectory, preset, simulate
from cdpr_sym.cli import main
from cdpr_sym.errors import InvalidCase
from cdpr_sym.results.animation import frame_steps

matplotlib.use("Agg")


@pytest.fixture(scope="module")
def planar_run():
    return simulate("planar3", "smooth", duration=1.0)


def _as_built_run(robot, controller: str):
    """0.2 s of ``controller`` on ``robot`` as built (the default draw, seed 0, pair 0)."""
    from cdpr_sym.as_built.draw import load_as_built_draw
    from cdpr_sym.calibration.drawn import drawn_robot
    from cdpr_sym.closed_loop import get_simulator
    from cdpr_sym.control import controller_by_name

    drawn = drawn_robot(robot, load_as_built_draw("default"), 0, 0, "none")
    simulator = get_simulator(drawn.model, controller_by_name(controller),
                              as_built=drawn.plant.as_built.structure())
    return simulator.run(robot.start, robot.goal, robot.k, robot.r_d, duration=0.2, dt=1e-3,
                         plant=drawn.plant)


def test_the_frames_are_every_stride_samples_and_the_last():
    """0.5 s per wall-clock second at 20 fps with dt = 1 ms: a frame every 25 samples."""
    steps = frame_steps(1001, 1e-3, fps=20, speed=0.5)
    assert steps.tolist() == [*range(0, 1001, 25)]
    steps = frame_steps(1000, 1e-3, fps=20, speed=0.5)  # 999 is not a multiple of 25
    assert steps.tolist() == [*range(0, 1000, 25), 999]
    assert frame_steps(10, 1e-3, fps=25, speed=1e-6).tolist() == list(range(10))


def test_each_frame_shows_the_runs_state_at_its_sample(planar_run):
    animation = planar_run.animate(fps=10)
    assert animation.steps.tolist() == [*range(0, 1001, 100)]
    robot = preset("planar3")
    for step in (0, 500, 1000):
        animation._frame(step)
        centre = np.column_stack(animation.picture.com.get_data())[0]
        q = planar_run.q[step]
        c, s = np.cos(q[2]), np.sin(q[2])
        expected = q[:2] + np.array([[c, -s], [s, c]]) @ robot.center_of_mass
        np.testing.assert_allclose(centre, expected, atol=1e-12)
        segments = animation.picture.cables.get_segments()
        np.testing.assert_allclose([segment[0] for segment in segments], robot.anchors)
        trace = np.column_stack(animation.picture.trace.get_data())
        assert len(trace) == step + 1
        assert f"t = {planar_run.t[step]:.2f} s" in animation.clock.get_text()


def test_a_gif_has_one_frame_per_sample_shown(planar_run, tmp_path):
    animation = planar_run.animate(fps=20)
    path = tmp_path / "run.gif"
    animation.save(path, dpi=40)
    with Image.open(path) as gif:
        assert gif.n_frames == len(animation.steps) == 21


def test_a_notebook_and_an_html_file_get_the_javascript_player(planar_run, tmp_path):
    animation = planar_run.animate(fps=5, speed=2.0)
    assert len(animation.steps) == 4  # samples 0, 400, 800 and the last, 1000
    shown = animation._repr_html_()
    assert "<script" in shown and shown.count("data:image/png;base64") == 4
    path = tmp_path / "run.html"
    animation.save(path)
    assert path.read_text().count("data:image/png;base64") == 4


def test_an_as_built_run_shows_the_pose_the_controller_read(tmp_path):
    """smooth reads the pose from the encoders as built: the ghost is at q_read, which is
    kept with the run (and through save and load)."""
    robot = preset("aras3")
    run = _as_built_run(robot, "smooth")
    assert run.q_read is not None and run.q_read.shape == run.q.shape
    assert not np.array_equal(run.q_read, run.q)
    animation = run.animate(robot, fps=25)
    animation._frame(100)
    np.testing.assert_array_equal(np.column_stack(animation.picture.ghost.get_data_3d())[0],
                                  run.q_read[100])
    stored = Trajectory.load(run.save(tmp_path / "run"))
    np.testing.assert_array_equal(stored.q_read, run.q_read)


def test_mp4_without_ffmpeg_and_unknown_formats_are_refused(planar_run, monkeypatch, tmp_path):
    from matplotlib import animation as mpl_animation

    monkeypatch.setattr(mpl_animation.writers, "is_available", lambda name: False)
    animation = planar_run.animate()
    with pytest.raises(InvalidCase, match=r"animate: writing \.mp4 needs ffmpeg"):
        animation.save(tmp_path / "run.mp4")
    with pytest.raises(InvalidCase, match="expected an animation file"):
        animation.save(tmp_path / "run.avi")
    assert not list(tmp_path.iterdir())


def test_a_run_of_a_robot_file_needs_its_robot(planar_run):
    from dataclasses import replace

    run = replace(planar_run, info={**planar_run.info, "robot": "my_robot"})
    with pytest.raises(InvalidCase, match="robot: this run's robot 'my_robot' is not a preset"):
        run.animate()
    with pytest.raises(InvalidCase, match="robot: spatial6 has n = 6 and m = 6; the run has 3"):
        run.animate(preset("spatial6"))
    assert run.animate(preset("planar3")).steps[-1] == 1000


def test_simulate_animate_writes_the_gif_and_refuses_bad_formats_first(tmp_path, capsys):
    out = tmp_path / "run.gif"
    assert main(["simulate", "--robot", "planar2", "--controller", "smooth", "--duration",
                 "0.2", "--animate", str(out), "-q"]) == 0
    with Image.open(out) as gif:
        assert gif.n_frames == len(frame_steps(201, 1e-3, fps=25, speed=1.0))
    status = main(["simulate", "--robot", "planar2", "--animate", str(tmp_path / "a.avi")])
    assert status == 2
    assert capsys.readouterr().err.count("\n") == 1


@pytest.mark.slow  # over 2 s in a quick run (fresh build cache)
def test_a_controller_that_reads_the_drives_has_no_read_pose():
    """ida-winch reads the winches, not the pose: its as-built run keeps no q_read (it
    would otherwise stay at the start's reading for the whole run)."""
    run = _as_built_run(preset("aras3"), "ida-winch")
    assert run.q_read is None


@pytest.mark.slow
def test_a_long_html_animation_keeps_every_frame_and_too_many_frames_are_refused(tmp_path):
    run = simulate("aras3", "smooth", duration=10.0)
    animation = run.animate(fps=25)  # 251 frames: over matplotlib's 20 MB embed limit
    path = tmp_path / "run.html"
    animation.save(path, dpi=50)
    assert path.read_text().count("data:image/png;base64") == len(animation.steps) == 251
    with pytest.raises(InvalidCase, match=r"fps: 1001 frames .* at most 600"):
        run.animate(fps=100)


def test_the_cables_are_coloured_against_the_runs_own_box():
    robot = preset("planar3").with_case(t_min=5.0, t_max=34.0)
    run = simulate(robot, "smooth", duration=0.3)
    with pytest.raises(InvalidCase, match=r"robot: this run's tension box \[5, 34\] N"):
        run.animate()
    norm = run.animate(robot).picture.colour_map.norm
    assert (norm.vmin, norm.vmax) == (5.0, 34.0)
