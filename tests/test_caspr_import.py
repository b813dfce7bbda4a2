"""CASPR models imported (cdpr_sym.caspr, ``cdpr-sym import caspr``).

The XML files under tests/data/caspr/ were written for these tests (invented geometry in
CASPR's format). Every check compares the imported robot with a numpy model written here
from the files' raw numbers and CASPR's own conventions, at CASPR's joint poses: a body
point b (joint frame) is at r_Parent + r_rel(q) + R(q) b; a cable's body point is r_G +
location ("com") or location ("joint"); the inertia tensor has the XML's Ixy as its entry;
gravity is 9.81 m/s^2 along -z.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from scipy.linalg import null_space

from cdpr_sym.caspr import caspr_import, choose_case, import_caspr, pose_from_caspr, read_caspr
from cdpr_sym.cli import main
from cdpr_sym.errors import InvalidCase, InvalidRobot
from cdpr_sym.geometry.sampled import static_margins
from cdpr_sym.model import SymbolicModel
from cdpr_sym.robot import load_robot

DATA = Path(__file__).parent / "data" / "caspr"
G = 9.81

#: (model, cable set) of every file pair that imports.
MODELS = [("point3", None), ("point2", None), ("spatial6", None), ("spatial8", None),
          ("spatial8", "straight"), ("planar3", None), ("planar_yz", None)]
IDS = [name if cable_set is None else f"{name}-{cable_set}" for name, cable_set in MODELS]

#: The rows of the world wrench (force, moment about the centre of mass) the cables must
#: balance for each joint: the others are held by the joint itself.
ROWS = {"T_XYZ": [0, 1, 2], "P_XZ": [0, 2], "PLANAR_XZ": [0, 2, 4], "PLANAR_YZ": [1, 2, 3],
        "SPATIAL_EULER_XYZ": [0, 1, 2, 3, 4, 5]}


# -- CASPR's model in numpy, from the raw XML ---------------------------------------------

def _vector(text: str) -> np.ndarray:
    return np.array([float(word) for word in text.split()])


def _rx(a: float) -> np.ndarray:
    return np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])


def _ry(a: float) -> np.ndarray:
    return np.array([[math.cos(a), 0, math.sin(a)], [0, 1, 0], [-math.sin(a), 0, math.cos(a)]])


def _rz(a: float) -> np.ndarray:
    return np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])


class Caspr:
    """A CASPR model from its files' raw numbers, posed by CASPR's joint coordinates."""

    def __init__(self, name: str, cable_set: str | None = None) -> None:
        link = ET.parse(DATA / f"{name}_bodies.xml").getroot().find("links/link_rigid")
        joint = link.find("joint")
        self.joint = joint.get("type")
        self.q_initial = _vector(joint.get("q_initial"))
        physical = link.find("physical")
        self.mass = float(physical.find("mass").text)
        self.r_G = _vector(physical.find("com_location").text)
        inertia = physical.find("inertia")
        e = {tag: float(inertia.find(tag).text) for tag in ("Ixx", "Iyy", "Izz", "Ixy", "Ixz",
                                                             "Iyz")}
        tensor = np.array([[e["Ixx"], e["Ixy"], e["Ixz"]], [e["Ixy"], e["Iyy"], e["Iyz"]],
                           [e["Ixz"], e["Iyz"], e["Izz"]]])
        if inertia.get("ref") == "joint":  # moved to the centre of mass (parallel axes)
            tensor -= self.mass * (self.r_G @ self.r_G * np.eye(3) - np.outer(self.r_G, self.r_G))
        self.I_G = tensor
        self.parent = _vector(link.find("parent/location").text)
        root = ET.parse(DATA / f"{name}_cables.xml").getroot()
        wanted = cable_set or root.get("default_cable_set")
        chosen = next(s for s in root.findall("cable_set") if s.get("id") == wanted)
        anchors, body = [], []
        for cable in chosen:
            points = {p.find("link").text: _vector(p.find("location").text)
                      for p in cable.find("attachments")}
            anchors.append(points["0"])
            reference = cable.get("attachment_reference")
            body.append(self.r_G + points["1"] if reference == "com" else points["1"])
        self.anchors, self.body = np.array(anchors), np.array(body)
        properties = chosen[0].find("properties")
        self.force = (float(properties.find("force_min").text),
                      float(properties.find("force_max").text))

    def rotation(self, q: np.ndarray) -> np.ndarray:
        if self.joint == "PLANAR_XZ":
            return _ry(q[2])
        if self.joint == "PLANAR_YZ":
            return _rx(q[2])
        if self.joint == "SPATIAL_EULER_XYZ":
            return _rx(q[3]) @ _ry(q[4]) @ _rz(q[5])
        return np.eye(3)

    def origin(self, q: np.ndarray) -> np.ndarray:
        relative = {"T_XYZ": q[:3], "P_XZ": np.array([q[0], 0, q[1]]),
                    "PLANAR_XZ": np.array([q[0], 0, q[1]]),
                    "PLANAR_YZ": np.array([0, q[0], q[1]]), "SPATIAL_EULER_XYZ": q[:3]}
        return self.parent + relative[self.joint]

    def points(self, q: np.ndarray) -> np.ndarray:
        return self.origin(q) + self.body @ self.rotation(q).T

    def com(self, q: np.ndarray) -> np.ndarray:
        return self.origin(q) + self.rotation(q) @ self.r_G

    def lengths(self, q: np.ndarray) -> np.ndarray:
        return np.linalg.norm(self.anchors - self.points(q), axis=1)

    def wrench_matrix(self, q: np.ndarray) -> np.ndarray:
        """Column i: cable i's unit pull and its moment about the centre of mass, (6, m)."""
        points = self.points(q)
        units = (self.anchors - points) / self.lengths(q)[:, None]
        moments = np.cross(points - self.com(q), units)
        return np.vstack([units.T, moments.T])

    def weight_held(self) -> np.ndarray:
        """What the cables must supply to hold the weight: (0, 0, m g) and no moment about
        the centre of mass."""
        return np.array([0.0, 0.0, self.mass * G, 0.0, 0.0, 0.0])

    def kinetic_energy(self, q: np.ndarray, dq: np.ndarray, h: float = 1e-6) -> float:
        v = (self.com(q + h * dq) - self.com(q - h * dq)) / (2 * h)
        R = self.rotation(q)
        dR = (self.rotation(q + h * dq) - self.rotation(q - h * dq)) / (2 * h)
        spin = dR @ R.T  # [w]x in the world
        w_body = R.T @ np.array([spin[2, 1], spin[0, 2], spin[1, 0]])
        return 0.5 * self.mass * v @ v + 0.5 * w_body @ self.I_G @ w_body


