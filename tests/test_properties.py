"""Properties (hypothesis): odd robot files, names and command-line numbers never end in a
traceback, only in a result or one line naming the field.

The quick suite runs each property on :data:`QUICK` (60 examples); ``pytest -m slow`` runs
:func:`test_fuzz_robot_files_and_command_line_numbers`, the robot-file and command-line
properties on :data:`FUZZ` (2,000 examples each, no deadline). Long work never runs: the
commands' heavy calls are replaced by a stand-in that records what got past the checks.
"""

from __future__ import annotations

import copy
import dataclasses
import math
import pkgutil
import re
import tomllib
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from cdpr_sym import Case, CdprError, InvalidCase, InvalidRobot, load_robot, preset
from cdpr_sym.cli import main
from cdpr_sym.codegen.names import MAX_IDENTIFIER, c_identifier, is_c_identifier
from cdpr_sym.robot import PRESET_NAMES

_COMMON = {"deadline": None, "derandomize": False,
           "suppress_health_check": [HealthCheck.function_scoped_fixture, HealthCheck.too_slow,
                                     HealthCheck.data_too_large]}
#: The quick suite: a few dozen examples per property (the whole file runs in seconds).
QUICK = settings(max_examples=60, **_COMMON)
#: The fuzz run (``pytest -m slow``): 2,000 examples per property.
FUZZ = settings(max_examples=2000, **_COMMON)

PRESETS = {name: tomllib.loads(resources.files("cdpr_sym.robot.presets")
                               .joinpath(f"{name}.toml").read_text())
           for name in PRESET_NAMES}

#: Fields a refusal of a robot file may name (besides an unknown key that was added).
ROBOT_FIELDS = {"path", "name", "mass", "gravity", "anchors", "tension", "frame", "case",
                "body", "tension.min", "tension.max", "frame.lower", "frame.upper",
                "case.start", "case.goal", "case.k", "case.r_d", "body.attachments",
                "body.inertia", "body.center_of_mass", "t_min", "t_max", "frame_lower",
                "frame_upper", "start", "goal", "k", "r_d"}


# -- TOML text from Python values ------------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class Deep:
    """A value nested ``depth`` times in arrays (``[[...]]``) or inline tables."""

    depth: int
    tables: bool


def toml_string(text: str) -> str:
    """``text`` as a TOML basic string (quotes, backslashes and controls escaped)."""
    out = []
    for char in text:
        if char in '"\\':
            out.append("\\" + char)
        elif ord(char) < 0x20 or ord(char) == 0x7F:
            out.append(f"\\u{ord(char):04x}")
        else:
            out.append(char)
    return '"' + "".join(out) + '"'


def toml_key(key: str) -> str:
    return key if re.fullmatch(r"[A-Za-z0-9_-]+", key) else toml_string(key)


def toml_value(value: Any) -> str:
    """One TOML value; tables inline."""
    if isinstance(value, Deep):
        if value.tables:
            return "{a = " * value.depth + "1" + "}" * value.depth
        return "[" * value.depth + "]" * value.depth
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return repr(value)  # nan, inf, -inf, 1e+308 and 5e-324 are TOML floats as written
    if isinstance(value, str):
        return toml_string(value)
    if isinstance(value, list):
        return "[" + ", ".join(toml_value(item) for item in value) + "]"
    return "{" + ", ".join(f"{toml_key(k)} = {toml_value(v)}" for k, v in value.items()) + "}"


def toml_document(data: dict[str, Any]) -> str:
    """A TOML document: plain values first, then one ``[table]`` per table of the root."""
    plain = [f"{toml_key(k)} = {toml_value(v)}" for k, v in data.items()
             if not isinstance(v, dict)]
    tables = []
    for key, table in data.items():
        if isinstance(table, dict):
            tables.append(f"[{toml_key(key)}]")
            tables += [f"{toml_key(k)} = {toml_value(v)}" for k, v in table.items()]
    return "\n".join(plain + tables) + "\n"


# -- strategies ------------------------------------------------------------------------------
ODD_FLOATS = st.sampled_from([math.nan, math.inf, -math.inf, 1e308, -1e308, 1e-320, -0.0, 0.0,
                              -1.0, 1e-9, 1e9, 5e-324])
FLOATS = st.one_of(ODD_FLOATS, st.floats(allow_nan=True, allow_infinity=True),
                   st.floats(-10.0, 10.0))
ODD_TEXT = st.sampled_from(["", " ", "x" * 5000, "Größe", "名前", "a\nb", "a\tb", "\u2028",
                            "\x1c", "robot_", "__x", "9lives", "my robot (v2)", "\x00"])
