"""The exported C package is safe to run: no command from NaN or infinity; prefixes that build.

Every test builds a real package (``export_c``, then make with strict gcc flags) and calls it
through the harness of ``tests/test_export.py`` (``tests/export_harness/harness.c``), which
reads ``nan`` and ``inf`` like any number. ``<prefix>_control`` must refuse a NaN or infinite
input, and a NaN or infinite result of the law, with a nonzero status, its own flag bit and
the safe command: T_MIN on every cable, the controller's memory unchanged. Finite states keep
status 0 and the Python law's numbers. Prefixes that would clash with the package's files,
build targets or the C library either build (make and CMake) or are refused in one line.
"""

from __future__ import annotations

import dataclasses
import functools
import re
import subprocess
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from tools import HARNESS, STRICT
from tools import run as _run
from tools import tool as _tool

from cdpr_sym import SymbolicModel, controller_by_name, preset
from cdpr_sym.cli import main
from cdpr_sym.control import FLAG_NAMES, initial_memory_function, law_function
from cdpr_sym.export import export_c
from cdpr_sym.robot import Robot

ROBOT = "aras3"
#: One stateless law that clips, the paper's design and one with internal state.
CONTROLLERS = ("pd-sat", "l2", "smooth")
TOLERANCE = 1e-10


@dataclasses.dataclass(frozen=True)
class Built:
    """An exported package of :data:`ROBOT`, built with make, and its harness."""

    controller: str
    out_dir: Path
    prefix: str
    harness: Path

    @property
    def header(self) -> str:
        return (self.out_dir / f"{self.prefix}.h").read_text()

    def macro(self, name: str) -> float:
        """The value of ``#define <PREFIX>_<name>`` in the header (fails if it is missing)."""
        found = re.search(rf"^#define {self.prefix.upper()}_{name} \(?(-?[0-9.e+-]+)\)?\s",
                          self.header, re.MULTILINE)
        assert found, f"{self.prefix.upper()}_{name} is not defined in the header"
        return float(found.group(1))


@pytest.fixture(scope="module")
def built(tmp_path_factory) -> Callable[[str], Built]:
    """``built(controller)``: the package of aras3 and ``controller``, exported and built."""
    cache: dict[str, Built] = {}

    def get(controller: str) -> Built:
        if controller not in cache:
            folder = tmp_path_factory.mktemp(controller)
            result = export_c(ROBOT, controller, folder / "pkg")
            _run([_tool("make"), "CC=gcc", f"CFLAGS={' '.join(STRICT)}"], cwd=result.out_dir)
            prefix, harness = result.prefix, folder / "harness"
            _run([_tool("gcc"), *STRICT, f'-DCDPR_HEADER="{prefix}.h"',
                  f"-DCDPR_PREFIX={prefix}", f"-DCDPR_UPPER={prefix.upper()}", "-I",
                  result.out_dir, HARNESS, result.out_dir / f"lib{prefix}.a", "-lm", "-o",
                  harness])
            cache[controller] = Built(controller, result.out_dir, prefix, harness)
        return cache[controller]
    return get


@dataclasses.dataclass(frozen=True)
class Case:
    """One call of ``_control``: the harness's inputs (k, r_d: None for the case's gains)."""

    q: np.ndarray
    dq: np.ndarray
    q_goal: np.ndarray
    k: np.ndarray | None = None
    r_d: np.ndarray | None = None
    memory: np.ndarray | None = None  # None: the plan from the case's start (if stateful)
    dt: float = 1e-3

    def row(self, robot: Robot, controller: str) -> np.ndarray:
        """The harness's input line: q dq q_goal k r_d (memory dt) use_case_gains."""
        gains = self.k is None and self.r_d is None
        k = robot.k if self.k is None else self.k
        r_d = robot.r_d if self.r_d is None else self.r_d
        parts = [self.q, self.dq, self.q_goal, k, r_d]
        if _memory_size(robot, controller):
            parts += [self.memory_of(robot, controller), [self.dt]]
        return np.concatenate([np.asarray(part, dtype=float) for part in parts]
                              + [[float(gains)]])

    def memory_of(self, robot: Robot, controller: str) -> np.ndarray:
        """The memory passed: given, or the plan of the case's move."""
        if self.memory is not None:
            return np.asarray(self.memory, dtype=float)
        plan = _plan_function(robot.name, controller)
        return np.array(plan(robot.start, robot.goal, robot.k, robot.r_d).full()).ravel()


