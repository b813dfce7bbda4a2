"""Pictures of a robot (``Robot.draw``, ``cdpr-sym view``): the parts where the geometry puts
them, checked on the rendered pixels, and the numpy scene against the CasADi kinematics."""

from __future__ import annotations

import json

import casadi as ca
import matplotlib
import numpy as np
import pytest
from matplotlib.colors import to_rgba
from matplotlib.figure import Figure
from PIL import Image

from cdpr_sym import preset
from cdpr_sym.cli import main
from cdpr_sym.errors import InvalidCase
from cdpr_sym.model import kinematics
from cdpr_sym.robot import PRESET_NAMES
from cdpr_sym.robot.picture import OUT_OF_BOX_COLOUR, draw_robot, out_of_box
from cdpr_sym.robot.scene import body_faces, scene

matplotlib.use("Agg")

#: How far a drawn pixel's colour may be from the colour asked for (antialiasing and the
#: line's edge), per RGB channel in [0, 1].
COLOUR_TOLERANCE = 0.12


def _pixels(ax) -> np.ndarray:
    """The figure of ``ax`` rendered: an (h, w, 3) array in [0, 1], row 0 at the top."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    canvas = FigureCanvasAgg(ax.figure)
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())[..., :3] / 255.0


def _pixel(image: np.ndarray, ax, point: np.ndarray, reach: int = 0) -> np.ndarray:
    """The colours at a data point of 2-D axes (display y counts from the bottom): the
    pixel there, or with ``reach`` the (2 reach + 1)^2 pixels around it, (k, 3)."""
    x, y = ax.transData.transform(point)
    row, column = image.shape[0] - round(float(y)), round(float(x))
    window = image[row - reach: row + reach + 1, column - reach: column + reach + 1]
    return window.reshape(-1, 3) if reach else image[row, column]


def _pixel_3d(image: np.ndarray, ax, point: np.ndarray, reach: int = 0) -> np.ndarray:
    """The colours at a data point of 3-D axes, projected as matplotlib projects it."""
    from mpl_toolkits.mplot3d import proj3d

    x, y, _ = proj3d.proj_transform(*point, ax.get_proj())
    return _pixel(image, ax, np.array([x, y]), reach)


def _close(colours: np.ndarray, expected) -> bool:
    """Whether any of ``colours`` ((3,) or (k, 3)) is the ``expected`` colour (a line's
    middle pixels are its colour; its edges blend with the background)."""
    gap = np.abs(np.atleast_2d(colours) - np.asarray(to_rgba(expected))[:3])
    return bool(np.any(np.all(gap < COLOUR_TOLERANCE, axis=1)))


def _numpy_pose_points(robot, q: np.ndarray) -> np.ndarray:
    """The attachment points from the CasADi model (the independent reference)."""
    sym = ca.SX.sym("q", robot.n)
    points = ca.Function("points", [sym], [ca.horzcat(*kinematics.attachment_points(robot, sym))])
    return np.array(points(q)).T


@pytest.mark.parametrize("name", PRESET_NAMES)
def test_the_scene_puts_the_attachments_where_the_model_does(name):
    robot = preset(name)
    rng = np.random.default_rng(3)
    for _ in range(5):
        q = rng.uniform(robot.frame_lower, robot.frame_upper)
        parts = scene(robot, q)
        np.testing.assert_allclose(parts.attachments, _numpy_pose_points(robot, q),
                                   rtol=0, atol=1e-12)
        np.testing.assert_allclose(parts.cables[:, 0], robot.anchors)


def test_a_bodys_outline_is_the_hull_of_its_attachments_moved_with_it():
    """planar3's plate: every attachment on the outline (a triangle), moved rigidly."""
    robot = preset("planar3")
    q = np.array([0.2, 1.1, 0.3])
    parts = scene(robot, q)
    (face,) = parts.outline
    hull = {tuple(np.round(point, 12)) for point in face}
    assert hull == {tuple(np.round(point, 12)) for point in parts.attachments}
    # a square with a point inside: the inner point is not on the outline
    square = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0.5, 0.5]], dtype=float)
    (outline,) = body_faces(square)
    assert len(outline) == 4 and [0.5, 0.5] not in outline.tolist()