TEXT = st.one_of(ODD_TEXT, st.text(max_size=40))
SCALARS = st.one_of(st.booleans(), st.integers(-(2 ** 63), 2 ** 63 - 1), FLOATS, TEXT)
VALUES = st.recursive(SCALARS, lambda inner: st.one_of(
    st.lists(inner, max_size=4), st.dictionaries(TEXT, inner, max_size=3)), max_leaves=12)


def _locations(node: Any, prefix: tuple = ()) -> list[tuple]:
    """Paths (keys and indices) of every value below ``node``."""
    out = []
    items = node.items() if isinstance(node, dict) else enumerate(node)
    for key, value in items:
        out.append((*prefix, key))
        if isinstance(value, (dict, list)):
            out += _locations(value, (*prefix, key))
    return out


def _parent(data: Any, path: tuple) -> Any:
    for key in path[:-1]:
        data = data[key]
    return data


def _keys_in(value: Any) -> list[str]:
    """Every table key inside a generated value."""
    if isinstance(value, dict):
        return [*value, *(key for item in value.values() for key in _keys_in(item))]
    if isinstance(value, list):
        return [key for item in value for key in _keys_in(item)]
    return []


@st.composite
def robot_documents(draw) -> tuple[str, list[str]]:
    """A preset's robot file, mutated 1-3 times; the text and the unknown keys added."""
    data = copy.deepcopy(PRESETS[draw(st.sampled_from(PRESET_NAMES))])
    added: list[str] = []
    for _ in range(draw(st.integers(1, 3))):
        places = _locations(data)
        kind = draw(st.sampled_from(["drop", "replace", "number", "number", "name", "unknown",
                                     "nest"]))
        if kind == "drop":
            keyed = [path for path in places if isinstance(_parent(data, path), dict)]
            if keyed:
                path = draw(st.sampled_from(keyed))
                del _parent(data, path)[path[-1]]
        elif kind == "replace" and places:
            path = draw(st.sampled_from(places))
            _parent(data, path)[path[-1]] = value = draw(VALUES)
            added += _keys_in(value)
        elif kind == "number":
            numbers = [path for path in places if isinstance(_parent(data, path)[path[-1]],
                                                             (int, float))]
            if numbers:
                path = draw(st.sampled_from(numbers))
                _parent(data, path)[path[-1]] = draw(st.one_of(FLOATS, st.integers()))
        elif kind == "name":
            data["name"] = draw(TEXT)
        elif kind == "unknown":
            tables = [()] + [path for path in places
                             if isinstance(_parent(data, path)[path[-1]], dict)]
            table = data if not (path := draw(st.sampled_from(tables))) else \
                _parent(data, path)[path[-1]]
            key = draw(TEXT)
            table[key] = value = draw(VALUES)
            added += [key, *_keys_in(value)]
        elif kind == "nest" and places:
            path = draw(st.sampled_from(places))
            deep = Deep(draw(st.integers(1, 3000)), draw(st.booleans()))
            _parent(data, path)[path[-1]] = deep
            added += ["a"] if deep.tables else []
    text = toml_document(data)
    if draw(st.integers(0, 9)) == 0:
        text += draw(st.text(max_size=30))  # often no longer TOML
    return text, added


def assert_one_line_naming_a_field(error: CdprError, allowed: set[str],
                                   added: list[str] = ()) -> None:
    """A refusal is one line ``<field>: <message>`` with a field the input has."""
    text = str(error)
    assert len(text.splitlines()) == 1, text
    assert isinstance(error, (InvalidRobot, InvalidCase)), repr(error)
    assert error.field and text.startswith(f"{error.field}: "), text
    assert error.field in allowed or any(_names_key(error.field, key) for key in added), text


def _names_key(field: str, key: str) -> bool:
    """Whether ``field`` names the unknown key ``key`` (maybe in a table, quoted or cut)."""
    for table in ("", "tension.", "frame.", "case.", "body."):
        shown = field.removeprefix(table) if field.startswith(table) else None
        if shown is None:
            continue
        for form in (key, repr(key)):
            if shown == form or (shown.endswith("...") and form.startswith(shown[:-3])):
                return True
    return False


# -- robot files -----------------------------------------------------------------------------
def robot_file_property(folder: Path):
    """load_robot (and the robot's own case) on mutated presets: a robot or one line."""
    path = folder / "robot.toml"

    @given(robot_documents())
    def check(document: tuple[str, list[str]]) -> None:
        text, added = document
        path.write_text(text, encoding="utf-8")
        try:
            robot = load_robot(path)
            Case.of(robot)
        except CdprError as error:
            assert_one_line_naming_a_field(error, ROBOT_FIELDS, added)
    return check