@functools.cache
def _plan_function(robot_name: str, controller: str):
    """The design's plan of a move as a CasADi function, built once per preset and design."""
    return initial_memory_function(SymbolicModel(preset(robot_name)),
                                   controller_by_name(controller))


@functools.cache
def _law_function(robot_name: str, controller: str):
    """The design's law as a CasADi function, built once per preset and design (graph
    building per call made the smooth check take 100 s)."""
    return law_function(SymbolicModel(preset(robot_name)), controller_by_name(controller))


def _memory_size(robot: Robot, controller: str) -> int:
    return controller_by_name(controller).memory_size(SymbolicModel(robot))


def _call(built: Built, cases: list[Case], folder: Path) -> list[dict[str, np.ndarray]]:
    """Run the harness on ``cases``; per case ret, tau, alpha, beta, j, flags, memory_next."""
    robot = preset(ROBOT)
    rows = np.array([case.row(robot, built.controller) for case in cases])
    path = folder / f"states_{built.controller}.txt"
    with path.open("w") as f:
        f.write(f"{len(rows)}\n")
        np.savetxt(f, rows, fmt="%.17g")  # nan, inf and -inf, as C's scanf reads them
    lines = _run([built.harness, path]).splitlines()
    n, n_j = robot.n, robot.n_j
    sizes = {"ret": 1, "tau": n, "alpha": 1, "beta": 1, "j": n_j, "flags": 1,
             "memory_next": _memory_size(robot, built.controller)}
    out = []
    for line in lines:
        values, parts, start = np.array(line.split(), dtype=float), {}, 0
        for name, size in sizes.items():
            parts[name] = values[start: start + size]
            start += size
        out.append(parts)
    return out


def _python_law(controller: str, case: Case) -> list[np.ndarray]:
    """The Python law (CasADi's virtual machine) at ``case``: tau, alpha, beta, j, flags, ..."""
    robot = preset(ROBOT)
    memory = case.memory_of(robot, controller) if _memory_size(robot, controller) else []
    values = _law_function(ROBOT, controller)(case.q, case.dq, case.q_goal,
                                      robot.k if case.k is None else case.k,
                                      robot.r_d if case.r_d is None else case.r_d,
                                      np.asarray(memory, dtype=float), case.dt)
    return [np.array(value.full()).ravel() for value in values]


def _assert_safe_command(built: Built, case: Case, out: dict[str, np.ndarray],
                         kind: str, label: str) -> None:
    """``out`` is the safe command with the status and flag of ``kind`` (input / output)."""
    robot = preset(ROBOT)
    assert out["ret"][0] != 0, f"{label}: status 0, tau {out['tau']}, flags {out['flags']}"
    assert np.array_equal(out["tau"], np.full(robot.n, robot.t_min)), f"{label}: {out['tau']}"
    assert out["alpha"][0] == 0 and out["beta"][0] == 0 and not out["j"].any(), label
    if out["memory_next"].size:  # the memory is handed on unchanged, bit for bit
        np.testing.assert_array_equal(out["memory_next"], case.memory_of(robot, built.controller),
                                      err_msg=label)
    assert built.macro("T_MIN") == robot.t_min
    status, flag = built.macro(f"CONTROL_INVALID_{kind}"), built.macro(f"FLAG_INVALID_{kind}")
    assert out["ret"][0] == status, f"{label}: status {out['ret'][0]}, expected {status}"
    assert out["flags"][0] == flag, f"{label}: flags {out['flags'][0]}, expected {flag}"