def test_cables_are_drawn_where_the_geometry_puts_them_in_their_tension_colour():
    """planar2 at a pose: the pixels along each cable have the colour of its tension (the
    colour map over the box), a cable under T_min is red; a pixel away from everything is
    the background."""
    import matplotlib as mpl

    # a box far from zero, so that a colour scale from 0 would show another colour
    robot = preset("planar2").with_case(t_min=10.0, t_max=30.0)
    pose = np.array([0.2, 0.9])
    tensions = np.array([robot.t_min - 0.5, 12.0])
    ax = Figure(figsize=(6, 5), dpi=100).add_subplot()
    draw_robot(robot, pose=pose, ax=ax, tensions=tensions, pyplot=False)
    image = _pixels(ax)
    expected = mpl.cm.ScalarMappable(norm=mpl.colors.Normalize(robot.t_min, robot.t_max),
                                     cmap="viridis").to_rgba(tensions[1])
    second = robot.anchors[1] + 0.5 * (pose - robot.anchors[1])
    assert _close(_pixel(image, ax, second, reach=2), expected)
    # the out-of-box cable is dashed: of points along it, the drawn ones are red
    along = [robot.anchors[0] + s * (pose - robot.anchors[0]) for s in np.linspace(0.2, 0.8, 25)]
    colours = [_pixel(image, ax, point, reach=1) for point in along]
    red = [c for c in colours if _close(c, OUT_OF_BOX_COLOUR)]
    assert 5 <= len(red) < len(colours)  # drawn in dashes
    assert not any(_close(c, expected) for c in colours)
    # below the end-effector, far from every cable: background
    background = _pixel(image, ax, np.array([0.8, 0.1]), reach=3)
    assert np.all(background > 0.99)


def test_a_spatial_robots_cables_are_drawn_between_anchor_and_platform():
    robot = preset("aras3")
    pose = np.array([0.3, -0.5, 2.0])
    ax = Figure(figsize=(6, 5), dpi=100).add_subplot(projection="3d")
    draw_robot(robot, pose=pose, ax=ax, pyplot=False)
    image = _pixels(ax)
    for anchor in robot.anchors:
        assert _close(_pixel_3d(image, ax, anchor + 0.5 * (pose - anchor), reach=2), "0.25")


def test_out_of_box_cables_are_named_and_marked():
    robot = preset("planar3")
    tensions = np.array([1.0, 40.0, 90.0])  # box [2, 80]
    assert out_of_box(robot, tensions).tolist() == [True, False, True]
    ax = draw_robot(robot, tensions=tensions, pyplot=False)
    texts = [text.get_text() for text in ax.texts]
    assert any(text.startswith("cable 1: 1 N < T_min") for text in texts)
    assert any(text.startswith("cable 3: 90 N > T_max") for text in texts)
    assert not any(text.startswith("cable 2") for text in texts)


def test_a_pose_of_the_wrong_size_is_refused_naming_it():
    with pytest.raises(InvalidCase, match="pose"):
        preset("aras3").draw(pose=[0.0, 1.0])
    with pytest.raises(InvalidCase, match="tensions"):
        draw_robot(preset("aras3"), tensions=[1.0, 2.0], pyplot=False)