def _files(name: str) -> tuple[Path, Path]:
    return DATA / f"{name}_bodies.xml", DATA / f"{name}_cables.xml"


def _poses(caspr: Caspr, count: int = 6, seed: int = 1) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return caspr.q_initial + rng.uniform(-0.3, 0.3, (count, len(caspr.q_initial)))


def _evaluate(function, q: np.ndarray) -> np.ndarray:
    return np.array(function(q))


class _Imported(dict):
    """Each model imported on first use (once per module), with its numpy twin and the
    toolkit's model functions: a model that fails to import fails its own tests only."""

    def __missing__(self, key: str) -> tuple:
        name, cable_set = MODELS[IDS.index(key)]
        result = caspr_import(*_files(name), cable_set=cable_set)
        self[key] = (result, Caspr(name, cable_set), SymbolicModel(result.robot).functions)
        return self[key]


@pytest.fixture(scope="module")
def imported() -> dict:
    return _Imported()


# -- the conversions -----------------------------------------------------------------------

@pytest.mark.parametrize("key", IDS)
def test_cable_lengths_equal_caspr_kinematics_at_random_caspr_poses(imported, key):
    result, caspr, functions = imported[key]
    for q_c in _poses(caspr):
        q = pose_from_caspr(result.model, q_c)
        lengths = _evaluate(functions["cable_lengths"], q).ravel()
        np.testing.assert_allclose(lengths, caspr.lengths(q_c), rtol=0, atol=1e-12)