def test_robot_files_load_or_are_refused_naming_a_field(tmp_path):
    QUICK(robot_file_property(tmp_path))()


def test_the_toml_writer_round_trips_the_presets():
    for name, data in PRESETS.items():
        assert tomllib.loads(toml_document(data)) == data, name


# -- names -----------------------------------------------------------------------------------
@QUICK
@given(st.one_of(TEXT, st.text(min_size=30, max_size=200)))
def test_any_text_gives_a_c_identifier(text):
    identifier = c_identifier(text)
    assert is_c_identifier(identifier), identifier
    assert re.fullmatch(r"[a-z][a-z0-9_]*", identifier) and "__" not in identifier
    assert not identifier.endswith("_") and len(identifier) <= MAX_IDENTIFIER
    assert c_identifier(identifier) == identifier


@QUICK
@given(TEXT)
def test_is_c_identifier_accepts_only_c_identifiers(text):
    if is_c_identifier(text):
        assert re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", text) and len(text) <= MAX_IDENTIFIER


@QUICK
@given(st.one_of(TEXT, st.text(max_size=200), st.integers(), st.none(), st.lists(TEXT)))
def test_any_robot_name_is_kept_or_refused_in_one_line(name):
    try:
        robot = dataclasses.replace(preset("planar2"), name=name)
    except CdprError as error:
        assert_one_line_naming_a_field(error, {"name"})
    else:
        assert robot.name == name and is_c_identifier(c_identifier(robot.name))


def test_an_export_prefix_that_is_no_c_identifier_is_refused_in_one_line(tmp_path, capsys):
    @QUICK
    @given(TEXT)
    def check(prefix: str) -> None:
        assume(not is_c_identifier(prefix))
        status = main(["export-c", "--robot", "planar2", "--controller", "pd",
                       f"--prefix={prefix}", "--out", str(tmp_path / "pkg")])
        lines = capsys.readouterr().err.strip().splitlines()
        assert status == 2 and len(lines) == 1, lines
        assert lines[0].startswith("cdpr-sym: error: prefix: "), lines[0]
        assert not (tmp_path / "pkg").exists()
    check()


# -- command-line numbers --------------------------------------------------------------------
class Reached(Exception):
    """The stand-in for long work was called: the options passed every check."""

    def __init__(self, name: str, args: tuple, kwargs: dict) -> None:
        super().__init__(name)
        self.name, self.args_, self.kwargs = name, args, kwargs


def _stand_in(name: str):
    def call(*args, **kwargs):
        raise Reached(name, args, kwargs)
    return call


#: Long work each command would start, replaced by a stand-in.
HEAVY = ("cdpr_sym.cli.commands.simulate", "cdpr_sym.studies.workspace.run_workspace_study",
         "cdpr_sym.studies.bench.run_bench", "cdpr_sym.sweep.run_sweep",
         "cdpr_sym.studies.compare.CompareStudy.compute")

_TIMING = {"duration", "dt"}
#: Numeric options per command: (option, fields its refusal may name, values it takes).
OPTIONS = {
    "simulate": [("--duration", _TIMING, 1), ("--dt", _TIMING, 1),
                 ("--mass-scale", {"mass_scale"}, 1), ("--rate-limit", {"rate_limit"}, 1),
                 ("--k", {"k"}, 3), ("--r-d", {"r_d"}, 3), ("--start", {"start"}, 3),
                 ("--goal", {"goal"}, 3)],
    "workspace": [("--resolution", {"resolution"}, 1), ("--orientation", {"orientation"}, 1)],
    "bench": [("--seconds", {"seconds"}, 1)],
    "sweep": [("--pairs", {"pairs"}, 1), ("--seed", {"seed"}, 1), ("--duration", _TIMING, 1),
              ("--dt", _TIMING, 1), ("--mass-scale", {"mass_scale"}, 1),
              ("--workers", {"workers"}, 1)],
    "study": [("--pairs", {"pairs"}, 1), ("--seed", {"seed"}, 1)],
}
#: What each command needs besides the fuzzed options ({tmp}: the test's folder).
BASE = {"simulate": ["simulate"],
        "workspace": ["workspace", "--robot", "planar3", "--out", "{tmp}/ws"],
        "bench": ["bench"],
        "sweep": ["sweep", "--out", "{tmp}/runs.csv"],
        "study": ["study", "compare", "--out", "{tmp}/compare"]}