def test_view_writes_a_picture_and_the_holding_tension(tmp_path, capsys):
    """aras3 at a pose: the PNG is written at the size asked for, and the tensions printed
    are W^-1 m g e_z computed here from the cables' unit vectors."""
    out = tmp_path / "aras3.png"
    pose = [0.3, -0.5, 2.0]
    status = main(["view", "--robot", "aras3", "--pose", *map(str, pose), "--dpi", "50",
                   "--out", str(out), "--json"])
    record = json.loads(capsys.readouterr().out)
    assert status == 0
    robot = preset("aras3")
    units = (robot.anchors - pose) / np.linalg.norm(robot.anchors - pose, axis=1)[:, None]
    expected = np.linalg.solve(units.T, [0.0, 0.0, robot.mass * robot.gravity])
    np.testing.assert_allclose(record["tensions"], expected, rtol=1e-10)
    with Image.open(out) as picture:
        assert picture.format == "PNG" and picture.size[0] > 200 and picture.size[1] > 200


def test_view_draws_a_certificates_boxes_in_their_verdicts_colours(tmp_path, capsys):
    """A certificate of two boxes written here: the proven one's middle is green, the
    disproven one's red, on the picture written."""
    folder = tmp_path / "certificate"
    folder.mkdir()
    (folder / "certificate.json").write_text(json.dumps({"robot": "planar2"}))
    (folder / "boxes.csv").write_text("lower_x,lower_z,upper_x,upper_z,verdict\n"
                                      "-0.9,0.1,-0.5,0.5,feasible\n0.5,0.1,0.9,0.5,infeasible\n")
    out = tmp_path / "planar2.png"
    assert main(["view", "--robot", "planar2", "--certificate", str(folder), "--out",
                 str(out), "-q"]) == 0
    from cdpr_sym.certify.report import read_boxes

    robot = preset("planar2")
    # the same picture on axes we can read back
    boxes = read_boxes(folder, robot)
    assert [code for *_, code in boxes] == [1, -1]
    ax = Figure(figsize=(6, 5), dpi=100).add_subplot()
    draw_robot(robot, ax=ax, boxes=boxes, pyplot=False)
    image = _pixels(ax)
    green, red = _pixel(image, ax, np.array([-0.7, 0.3])), _pixel(image, ax, np.array([0.7, 0.3]))
    assert green[1] > green[0] + 0.1 and green[1] > green[2] + 0.1
    assert red[0] > red[1] + 0.1 and red[0] > red[2] + 0.1


@pytest.mark.parametrize("argv, field", [
    (["--pose", "0", "1"], "pose"),
    (["--out", "picture.jpg"], "out"),
    (["--certificate", "nowhere"], "certificate"),
    (["--dpi", "0"], "dpi"),
])
def test_view_refuses_bad_input_in_one_line(tmp_path, capsys, monkeypatch, argv, field):
    monkeypatch.chdir(tmp_path)
    arguments = ["view", "--robot", "aras3", "--out", "picture.png", *argv]
    assert main(arguments) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and f"error: {field}:" in err
    assert not (tmp_path / "picture.png").exists()


def test_view_refuses_a_certificate_of_another_robot(tmp_path, capsys):
    folder = tmp_path / "certificate"
    folder.mkdir()
    (folder / "certificate.json").write_text(json.dumps({"robot": "aras3"}))
    (folder / "boxes.csv").write_text("lower_x,lower_z,upper_x,upper_z,verdict\n")
    assert main(["view", "--robot", "planar2", "--certificate", str(folder), "--out",
                 str(tmp_path / "p.png")]) == 2
    assert "of robot 'aras3', not 'planar2'" in capsys.readouterr().err


def test_outlines_of_a_bar_a_plate_and_a_solid():
    """Collinear attachments: a bar between the two farthest; coplanar: one polygon, the
    hull in order; a cube's corners: 12 triangles, each on one of its faces."""
    (bar,) = body_faces(np.array([[-0.25, 0.0], [0.25, 0.0], [0.1, 0.0]]))
    assert sorted(bar[:, 0].tolist()) == [-0.25, 0.25]
    hexagon = preset("spatial6").attachments
    (plate,) = body_faces(hexagon)
    assert len(plate) == 6 and {tuple(p) for p in plate} == {tuple(p) for p in hexagon}
    cube = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], dtype=float)
    faces = body_faces(cube)
    assert len(faces) == 12
    for face in faces:  # every triangle lies on a face of the cube (one coordinate fixed)
        assert any(np.ptp(face[:, axis]) == 0 for axis in range(3))