@pytest.mark.parametrize("key", IDS)
def test_the_static_tension_holds_the_weight_in_caspr_statics(imported, key):
    """m = n: the toolkit's unique tension is numpy's solution of CASPR's equilibrium;
    m > n: a tension of the toolkit's W T = grad V holds numpy's weight, and the toolkit's
    internal tensions (null space of W) move nothing in CASPR's statics."""
    result, caspr, functions = imported[key]
    rows = ROWS[caspr.joint]
    for q_c in _poses(caspr):
        q = pose_from_caspr(result.model, q_c)
        W_c, held = caspr.wrench_matrix(q_c)[rows], caspr.weight_held()[rows]
        if result.robot.m == result.robot.n:
            tension = _evaluate(functions["static_tension"], q).ravel()
            np.testing.assert_allclose(tension, np.linalg.solve(W_c, held), rtol=1e-9,
                                       atol=1e-9)
        else:
            W = _evaluate(functions["structure_matrix"], q)
            grad_V = _evaluate(functions["grad_potential"], q).ravel()
            tension = np.linalg.lstsq(W, grad_V, rcond=None)[0]
            np.testing.assert_allclose(W_c @ tension, held, rtol=0, atol=1e-9)
            np.testing.assert_allclose(W_c @ null_space(W), 0, atol=1e-12)


@pytest.mark.parametrize("key", IDS)
def test_the_kinetic_energy_equals_caspr_mass_and_inertia(imported, key):
    """The inertia tensor (its Ixy entry, ref="joint" moved to the centre of mass), the
    centre of mass and the orientation map, through the energy of a random motion."""
    result, caspr, functions = imported[key]
    rng = np.random.default_rng(2)
    for q_c in _poses(caspr, count=4):
        dq_c = rng.uniform(-1, 1, len(q_c))
        h = 1e-6
        q = pose_from_caspr(result.model, q_c)
        dq = (pose_from_caspr(result.model, q_c + h * dq_c)
              - pose_from_caspr(result.model, q_c - h * dq_c)) / (2 * h)
        energy = float(np.array(functions["kinetic_energy"](q, dq)).item())
        np.testing.assert_allclose(energy, caspr.kinetic_energy(q_c, dq_c), rtol=1e-7)


def test_the_inertia_entry_ixy_is_the_tensor_entry():
    model = read_caspr(*_files("spatial6"))
    assert model.inertia[0, 1] == model.inertia[1, 0] == -0.04


def test_the_point_mass_anchors_are_shifted_by_the_attachments_from_the_com():
    caspr = Caspr("point3")
    robot = import_caspr(*_files("point3"))
    np.testing.assert_allclose(robot.anchors, caspr.anchors - caspr.body, atol=1e-15)
    assert np.abs(caspr.body - caspr.r_G).max() > 0  # the com shift is exercised


@pytest.mark.parametrize(("name", "lower", "upper"), [
    ("spatial6", [-1.3, -1.6, 0.0, -math.pi / 4, -math.pi / 4, -math.pi / 4],
     [1.7, 1.4, 3.0, math.pi / 4, math.pi / 4, math.pi / 4]),
    ("spatial8", [-2.0, -1.6, 0.4, -0.5, -0.5, -0.5], [2.0, 1.6, 2.2, 0.5, 0.5, 0.5]),
    ("planar3", [0.05 - 1.5, 0.2, -0.5], [0.05 + 1.5, 2.8, 0.5]),
])
def test_the_frame_is_caspr_range_moved_by_the_parent_with_angles_within_a_quarter_turn(
        name, lower, upper):
    robot = import_caspr(*_files(name))
    np.testing.assert_allclose(robot.frame_lower, lower, atol=1e-12)
    np.testing.assert_allclose(robot.frame_upper, upper, atol=1e-12)