def _input_faults(controller: str) -> dict[str, Case]:
    """A NaN or infinite entry in each input, the rest the case's start at rest."""
    robot = preset(ROBOT)
    start, rest, goal, n = robot.start, np.zeros(robot.n), robot.goal, robot.n

    def one(values: np.ndarray, index: int, value: float) -> np.ndarray:
        out = np.array(values, dtype=float)
        out[index] = value
        return out
    faults = {"nan in q": Case(one(start, 0, np.nan), rest, goal),
              "+inf in dq": Case(start, one(rest, 1, np.inf), goal),
              "nan in q_goal": Case(start, rest, one(goal, n - 1, np.nan)),
              "-inf in k": Case(start, rest, goal, k=one(robot.k, 0, -np.inf), r_d=robot.r_d),
              "nan in r_d": Case(start, rest, goal, k=robot.k, r_d=one(robot.r_d, 2, np.nan)),
              "negative k": Case(start, rest, goal, k=one(robot.k, 1, -1.0), r_d=robot.r_d),
              "negative r_d": Case(start, rest, goal, k=robot.k, r_d=one(robot.r_d, 0, -1e-3))}
    if _memory_size(robot, controller):
        plan = Case(start, rest, goal).memory_of(robot, controller)
        faults["nan in memory"] = Case(start, rest, goal, memory=one(plan, 0, np.nan))
        faults["+inf dt"] = Case(start, rest, goal, dt=np.inf)
        faults["nan dt"] = Case(start, rest, goal, dt=np.nan)
    return faults


# -- NaN and infinity ----------------------------------------------------------------------
@pytest.mark.parametrize("controller", [  # smooth's planner compiles for ~25 s: CI only
    pytest.param(name, marks=pytest.mark.slow) if name == "smooth" else name
    for name in CONTROLLERS])
def test_non_finite_input_gives_the_safe_command(built, controller, tmp_path):
    """NaN in q, +inf in dq, NaN in q_goal (and gains, memory, dt), a negative gain: refused,
    never a command."""
    package = built(controller)
    faults = _input_faults(controller)
    outputs = _call(package, list(faults.values()), tmp_path)
    for (label, case), out in zip(faults.items(), outputs, strict=True):
        _assert_safe_command(package, case, out, "INPUT", f"{controller}, {label}")


#: Huge but finite states whose law overflows: (controller, label, q scale, dq value) and
#: which result is then not finite in Python (the CasADi virtual machine).
OVERFLOWS = [
    # (the closed-form l2 squares nothing: dq = 1e155, which overflowed the normal equations
    # of the solve, now gives finite numbers)
    ("l2", "dq = 1e307 overflows the PD force R_d dq", None, 1e307, "tau"),
    ("pd-sat", "q = 1e200: tau clipped to the box, beta NaN", 1e200, None, "beta"),
    ("smooth", "q = 1e200: tau clipped to the box, beta NaN", 1e200, None, "beta"),
]


@pytest.mark.parametrize(("controller", "label", "q", "dq", "bad"), [
    # smooth's package (its planner) takes ~15 s to build: a slow check
    pytest.param(*row, id=row[0], marks=[pytest.mark.slow] if row[0] == "smooth" else [])
    for row in OVERFLOWS])
def test_law_overflow_gives_the_safe_command(built, controller, label, q, dq, bad, tmp_path):
    """A finite state where the law itself overflows to NaN or infinity: refused as output.

    pd-sat and smooth clip a NaN tension into the box (fmin/fmax drop NaN), so the command
    looked plausible; their NaN margin beta gives the fault away.
    """
    robot = preset(ROBOT)
    case = Case(robot.start if q is None else np.full(robot.n, q),
                np.zeros(robot.n) if dq is None else np.full(robot.n, dq), robot.goal)
    names = law_function(SymbolicModel(robot), controller_by_name(controller)).name_out()
    python = dict(zip(names, _python_law(controller, case), strict=True))
    assert np.all(np.isfinite(case.row(robot, controller)))  # the inputs are finite
    assert not np.all(np.isfinite(python[bad])), "the law no longer overflows here"
    out = _call(built(controller), [case], tmp_path)[0]
    _assert_safe_command(built(controller), case, out, "OUTPUT", f"{controller}, {label}")


# smooth's Python law plans each of the 65 states (about 30 s): left to the slow suite
@pytest.mark.parametrize("controller", [pytest.param(name, marks=pytest.mark.slow)
                                        if name == "smooth" else name for name in CONTROLLERS])