def test_a_pose_outside_the_frame_stays_in_view_and_an_anchor_pose_is_refused(tmp_path,
                                                                                capsys):
    ax = draw_robot(preset("planar2"), pose=[5.0, 5.0], pyplot=False)
    assert ax.get_xlim()[1] >= 5.0 and ax.get_ylim()[1] >= 5.0
    status = main(["view", "--robot", "planar4", "--pose", "-2", "0", "--out",
                   str(tmp_path / "a.png"), "--json"])
    captured = capsys.readouterr()
    assert status == 2 and captured.err.count("\n") == 1 and "pose: the structure matrix W" \
        in captured.err
    assert main(["view", "--robot", "planar4", "--pose", "5", "5", "--out",
                 str(tmp_path / "far" / "b.png"), "--json"]) == 0  # the folder is made
    record = json.loads(capsys.readouterr().out)
    assert record["tension_rule"].startswith("none in the box")
    assert min(record["tensions"]) < 0 and (tmp_path / "far" / "b.png").is_file()


def test_a_certificate_of_another_orientation_and_a_fifo_are_refused(tmp_path, capsys):
    import os

    folder = tmp_path / "certificate"
    folder.mkdir()
    (folder / "certificate.json").write_text(json.dumps({"robot": "planar3",
                                                         "orientation": [0.0]}))
    (folder / "boxes.csv").write_text("lower_x,lower_z,upper_x,upper_z,verdict\n"
                                      "-0.5,0.5,0.5,1.5,feasible\n")
    out = str(tmp_path / "p.png")
    assert main(["view", "--robot", "planar3", "--pose", "0", "1", "0", "--certificate",
                 str(folder), "--out", out, "-q"]) == 0
    assert main(["view", "--robot", "planar3", "--pose", "0", "1", "0.2", "--certificate",
                 str(folder), "--out", out]) == 2
    assert "proven at the orientation [0.0]" in capsys.readouterr().err
    fifo = tmp_path / "fifo.png"
    os.mkfifo(fifo)
    assert main(["view", "--robot", "planar3", "--out", str(fifo)]) == 2
    assert "not a regular file" in capsys.readouterr().err


def test_axes_of_the_wrong_kind_are_refused():
    with pytest.raises(InvalidCase, match="ax: aras3 is drawn on 3-D"):
        preset("aras3").draw(ax=Figure().add_subplot())
    with pytest.raises(InvalidCase, match="ax: planar2 is drawn on 2-D"):
        preset("planar2").draw(ax=Figure().add_subplot(projection="3d"))


def test_the_written_picture_shows_red_only_where_a_cable_leaves_the_box(tmp_path, capsys):
    """The PNG view writes: no pixel of the out-of-box red while every cable holds the
    robot in the box (planar2 at its start); many when both cables would have to push
    (the point above its anchors)."""
    def red_pixels(pose: list[str]) -> int:
        out = tmp_path / f"{'_'.join(pose)}.png"
        assert main(["view", "--robot", "planar2", "--pose", *pose, "--dpi", "60",
                     "--out", str(out), "-q"]) == 0
        with Image.open(out) as picture:
            rgb = np.asarray(picture.convert("RGB")) / 255.0
        red = np.asarray(to_rgba(OUT_OF_BOX_COLOUR)[:3])
        return int(np.sum(np.all(np.abs(rgb - red) < COLOUR_TOLERANCE, axis=2)))

    start = preset("planar2").start
    assert red_pixels([str(v) for v in start]) == 0
    assert red_pixels(["0.0", "2.5"]) > 100