def test_an_infinite_side_of_the_frame_comes_from_the_anchors_box():
    """point3: x and y unbounded in CASPR (the shifted anchors' box), z from 0 (parent
    z = 0.3) up to the top anchor (z's range is flat, so it reaches down: not used here)."""
    caspr = Caspr("point3")
    robot = import_caspr(*_files("point3"))
    shifted = caspr.anchors - caspr.body
    np.testing.assert_allclose(robot.frame_lower, [*shifted.min(axis=0)[:2], 0.3])
    np.testing.assert_allclose(robot.frame_upper, shifted.max(axis=0))


def test_the_cable_set_option_picks_the_set_named():
    default = read_caspr(*_files("spatial8"))
    straight = read_caspr(*_files("spatial8"), cable_set="straight")
    assert (default.cable_set, straight.cable_set) == ("crossed", "straight")
    np.testing.assert_array_equal(straight.attachments, Caspr("spatial8", "straight").body)
    assert not np.allclose(default.attachments, straight.attachments)


# -- the case ------------------------------------------------------------------------------

@pytest.mark.parametrize("key", IDS)
def test_the_case_starts_at_q_initial_and_both_ends_hold_the_platform(imported, key):
    result, _, _ = imported[key]
    robot = result.robot
    assert result.case.start_rule == "CASPR's q_initial"
    np.testing.assert_array_equal(robot.start, pose_from_caspr(result.model,
                                                               result.model.q_initial))
    assert np.all(static_margins(robot, np.array([robot.start, robot.goal])) > 0)
    d = robot.dimension
    diagonal = np.linalg.norm(robot.frame_upper[:d] - robot.frame_lower[:d])
    assert np.linalg.norm(robot.goal[:d] - robot.start[:d]) >= diagonal / 4


def test_an_unusable_q_initial_gives_the_nearest_feasible_sample(imported):
    robot = imported["point3"][0].robot
    case = choose_case(robot, [0.0, 0.0, 50.0])
    assert case.start_rule.startswith("the feasible sample nearest")
    assert "frame" in case.start_rule and case.start_margin > 0


def test_a_given_start_and_goal_are_kept():
    robot = import_caspr(*_files("planar3"), start=[0.0, 1.3, 0.05], goal=[0.3, 1.8, 0.0])
    np.testing.assert_array_equal(robot.start, [0.0, 1.3, 0.05])
    np.testing.assert_array_equal(robot.goal, [0.3, 1.8, 0.0])


@pytest.mark.parametrize(("start", "words"), [([0.0, 5.0, 0.0], "inside the frame"),
                                              ([1.5, 2.7, 0.0], "cannot rest"),
                                              ([0.0, 1.0], "expected 3 values")])
def test_a_bad_start_is_refused_naming_it(start, words):
    with pytest.raises(InvalidCase, match=words) as refusal:
        import_caspr(*_files("planar3"), start=start)
    assert refusal.value.field == "start"


# -- the command ---------------------------------------------------------------------------

def _run(capsys, *argv: str) -> tuple[int, str, str]:
    status = main(list(argv))
    captured = capsys.readouterr()
    return status, captured.out, captured.err


@pytest.mark.parametrize(("name", "cable_set"), MODELS, ids=IDS)
def test_the_written_file_loads_back_into_the_imported_robot(capsys, tmp_path, name,
                                                             cable_set):
    out = tmp_path / "robot.toml"
    extra = ["--cable-set", cable_set] if cable_set else []
    status, text, err = _run(capsys, "import", "caspr", *map(str, _files(name)), *extra,
                             "--out", str(out))
    assert (status, err) == (0, "")
    assert f"written: {out}" in text
    loaded = load_robot(out)
    robot = import_caspr(*_files(name), cable_set=cable_set)
    assert loaded.name == name and loaded.kind == robot.kind
    for field in ("anchors", "attachments", "inertia", "center_of_mass", "frame_lower",
                  "frame_upper", "start", "goal", "k", "r_d"):
        expected = getattr(robot, field)
        if expected is None:
            assert getattr(loaded, field) is None
        else:
            np.testing.assert_array_equal(getattr(loaded, field), expected)
    assert (loaded.mass, loaded.gravity, loaded.t_min, loaded.t_max) == (
        robot.mass, 9.81, robot.t_min, robot.t_max)
    written = out.read_text()
    assert "\nk =" not in written and "\nr_d =" not in written  # gains derived on loading
    assert "# Start: CASPR's q_initial." in written