def test_finite_states_keep_status_ok_and_the_python_law(built, controller, rng,
                                                         random_states, tmp_path):
    """Ordinary states (moving, at rest, at the goal, case and other gains): status
    <PREFIX>_CONTROL_OK and the Python law's numbers, as before the checks."""
    robot, package = preset(ROBOT), built(controller)
    q, dq = random_states(robot, rng, 60)
    goal, _ = random_states(robot, rng, 60, margin=0.2)
    dq[:15] = 0.0
    q[-5:], dq[-5:] = goal[-5:], 0.0
    cases = [Case(q[i], dq[i], goal[i], dt=float(rng.uniform(1e-4, 1e-2))) for i in range(60)]
    cases += [Case(q[i], dq[i], goal[i], k=robot.k * 1.5, r_d=robot.r_d * 0.7) for i in range(5)]
    names = ("tau", "alpha", "beta", "j", "flags", "memory_next")
    for index, (case, out) in enumerate(zip(cases, _call(package, cases, tmp_path),
                                            strict=True)):
        assert out["ret"][0] == 0, f"state {index}: status {out['ret'][0]}"
        for name, expected in zip(names, _python_law(controller, case), strict=False):
            scale = max(float(np.abs(expected).max(initial=0.0)), 1e-300)
            error = float(np.abs(out[name] - expected).max(initial=0.0)) / scale
            assert error <= TOLERANCE, f"state {index}, {name}: {out[name]} vs {expected}"
    assert package.macro("CONTROL_OK") == 0  # the status has its name


@pytest.mark.slow  # builds every design's package (~11 s)
def test_header_and_readme_document_the_flags_statuses_and_safe_command(built):
    """New bits above every Python flag; named statuses; the safe command in both texts."""
    package = built("smooth")
    bits = {package.macro(f"FLAG_{name}") for name in ("INVALID_INPUT", "INVALID_OUTPUT")}
    assert len(bits) == 2 and all(bit > max(FLAG_NAMES) for bit in bits)
    assert all(int(bit) & (int(bit) - 1) == 0 for bit in bits)  # powers of two
    statuses = [package.macro(f"CONTROL_{name}") for name in
                ("OK", "NULL_ARGUMENT", "INVALID_INPUT", "INVALID_OUTPUT")]
    assert statuses[0] == 0 and statuses[1] == -1 and len(set(statuses)) == 4
    readme = (package.out_dir / "README.md").read_text()
    up = package.prefix.upper()
    for text in (package.header, readme):
        assert f"{up}_T_MIN on every cable" in text or f"`{up}_T_MIN` on every cable" in text
        assert f"{up}_FLAG_INVALID_INPUT" in text and f"{up}_CONTROL_INVALID_OUTPUT" in text
        assert "memory_next = memory" in text or "`memory_next` = `memory`" in text


def test_source_refuses_finite_math_and_build_files_do_not_enable_it(built, tmp_path):
    """isfinite() is a no-op under -ffinite-math-only: the wrapper source must not compile so,
    and neither the Makefile nor CMake (Release) may pass such a flag."""
    package = built("l2")
    source = package.out_dir / f"{package.prefix}.c"
    for flag in ("-ffast-math", "-ffinite-math-only", "-Ofast"):
        done = subprocess.run([_tool("gcc"), "-std=c99", "-O2", flag, "-c", str(source), "-o",
                               str(tmp_path / "x.o")], capture_output=True, text=True)
        assert done.returncode != 0 and "#error" in done.stderr, flag
    fast = re.compile(r"-ffast-math|-ffinite-math-only|-Ofast")
    assert not fast.search(_run([_tool("make"), "-n", "-B"], cwd=package.out_dir))
    cmake = _tool("cmake")
    _run([cmake, "-S", package.out_dir, "-B", tmp_path / "build", "-DCMAKE_C_COMPILER=gcc"])
    log = _run([cmake, "--build", tmp_path / "build", "--verbose"])
    assert f"{package.prefix}.c" in log and not fast.search(log)


# -- prefixes ------------------------------------------------------------------------------
#: Prefixes that clashed with a file, a library or a target of the package: they must build.
BUILDING_PREFIXES = ("example", "m", "c")
#: Prefixes that cannot work (or are not C identifiers the toolkit accepts): refused.
REFUSED_PREFIXES = {"main": "main.c", "Main": "main.c", "all": "CMake reserves",
                    "math": "<math.h>", "stdio": "<stdio.h>", "a__b": "C identifier",
                    "_": "C identifier", "p" * 300: "300 characters"}