NUMBER_TEXT = st.one_of(
    st.sampled_from(["nan", "-nan", "inf", "-inf", "Infinity", "0", "-0", "-0.0", "1e308",
                     "-1e308", "1e309", "1e-320", "-1e-320", "abc", "", " ", "1_000", "0x10",
                     "1e3", "2", "3", "5", "0.5", "0.01", "-1", "100000", "1e6", "1e-300",
                     "99999999999999999999999", "1.5", "4.0"]),
    st.floats().map(repr), st.integers(-10, 10 ** 12).map(str), st.text(max_size=8))


@st.composite
def command_lines(draw) -> tuple[list[str], set[str]]:
    """A command with 1-3 of its numeric options set to odd text; the fields they name."""
    command = draw(st.sampled_from(sorted(OPTIONS)))
    chosen = draw(st.lists(st.sampled_from(OPTIONS[command]), min_size=1, max_size=3,
                           unique_by=lambda option: option[0]))
    argv, fields = list(BASE[command]), set()
    for option, names, count in chosen:
        values = draw(st.lists(NUMBER_TEXT, min_size=1, max_size=count + 1))
        argv += [f"{option}={values[0]}"] if len(values) == 1 else [option, *values]
        fields |= names
    if command == "sweep" and not any(option == "--pairs" for option, _, _ in chosen):
        argv += ["--pairs", "2"]
    return argv, fields


def _check_what_got_through(reached: Reached) -> None:
    """The options that reached long work are the sane ones."""
    from cdpr_sym.closed_loop.case import trajectory_budget
    from cdpr_sym.studies.bench import MAX_SECONDS
    from cdpr_sym.workspace import MAX_GRID_POSES

    kwargs = reached.kwargs
    if reached.name.endswith("simulate"):
        duration, dt = kwargs["duration"], kwargs["dt"]
        assert math.isfinite(duration) and 0 < dt <= duration
        assert duration / dt * 8 <= trajectory_budget()
        for field in ("start", "goal", "k", "r_d"):
            assert np.all(np.isfinite(kwargs[field]))
        assert math.isfinite(kwargs["plant"].mass_scale)
    elif reached.name.endswith("run_workspace_study"):
        assert 2 <= kwargs["resolution"] and kwargs["resolution"] ** 2 <= MAX_GRID_POSES
        assert kwargs["orientation"] is None or np.all(np.isfinite(kwargs["orientation"]))
    elif reached.name.endswith("run_bench"):
        assert 0 < kwargs["min_seconds"] <= MAX_SECONDS
    elif reached.name.endswith("run_sweep"):
        config = reached.args_[0]
        assert 0 < config.pairs <= 100_000 and config.seed >= 0
        assert math.isfinite(config.duration) and 0 < config.dt <= config.duration
        assert kwargs["workers"] is None or 0 < kwargs["workers"] <= 256
    else:  # a study's compute(self, folder, request)
        request = reached.args_[2]
        assert 0 < request.pairs <= 100_000 and request.seed >= 0


def command_line_property(folder: Path, capsys):
    """Odd numbers on the command line: argparse's refusal, one line naming the field, or
    sane values handed to the long work."""

    @given(command_lines())
    def check(case: tuple[list[str], set[str]]) -> None:
        template, fields = case
        argv = [arg.replace("{tmp}", str(folder)) for arg in template]
        try:
            status = main(argv)
        except SystemExit as stop:  # argparse: not a number, or a missing value
            assert stop.code == 2
            capsys.readouterr()
            return
        except Reached as reached:
            capsys.readouterr()
            _check_what_got_through(reached)
            return
        err = capsys.readouterr().err
        lines = err.strip().splitlines()
        assert status == 2 and len(lines) == 1, (argv, err)
        field = lines[0].removeprefix("cdpr-sym: error: ").split(": ", 1)[0]
        assert lines[0].startswith("cdpr-sym: error: ") and field in fields, (argv, lines)
    return check


@pytest.fixture
def no_long_work(monkeypatch, tmp_path):
    """The long work replaced; its modules imported first, so that none of them binds a
    stand-in by its own ``from ... import`` (which would outlive the test)."""
    for target in HEAVY:
        pkgutil.resolve_name(target)  # imports the module defining it
    for target in HEAVY:
        monkeypatch.setattr(target, _stand_in(target))
    monkeypatch.chdir(tmp_path)


def test_odd_numbers_on_the_command_line_end_in_one_line(tmp_path, capsys, no_long_work):
    QUICK(command_line_property(tmp_path, capsys))()


# -- the fuzz run ----------------------------------------------------------------------------
@pytest.mark.slow
def test_fuzz_robot_files_and_command_line_numbers(tmp_path, capsys, no_long_work):
    (tmp_path / "robots").mkdir()
    FUZZ(robot_file_property(tmp_path / "robots"))()
    FUZZ(command_line_property(tmp_path, capsys))()