def test_json_prints_one_object_naming_the_conversion(capsys, tmp_path):
    import json

    status, text, _ = _run(capsys, "import", "caspr", *map(str, _files("planar3")),
                           "--model", "bar", "--json", "--out", str(tmp_path / "bar.toml"))
    value = json.loads(text)
    assert status == 0 and value["robot"] == "bar" and value["kind"] == "planar"
    assert value["conversion"].startswith("PLANAR_XZ") and "-theta" in value["conversion"]
    assert value["case"]["start_rule"] == "CASPR's q_initial"


REFUSALS = [
    ("refuse_two_links", "point3", [], "bodies.link_rigid", "one rigid link"),
    ("refuse_revolute", "point3", [], "bodies.joint", "R_X"),
    ("refuse_planar_xy", "point3", [], "bodies.joint", "horizontal"),
    ("refuse_actuated", "point3", [], "bodies.joint", "actuated"),
    ("refuse_not_xml", "point3", [], "bodies", "not an XML file"),
    ("point3", "refuse_routed", [], "cables.attachments", "runs through 3 points"),
    ("point3", "refuse_pulley", [], "cables.attachments", "pulleys"),
    ("point3", "refuse_link2", [], "cables.attachments", "link 2"),
    ("point3", "refuse_vsd", [], "cables.cable_vsd_torsion_spring", "cable 2"),
    ("point3", "refuse_limits", [], "cables.force_max", "winch 1"),
    ("point3", "refuse_weak", [], "case", "no pose of the frame holds the platform"),
    ("planar3", "refuse_off_plane", [], "cables.attachments", "leaves the plane"),
    ("point3", "point3", ["--cable-set", "spare"], "cables.cable_set", "'spare'"),
    ("point3", "point3", ["--start", "0", "0", "9"], "start", "inside the frame"),
    ("point3", "point3", ["--goal", "1.4", "1.2", "1.0"], "goal", "cannot rest"),
    ("point3", "point3", ["--model", "a\nb"], "model", "printable"),
    ("no_such", "point3", [], "bodies", "no file"),
]


@pytest.mark.parametrize(("bodies", "cables", "extra", "field", "words"), REFUSALS,
                         ids=[row[3] + "-" + row[4][:20] for row in REFUSALS])
def test_every_refusal_exits_2_with_one_line_naming_the_field(capsys, tmp_path, bodies,
                                                              cables, extra, field, words):
    out = tmp_path / "robot.toml"
    status, text, err = _run(capsys, "import", "caspr", str(DATA / f"{bodies}_bodies.xml"),
                             str(DATA / f"{cables}_cables.xml"), *extra, "--out", str(out))
    assert status == 2 and text == ""
    assert err.count("\n") == 1 and err.startswith(f"cdpr-sym: error: {field}: "), err
    assert words in err
    assert not out.exists()


@pytest.mark.parametrize(("out", "words"), [("robot.json", "ending in .toml"),
                                            ("folder.toml", "got the folder")])
def test_a_bad_out_path_is_refused_before_reading(capsys, tmp_path, out, words):
    (tmp_path / "folder.toml").mkdir()
    status, _, err = _run(capsys, "import", "caspr", "missing.xml", "missing.xml", "--out",
                          str(tmp_path / out))
    assert status == 2 and err.startswith("cdpr-sym: error: out: ") and words in err


def test_a_file_over_the_size_cap_is_refused_unparsed(tmp_path):
    big = tmp_path / "big_bodies.xml"
    big.write_bytes(b"<bodies_system>" + b" " * (1 << 20) + b"</bodies_system>")
    with pytest.raises(InvalidRobot, match="larger than 1 MiB") as refusal:
        read_caspr(big, DATA / "point3_cables.xml")
    assert refusal.value.field == "bodies"