@pytest.mark.parametrize("prefix", [BUILDING_PREFIXES[0], *(
    pytest.param(prefix, marks=pytest.mark.slow) for prefix in BUILDING_PREFIXES[1:])])
def test_prefixes_that_clashed_build_with_make_and_cmake(prefix, tmp_path, capsys):
    """example: the CMake example target; m, c: make's -L. -lm / -lc found the package."""
    out = tmp_path / "pkg"
    assert main(["export-c", "--robot", "planar2", "--controller", "pd", "--prefix", prefix,
                 "--out", str(out)]) == 0
    capsys.readouterr()
    _run([_tool("make"), "CC=gcc", f"CFLAGS={' '.join(STRICT)}"], cwd=out)
    assert "final_error" in _run([out / "example"])
    cmake, build = _tool("cmake"), tmp_path / "build"
    _run([cmake, "-S", out, "-B", build, "-DCMAKE_C_COMPILER=gcc"])
    _run([cmake, "--build", build])
    assert "final_error" in _run([build / "example"])


@pytest.mark.parametrize("prefix", list(REFUSED_PREFIXES),
                         ids=[p if len(p) < 20 else "300_characters" for p in REFUSED_PREFIXES])
def test_unusable_prefixes_are_refused_in_one_line(prefix, tmp_path, capsys):
    out = tmp_path / "pkg"
    assert main(["export-c", "--robot", "planar2", "--controller", "pd", "--prefix", prefix,
                 "--out", str(out)]) == 2
    captured = capsys.readouterr()
    err = captured.err.strip()
    assert len(err.splitlines()) == 1 and len(err) < 300, err
    assert err.startswith("cdpr-sym: error: prefix:") and REFUSED_PREFIXES[prefix] in err, err
    assert not out.exists()


_PARAMETERS_PROGRAM = """
#include <math.h>
#include <stdio.h>
#include CDPR_HEADER
#define CALL(name) CDPR_CAT(CDPR_PREFIX, name)
#define CDPR_NP(upper) CDPR_CAT3(upper, NP)
#define CDPR_CAT3(a, b) CDPR_CAT4(a, b)
#define CDPR_CAT4(a, b) a##_##b
#define CDPR_CAT(a, b) CDPR_CAT2(a, b)
#define CDPR_CAT2(a, b) a##_##b
int main(void) {
  double p[CDPR_NP(CDPR_UPPER)], k[3] = {1200.0, -1.0, 1200.0}, goal[3] = {0.0, NAN, 1.0};
  printf("%d %d %d %d %d %d %d\\n",
         CALL(parameters)(0, 0, 0, 1e-3, 1.0, 0, p),
         CALL(parameters)(0, 0, 0, 0.0, 1.0, 0, p),
         CALL(parameters)(0, 0, 0, -1e-3, 1.0, 0, p),
         CALL(parameters)(0, 0, 0, 1e-3, -1.0, 0, p),
         CALL(parameters)(0, k, 0, 1e-3, 1.0, 0, p),
         CALL(parameters)(goal, 0, 0, 1e-3, 1.0, 0, p),
         CALL(parameters)(0, 0, 0, INFINITY, 1.0, 0, p));
  return 0;
}
"""


def test_parameters_report_a_step_that_is_not_one(built, tmp_path):
    """dt <= 0, a negative mass scale, a negative gain or a NaN goal: _parameters says so."""
    package = built("l2")
    source = tmp_path / "parameters.c"
    source.write_text(_PARAMETERS_PROGRAM)
    program = tmp_path / "parameters"
    _run([_tool("gcc"), *STRICT, f'-DCDPR_HEADER="{package.prefix}.h"',
          f"-DCDPR_PREFIX={package.prefix}", f"-DCDPR_UPPER={package.prefix.upper()}", "-I",
          package.out_dir, source,
          package.out_dir / f"lib{package.prefix}.a", "-lm", "-o", program])
    assert _run([program]).split() == ["0", "-1", "-1", "-1", "-1", "-1", "-1"]
