"""Robot files: the TOML layout of a robot (docs/guide/tour.md, "Robot files"), presets and
loading."""

from __future__ import annotations

import dataclasses
import functools
import os
import re
import stat
import tomllib
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from cdpr_sym.errors import InvalidRobot, UnknownName
from cdpr_sym.robot.description import Robot
from cdpr_sym.robot.gains import case_gains
from cdpr_sym.robot.target import TARGET_FIELDS

PRESET_NAMES = ("aras3", "planar2", "planar3", "spatial6", "planar4", "spatial4", "ipanema8")
#: Bundled robots with fewer cables than degrees of freedom (:mod:`cdpr_sym.underactuated`):
#: a planar bar on two cables and a 6-DOF platform on three. Kept apart from
#: :data:`PRESET_NAMES`, whose robots every design of m >= n cables runs.
UNDERACTUATED_PRESETS = ("bar2", "tri3")

#: Largest robot file read, bytes (1 MiB; the presets are under 2 KiB). A larger file, or
#: anything that is not a regular file (a device, a FIFO), is refused before it is read.
MAX_ROBOT_FILE_BYTES = 1 << 20


def robot_from_dict(data: dict[str, Any], *, source: str = "<dict>") -> Robot:
    """Build a :class:`Robot` from the robot-file layout (docs/guide/tour.md, "Robot files")."""
    _check_known_fields(data, source)
    body = data.get("body", {})
    wrench = data.get("wrench", {})
    encoders = data.get("encoders", {})
    if "body" in data and "attachments" not in body:
        raise InvalidRobot("body.attachments", f"required field missing in {source} (a [body] "
                           "table makes the end-effector a rigid body)")
    if "attachments" in body and "inertia" not in body:
        raise InvalidRobot("body.inertia", f"required field missing in {source}")

    def get(path: str, default: Any = None) -> Any:
        node: Any = data
        for key in path.split("."):
            if not isinstance(node, dict):
                raise InvalidRobot(path, f"expected a table above {key!r} in {source}")
            if key not in node:
                if default is not None:
                    return default
                raise InvalidRobot(path, f"required field missing in {source}")
            node = node[key]
        return node

    case = data.get("case", {})
    stated = {gain: get(f"case.{gain}") for gain in ("k", "r_d")
              if isinstance(case, dict) and gain in case}
    start = get("case.start")
    # until the gains a file leaves out are derived: ones of the start's size
    placeholder = [1.0] * len(start) if isinstance(start, list) else 1.0
    try:
        robot = Robot(
            name=data.get("name", Path(source).stem),
            anchors=get("anchors"), mass=get("mass"), gravity=get("gravity", 9.81),
            t_min=get("tension.min"), t_max=get("tension.max"),
            frame_lower=get("frame.lower"), frame_upper=get("frame.upper"),
            start=start, goal=get("case.goal"),
            k=stated.get("k", placeholder), r_d=stated.get("r_d", placeholder),
            attachments=body.get("attachments"), inertia=body.get("inertia"),
            center_of_mass=body.get("center_of_mass"),
            external_force=wrench.get("force"), external_moment=wrench.get("moment"),
            encoder_offsets=encoders.get("offsets"),
            # the fields a [target] table states; the Robot derives the rest from the box
            target=data.get("target") or None,
        )
    except InvalidRobot as error:  # named as the file names it (frame.lower, not frame_lower)
        raise InvalidRobot(FILE_KEYS.get(error.field, error.field),
                           _file_words(error.message)) from None
    if len(stated) == 2:
        return robot
    # the gains the file leaves out, from the robot (cdpr_sym.robot.gains)
    k, r_d = case_gains(robot.mass, robot.inertia, robot.n, robot.dimension,
                        robot.center_of_mass)
    return dataclasses.replace(robot, k=np.asarray(stated.get("k", k), dtype=float),
                               r_d=np.asarray(stated.get("r_d", r_d), dtype=float))


#: The robot file's key of each :class:`Robot` field that :class:`Robot`'s checks name by
#: its attribute (the body, wrench and encoder fields they already name by the file's key).
FILE_KEYS = {"t_min": "tension.min", "t_max": "tension.max", "frame_lower": "frame.lower",
             "frame_upper": "frame.upper", "start": "case.start", "goal": "case.goal",
             "k": "case.k", "r_d": "case.r_d"}


def _file_words(message: str) -> str:
    """``message`` with the attribute names a file does not use (t_min, frame_lower, ...)
    written as its keys; the one-letter ones are left alone (k would match the word)."""
    for attribute in ("t_min", "t_max", "frame_lower", "frame_upper"):
        message = re.sub(rf"\b{attribute}\b", FILE_KEYS[attribute], message)
    return message


#: The robot-file layout: top-level fields, and the fields of each table.
FILE_FIELDS = {"": {"name", "mass", "gravity", "anchors", "tension", "frame", "case", "body",
                    "wrench", "encoders", "target"},
               "tension": {"min", "max"}, "frame": {"lower", "upper"},
               "case": {"start", "goal", "k", "r_d"},
               "body": {"attachments", "inertia", "center_of_mass"},
               "wrench": {"force", "moment"}, "encoders": {"offsets"},
               "target": set(TARGET_FIELDS)}


def _check_known_fields(data: dict[str, Any], source: str) -> None:
    """Refuse a misspelt or unknown field anywhere in a robot file, naming it."""
    for table, known in FILE_FIELDS.items():
        node = data if not table else data.get(table, {})
        if not isinstance(node, dict):
            raise InvalidRobot(table, f"expected a table in {source}, got {node!r}")
        unknown = sorted(set(node) - known)
        if unknown:
            key = _key_text(unknown[0])
            raise InvalidRobot(f"{table}.{key}" if table else key,
                               f"unknown field in {source}; expected one of "
                               f"{', '.join(sorted(known))}")


def _key_text(key: str) -> str:
    """A key of a robot file as it can be named in a one-line message (quoted unless bare)."""
    shown = key if key.isidentifier() and key.isascii() else repr(key)
    return shown if len(shown) <= 60 else shown[:57] + "..."


def read_robot_text(path: Path) -> str:
    """The text of a robot file: a regular file of at most :data:`MAX_ROBOT_FILE_BYTES`.

    The file is opened without blocking (a FIFO would otherwise wait for a writer) and
    checked to be a regular file before anything is read; at most the cap plus one byte is
    ever read, so a device that never ends (``/dev/zero``) cannot fill the memory.

    Raises
    ------
    InvalidRobot
        Field ``path``: missing, a folder, not a regular file, too large, unreadable or not
        UTF-8.
    """
    try:
        descriptor = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except FileNotFoundError:
        raise InvalidRobot("path", f"no robot file at {path}") from None
    except IsADirectoryError:
        raise InvalidRobot("path", f"{path} is a folder, not a robot file") from None
    except OSError as failure:
        raise InvalidRobot("path", f"cannot read {path}: {failure.strerror}") from None
    # a folder opens read-only on Linux, and os.fdopen then refuses it with an errno that
    # names the descriptor: look at the kind of file before wrapping it
    mode = os.fstat(descriptor).st_mode
    if not stat.S_ISREG(mode):
        os.close(descriptor)
        if stat.S_ISDIR(mode):
            raise InvalidRobot("path", f"{path} is a folder, not a robot file")
        raise InvalidRobot("path", f"{path} is not a regular file (a device, FIFO or "
                           "socket); expected a robot TOML file")
    with os.fdopen(descriptor, "rb") as handle:
        try:
            data = handle.read(MAX_ROBOT_FILE_BYTES + 1)
        except OSError as failure:
            raise InvalidRobot("path", f"cannot read {path}: {failure.strerror}") from None
    if len(data) > MAX_ROBOT_FILE_BYTES:
        raise InvalidRobot("path", f"{path} is larger than "
                           f"{MAX_ROBOT_FILE_BYTES / (1 << 20):g} MiB, the most a robot file "
                           "may hold")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        raise InvalidRobot("path", f"{path} is not a UTF-8 text file") from None


def load_robot(path: str | Path) -> Robot:
    """Load and validate a robot description from a TOML file.

    Parameters
    ----------
    path : str or Path
        A TOML file in the robot-file layout (docs/guide/tour.md, "Robot files").

    Returns
    -------
    Robot
        The validated description.

    Raises
    ------
    InvalidRobot
        The file is missing, unreadable, not a regular file, larger than
        :data:`MAX_ROBOT_FILE_BYTES`, not UTF-8 TOML, nested too deeply, or a field is
        wrong; the error names the field (``path`` for the file itself).

    Examples
    --------
    >>> from importlib import resources
    >>> robot = load_robot(resources.files("cdpr_sym.robot.presets") / "planar2.toml")
    >>> robot.name, robot.n
    ('planar2', 2)
    """
    path = Path(path)
    text = read_robot_text(path)
    try:
        data = tomllib.loads(text)
        return robot_from_dict(data, source=str(path))
    except tomllib.TOMLDecodeError as bad:
        raise InvalidRobot("path", f"{path} is not valid TOML: {bad}") from None
    except RecursionError:
        raise InvalidRobot("path", f"{path} nests arrays or tables too deeply to be a robot "
                           "file") from None


def preset(name: str) -> Robot:
    """A bundled robot by name.

    Parameters
    ----------
    name : str
        One of :data:`PRESET_NAMES`: ``aras3`` (the paper's Section IV robot), ``planar2``
        (a planar point mass on two cables), ``planar3`` (a planar rigid body on three
        cables), ``spatial6`` (a suspended 6-DOF platform on six cables), and with more
        cables than degrees of freedom ``planar4`` (a planar point mass on four cables),
        ``spatial4`` (aras3's frame with a fourth cable) and ``ipanema8`` (a 6-DOF
        platform on eight cables); or, with fewer (:data:`UNDERACTUATED_PRESETS`), ``bar2``
        (a planar bar on two cables) and ``tri3`` (a 6-DOF platform on three).

    Returns
    -------
    Robot

    Raises
    ------
    UnknownName
        ``name`` is not a preset.

    Examples
    --------
    >>> preset("aras3").mass
    4.0
    """
    if name not in PRESET_NAMES + UNDERACTUATED_PRESETS:
        raise UnknownName(f"unknown preset {name!r}; expected one of "
                          f"{', '.join(PRESET_NAMES + UNDERACTUATED_PRESETS)}")
    return _bundled(name)


@functools.cache
def _bundled(name: str) -> Robot:
    """A preset read once per process: robots are frozen (read-only arrays), and parsing
    the file was 1 ms of every ``simulate("aras3", ...)`` call."""
    text = resources.files("cdpr_sym.robot.presets").joinpath(f"{name}.toml").read_text()
    return robot_from_dict(tomllib.loads(text), source=f"{name}.toml")


def resolve_robot(name_or_path: Robot | str | Path) -> Robot:
    """A preset by name, or else a TOML file by path; a :class:`Robot` as it is (every
    function that takes a robot, its name or its file coerces it here).

    Parameters
    ----------
    name_or_path : Robot, str or Path
        A robot, a preset name (:data:`PRESET_NAMES`) or a robot TOML file.

    Returns
    -------
    Robot

    Raises
    ------
    UnknownName
        Neither a preset nor a path to a ``.toml`` file.
    InvalidRobot
        The file is missing or malformed.
    """
    if isinstance(name_or_path, Robot):
        return name_or_path
    if str(name_or_path) in PRESET_NAMES + UNDERACTUATED_PRESETS:
        return preset(str(name_or_path))
    if Path(name_or_path).suffix == ".toml" or Path(name_or_path).exists():
        return load_robot(name_or_path)
    raise UnknownName(
        f"unknown robot {str(name_or_path)!r}; expected a preset "
        f"({', '.join(PRESET_NAMES)}) or a path to a .toml file")


def _toml_value(value: Any) -> str:
    """A number, text or (nested) list of numbers in TOML; floats keep every digit
    (``repr``), so a written robot loads back equal."""
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml_value(item) for item in value) + "]"
    return repr(float(value))


def _toml_rows(rows: list[list[float]]) -> str:
    """An array of rows, one row per line (anchors, attachments)."""
    return "[\n" + "".join(f"    {_toml_value(row)},\n" for row in rows) + "]"


def robot_file_text(robot: Robot, *, comment: str = "", gains: bool = True) -> str:
    """The robot-file TOML of ``robot`` (docs/guide/tour.md, "Robot files"):
    :func:`load_robot` reads it back into an equal robot. ``comment`` (lines of text) heads
    the file as ``#`` lines. Without ``gains`` the file leaves out ``[case] k`` and ``r_d``,
    so loading it derives them (:mod:`cdpr_sym.robot.gains`): equal to the robot's only if
    the robot's are the derived ones."""
    data = robot.as_dict()
    lines = [f"# {line}" for line in comment.splitlines()]
    lines += [f"name = {_toml_value(robot.name)}", f"mass = {_toml_value(robot.mass)}",
              f"gravity = {_toml_value(robot.gravity)}",
              f"anchors = {_toml_rows(data['anchors'])}", "",
              "[tension]", f"min = {_toml_value(robot.t_min)}", f"max = {_toml_value(robot.t_max)}",
              "", "[frame]", f"lower = {_toml_value(data['frame_lower'])}",
              f"upper = {_toml_value(data['frame_upper'])}", "", "[case]"]
    lines += [f"{key} = {_toml_value(data[key])}"
              for key in ("start", "goal", *(("k", "r_d") if gains else ()))]
    if robot.attachments is not None:
        lines += ["", "[body]", f"attachments = {_toml_rows(data['attachments'])}",
                  f"inertia = {_toml_value(data['inertia'])}",
                  f"center_of_mass = {_toml_value(data['center_of_mass'])}"]
    wrench = [(key, data[field]) for key, field in (("force", "external_force"),
                                                   ("moment", "external_moment"))
              if field in data]
    if wrench:
        lines += ["", "[wrench]", *(f"{key} = {_toml_value(value)}" for key, value in wrench)]
    if robot.encoder_offsets is not None:
        lines += ["", "[encoders]", f"offsets = {_toml_value(data['encoder_offsets'])}"]
    if robot.target is not None:
        lines += ["", "[target]", *(f"{key} = {_toml_value(value)}"
                                    for key, value in data["target"].items())]
    return "\n".join(lines) + "\n"
