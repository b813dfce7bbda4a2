"""The exported C package: strict builds, agreement with Python, valgrind, errors, CLI.

Every test compiles for real (gcc, make, cmake) and checks the C against the Python twin:
the control law of :func:`cdpr_sym.control.law_function`, the model terms of
:class:`cdpr_sym.SymbolicModel` and the closed loop of :func:`cdpr_sym.simulate`.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import re
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import casadi as ca
import numpy as np
import pytest
from tools import HARNESS, STRICT
from tools import run as _run
from tools import tool as _tool

from cdpr_sym import (
    BuildOptions,
    CompilationFailed,
    InvalidCase,
    SymbolicModel,
    UnknownName,
    controller_by_name,
    preset,
    simulate,
)
from cdpr_sym.cli import main
from cdpr_sym.codegen import run_command
from cdpr_sym.control import (
    CONTROLLERS,
    FLAG_NAMES,
    capabilities,
    initial_memory_function,
    law_function,
)
from cdpr_sym.export import REQUIRED_MODEL_TERMS, ExportResult, bench_export, export_c
from cdpr_sym.export.package import prefix_problem
from cdpr_sym.robot import PRESET_NAMES

#: Functions the exported object file may call: libm only (no heap, no I/O).
LIBM = {"sqrt", "fabs", "fmin", "fmax", "floor", "fmod", "ceil", "pow", "exp", "log", "sin",
        "cos", "tan", "atan2", "tanh", "sinh", "cosh", "asin", "acos", "atan", "round",
        "erf", "log1p", "expm1", "copysign", "trunc", "hypot"}
TOLERANCE = 1e-10


@dataclasses.dataclass(frozen=True)
class Package:
    """An exported package built with make (strict flags) plus the test harness."""

    result: ExportResult
    make_output: str
    harness: Path

    @property
    def library(self) -> Path:
        return self.result.out_dir / f"lib{self.result.prefix}.a"


def _build_harness(result: ExportResult, out: Path) -> Path:
    prefix = result.prefix
    _run([_tool("gcc"), *STRICT, "-g", f'-DCDPR_HEADER="{prefix}.h"',
          f"-DCDPR_PREFIX={prefix}", f"-DCDPR_UPPER={prefix.upper()}", "-I", result.out_dir,
          HARNESS, result.out_dir / f"lib{prefix}.a", "-lm", "-o", out])
    return out


@pytest.fixture(scope="module")
def package(tmp_path_factory):
    """``package(robot, controller)``: exported, built with make and strict flags (cached)."""
    built: dict[tuple[str, str], Package] = {}

    def get(robot: str, controller: str) -> Package:
        if (robot, controller) not in built:
            folder = tmp_path_factory.mktemp(f"{robot}_{controller}")
            result = export_c(robot, controller, folder / "pkg")
            output = _run([_tool("make"), "CC=gcc", f"CFLAGS={' '.join(STRICT)}"],
                          cwd=result.out_dir)
            built[robot, controller] = Package(result, output,
                                               _build_harness(result, folder / "harness"))
        return built[robot, controller]
    return get


def _states(robot, controller: str, rng, draw_states, count: int) -> np.ndarray:
    """Rows [q, dq, q_goal, k, r_d, (memory, dt,) use_case_gains]: random, at and near rest.

    A controller's memory is its plan from a random start, advanced by five law calls with
    random time steps of up to 0.5 s.
    """
    q, dq = draw_states(robot, rng, count)
    goal, _ = draw_states(robot, rng, count, margin=0.2)
    quarter = count // 4
    dq[:quarter] = 0.0
    direction = rng.normal(size=(quarter, robot.n))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    speed = 10.0 ** rng.uniform(-12, -6, size=(quarter, 1))
    speed[: quarter // 4] = 1e-6 * (1 + rng.uniform(-1e-9, 1e-9, size=(quarter // 4, 1)))
    dq[quarter: 2 * quarter] = direction * speed
    k = robot.k * rng.uniform(0.5, 2.0, size=(count, robot.n))
    r_d = robot.r_d * rng.uniform(0.5, 2.0, size=(count, robot.n))
    use_case = (np.arange(count) % 7 == 0).astype(float)
    k[use_case == 1], r_d[use_case == 1] = robot.k, robot.r_d
    model, law = SymbolicModel(robot), controller_by_name(controller)
    if not law.memory_size(model):
        return np.column_stack([q, dq, goal, k, r_d, use_case])
    start, _ = draw_states(robot, rng, count)
    memory = initial_memory_function(model, law).map(count)(start.T, goal.T, k.T, r_d.T)
    mapped = law_function(model, law).map(count)
    for _ in range(5):
        memory = mapped(q.T, dq.T, goal.T, k.T, r_d.T, memory, rng.uniform(0, 0.5, count))[-1]
    dt = rng.uniform(1e-4, 1e-2, count)
    return np.column_stack([q, dq, goal, k, r_d, np.array(memory.full()).T, dt, use_case])


def _run_harness(package: Package, states: np.ndarray, folder: Path,
                 valgrind: bool = False) -> np.ndarray:
    path = folder / "states.txt"
    with path.open("w") as f:
        f.write(f"{len(states)}\n")
        np.savetxt(f, states, fmt="%.17g")
    command = [package.harness, path]
    if valgrind:
        command = [_tool("valgrind"), "--error-exitcode=1", "--leak-check=full",
                   "--errors-for-leak-kinds=definite", "-q", *command]
    return np.atleast_2d(np.loadtxt(_run(command).splitlines()))


def _split(output: np.ndarray, n: int, n_j: int, n_memory: int = 0) -> dict[str, np.ndarray]:
    sizes = {"ret": 1, "tau": n, "alpha": 1, "beta": 1, "j": n_j, "flags": 1,
             "memory_next": n_memory, "memory0": n_memory,
             "cable_lengths": n, "structure_matrix": n * n, "mass_matrix": n * n,
             "potential": 1, "p_matrix": n * n_j, "a_matrix": n * n_j}
    parts, start = {}, 0
    for name, size in sizes.items():
        parts[name] = output[:, start: start + size]
        start += size
    assert start == output.shape[1]
    return parts


def _python_law(robot, controller: str, states: np.ndarray) -> dict[str, np.ndarray]:
    """The law (and plan) of ``controller`` at the harness's states, evaluated by CasADi."""
    n, model, law = robot.n, SymbolicModel(robot), controller_by_name(controller)
    size = law.memory_size(model)
    columns = [states[:, i * n: (i + 1) * n].T for i in range(5)]
    if size:
        columns += [states[:, 5 * n: 5 * n + size].T, states[:, 5 * n + size]]
    else:  # a stateless law: empty memory, and dt does not matter
        columns += [np.zeros((0, len(states))), 1e-3]
    mapped = law_function(model, law).map(len(states))
    out = {name: np.array(value.full()).T
           for name, value in zip(mapped.name_out(), mapped(*columns), strict=True)}
    if size:
        plan = initial_memory_function(model, law).map(len(states))
        out["memory0"] = np.array(plan(columns[0], columns[2], columns[3], columns[4])
                                  .full()).T
    return out


def _python_model_term(robot, name: str, states: np.ndarray) -> np.ndarray:
    """Row-major values of a model term at every state (inputs q and/or dq)."""
    n, count = robot.n, len(states)
    function = SymbolicModel(robot).functions[name]
    inputs = {"q": states[:, :n].T, "dq": states[:, n: 2 * n].T}
    value = np.array(function.map(count)(*[inputs[label] for label in function.name_in()])
                     .full())
    rows, cols = function.size_out(0)
    return value.reshape(rows, count, cols).transpose(1, 0, 2).reshape(count, rows * cols)


def _relative_error(c_value: np.ndarray, python_value: np.ndarray) -> float:
    """Largest |C - Python| over the largest |Python| entry of the same vector, per state."""
    scale = np.maximum(np.abs(python_value).max(axis=1, keepdims=True), 1e-300)
    return float((np.abs(c_value - python_value) / scale).max())


def _example_output(text: str) -> dict[str, np.ndarray]:
    return {line.split()[0]: np.array(line.split()[1:], dtype=float)
            for line in text.splitlines() if re.match(r"(final|tension)_", line)}


def _reference_run(robot, controller: str):
    """The Python closed loop on CasADi's virtual machine: a reference independent of the
    compiled simulator (which gives the same bits, every operation rounded as written, and
    is compared too)."""
    return simulate(robot, controller_by_name(controller), duration=10.0,
                    build_options=BuildOptions(backend="casadi"))


# -- aras3 with the paper's l2 design: the full set of checks --------------------------------
def test_package_builds_with_make_and_strict_gcc_flags(package):
    built = package("aras3", "l2")
    assert " ".join(STRICT) in built.make_output
    assert built.library.exists() and (built.result.out_dir / "example").exists()


def test_package_builds_with_cmake_and_example_prints_the_same(package, tmp_path):
    built = package("aras3", "l2")
    _run([_tool("cmake"), "-S", built.result.out_dir, "-B", tmp_path, "-DCMAKE_C_COMPILER=gcc",
          "-DCMAKE_BUILD_TYPE=Release", "-DCMAKE_C_FLAGS=-Wall -Wextra -Werror"])
    log = _run([_tool("cmake"), "--build", tmp_path, "--verbose"])
    assert "-std=c99" in log
    assert _run([tmp_path / "example"]) == _run([built.result.out_dir / "example"])


@pytest.mark.slow  # ~4 s; the package's CMake build and CTest stay in the quick suite
def test_cmake_install_gives_a_package_for_find_package(package, tmp_path):
    """A consumer project finds the installed package and links <prefix>::<prefix>."""
    built, cmake = package("aras3", "l2"), _tool("cmake")
    prefix, installed = built.result.prefix, tmp_path / "installed"
    _run([cmake, "-S", built.result.out_dir, "-B", tmp_path / "build",
          "-DCMAKE_C_COMPILER=gcc"])
    _run([cmake, "--build", tmp_path / "build"])
    _run([cmake, "--install", tmp_path / "build", "--prefix", installed])
    files = {path.relative_to(installed).as_posix() for path in installed.rglob("*")
             if path.is_file()}
    assert {f"lib/lib{prefix}.a", f"include/{prefix}.h", f"lib/cmake/{prefix}/{prefix}Config.cmake",
            f"lib/cmake/{prefix}/{prefix}ConfigVersion.cmake",
            f"lib/cmake/{prefix}/{prefix}Targets.cmake"} <= files
    assert not any(name.endswith(".inc") for name in files)  # the header needs no .inc
    app = tmp_path / "app"
    app.mkdir()
    (app / "CMakeLists.txt").write_text(f"""cmake_minimum_required(VERSION 3.11)
project(app C)
find_package({prefix} CONFIG REQUIRED)
add_executable(app app.c)
target_link_libraries(app PRIVATE {prefix}::{prefix})
""")
    (app / "app.c").write_text(f"""#include <stdio.h>
#include "{prefix}.h"
int main(void) {{
  static {prefix}_work work;
  double dq[{prefix.upper()}_N] = {{0}}, tau[{prefix.upper()}_N];
  int ret = {prefix}_control({prefix}_case_start, dq, {prefix}_case_goal, 0, 0, tau, 0, 0, 0,
                             0, &work);
  printf("%d\\n", ret);
  return ret;
}}
""")
    _run([cmake, "-S", app, "-B", app / "build", "-DCMAKE_C_COMPILER=gcc",
          f"-DCMAKE_PREFIX_PATH={installed}"])
    _run([cmake, "--build", app / "build"])
    assert _run([app / "build" / "app"]).strip() == "0"


@pytest.mark.slow
def test_cmake_and_make_optimise_by_default_and_keep_the_planner_at_o0(tmp_path):
    result = export_c("planar2", "smooth", tmp_path / "pkg")
    cmake, build = _tool("cmake"), tmp_path / "build"
    _run([cmake, "-S", result.out_dir, "-B", build, "-DCMAKE_C_COMPILER=gcc"])
    cache = (build / "CMakeCache.txt").read_text()
    assert "CMAKE_BUILD_TYPE:STRING=Release\n" in cache
    log = _run([cmake, "--build", build, "--verbose"]).splitlines()
    compiles = {name: next(line for line in log if f"{name} -c " in line or
                           line.rstrip().endswith(f"-c {result.out_dir / name}"))
                for name in (result.source.name, result.plan_source.name)}
    assert re.findall(r"-O\d", compiles[result.source.name])[-1] in ("-O2", "-O3")
    assert re.findall(r"-O\d", compiles[result.plan_source.name])[-1] == "-O0"
    commands = _run([_tool("make"), "-n"], cwd=result.out_dir).splitlines()
    assert re.findall(r"-O\d", next(c for c in commands if f"-c {result.source.name}" in c)) \
        == ["-O2"]
    assert re.findall(r"-O\d", next(c for c in commands
                                     if f"-c {result.plan_source.name}" in c)) == ["-O2", "-O0"]


def test_exported_law_matches_python_law_on_random_and_resting_states(
        package, aras3, rng, random_states, tmp_path):
    built = package("aras3", "l2")
    states = _states(aras3, "l2", rng, random_states, 1200)
    speeds = np.linalg.norm(states[:, 3:6], axis=1)
    assert np.sum(speeds == 0) >= 100 and np.sum((speeds > 0) & (speeds < 1e-6)) >= 100
    c_out = _split(_run_harness(built, states, tmp_path), aras3.n, aras3.n_j)
    python = _python_law(aras3, "l2", states)
    assert np.all(c_out["ret"] == 0)
    np.testing.assert_array_equal(c_out["flags"], python["flags"])
    for name in ("tau", "alpha", "beta", "j"):
        assert _relative_error(c_out[name], python[name]) <= TOLERANCE, name
    assert len(np.unique(python["flags"])) >= 3  # several branches of the law were exercised


@pytest.mark.parametrize("robot_name", ["aras3", "planar2"])  # 3 x 3 and 2 x 2 matrices
def test_exported_model_terms_match_symbolic_model_row_major(
        package, robot_name, request, rng, random_states, tmp_path):
    robot = request.getfixturevalue(robot_name)
    n = robot.n
    built = package(robot_name, "l2")
    states = _states(robot, "l2", rng, random_states, 200)
    c_out = _split(_run_harness(built, states, tmp_path), n, robot.n_j)
    for name in REQUIRED_MODEL_TERMS:
        python = _python_model_term(robot, name, states)
        assert _relative_error(c_out[name], python) <= TOLERANCE, name
    W = c_out["structure_matrix"].reshape(-1, n, n)  # row-major: column i points to anchor i
    towards = (robot.anchors[0] - states[:, :n])
    np.testing.assert_allclose(W[:, :, 0] * np.linalg.norm(towards, axis=1)[:, None], towards,
                               rtol=1e-12, atol=1e-12)


def test_example_closed_loop_matches_python_simulation(package, aras3):
    built = package("aras3", "l2")
    printed = _example_output(_run([built.result.out_dir / "example"]))
    run = _reference_run(aras3, "l2")
    np.testing.assert_allclose(printed["final_q"], run.q[-1], rtol=0, atol=1e-9)
    np.testing.assert_allclose(printed["final_dq"], run.dq[-1], rtol=0, atol=1e-9)
    np.testing.assert_allclose(printed["tension_min_N"], run.tau.min(), rtol=1e-9)
    np.testing.assert_allclose(printed["tension_max_N"], run.tau.max(), rtol=1e-9)
    np.testing.assert_allclose(printed["final_error"], np.linalg.norm(run.q[-1] - aras3.goal),
                               rtol=1e-6)


@pytest.mark.parametrize("controller", ["l2", "pd-sat"])
def test_readme_states_the_measured_agreement_with_python(package, aras3, controller):
    """Built at -O2 without fast-math, the example equals the CasADi virtual machine bit for
    bit, and the default compiled simulator too: it rounds every operation as written."""
    built = package("aras3", controller)
    readme = " ".join(built.result.readme.read_text().split())
    assert ('equal bit for bit those of `cdpr_sym.simulate(..., '
            'build_options=BuildOptions(backend="casadi"))`') in readme
    assert "gives the same bits too (tested on aras3 with l2 and pd-sat)" in readme
    assert "bit for bit" not in readme.replace('bit for bit those of `cdpr_sym.simulate(..., '
                                               'build_options=BuildOptions(backend="casadi"))',
                                               "")
    printed = _example_output(_run([built.result.out_dir / "example"]))
    exact = _reference_run(aras3, controller)
    np.testing.assert_array_equal(printed["final_q"], exact.q[-1])
    np.testing.assert_array_equal(printed["final_dq"], exact.dq[-1])
    np.testing.assert_array_equal(printed["tension_min_N"], exact.tau.min())
    np.testing.assert_array_equal(printed["tension_max_N"], exact.tau.max())
    compiled = simulate(aras3, controller_by_name(controller), duration=10.0)
    np.testing.assert_array_equal(printed["final_q"], compiled.q[-1])
    np.testing.assert_array_equal(printed["final_dq"], compiled.dq[-1])
    np.testing.assert_array_equal(printed["tension_min_N"], compiled.tau.min())


def test_harness_is_clean_under_valgrind(package, aras3, rng, random_states, tmp_path):
    built = package("aras3", "l2")
    states = _states(aras3, "l2", rng, random_states, 40)
    output = _run_harness(built, states, tmp_path, valgrind=True)
    assert output.shape[0] == 40


def test_library_calls_only_libm_and_sources_neither_print_nor_allocate(package):
    built = package("aras3", "l2")
    undefined = set(_run([_tool("nm"), "-u", built.library]).split()) - {"U"}
    undefined = {symbol.split("@")[0] for symbol in undefined if not symbol.endswith(":")}
    assert undefined <= LIBM, undefined - LIBM
    for path in (built.result.source, built.result.generated, built.result.header):
        text = path.read_text()
        assert not re.search(r"\b(printf|fprintf|puts|malloc|calloc|realloc|free)\s*\(", text)


def test_header_documents_sizes_flags_work_memory_and_model_terms(package):
    built = package("aras3", "l2")
    header, up = built.result.header.read_text(), built.result.prefix.upper()
    for bit, name in FLAG_NAMES.items():
        assert f"#define {up}_FLAG_{name.upper()} {bit}\n" in header
    for name in ("N 3", "NJ 3", "NX 7", "NP 12", "NLOG 9", "P_DT 9", "LOG_FLAGS 8"):
        assert f"#define {up}_{name} " in header or f"#define {up}_{name}\n" in header
    assert f"{up}_WORK_BYTES" in header and f"{up}_SZ_W" in header
    for name in ("control", "step", "parameters", *REQUIRED_MODEL_TERMS):
        assert re.search(rf"\b{built.result.prefix}_{name}\(", header), name
    assert "m/s" in header and "N s/m" in header


# -- every controller and preset; lighter checks ---------------------------------------------
#: spatial6's exports in the strict-build check: one design of each kind (plain PD, clipped
#: PD, the paper's least-squares J_d, a planner), as each design's code is the same for every
#: rigid body; its other designs are compiled and run by the rigid study's test.
SPATIAL_STRICT = ("pd", "pd-sat", "l2", "smooth")


@pytest.mark.slow
@pytest.mark.parametrize("robot", [name for name in PRESET_NAMES
                                   if preset(name).m == preset(name).n])
def test_every_controller_and_preset_builds_strict_and_reproduces_simulation(tmp_path, robot):
    """Presets with as many cables as degrees of freedom x every controller (spatial6:
    :data:`SPATIAL_STRICT`): strict build (planner at -O0, as the Makefile does), run. The
    robots with more cables are checked in the next section.

    aras3, planar3 and spatial6 are exported with ``avoid_stack=False`` (intermediates on the
    stack), which also halves the compile time of their large planners (spatial6's smooth
    planner, 2.8 MB of C, takes 60 s at -O0 with the default, 40 s without); planar2 with the
    default.
    """
    gcc = _tool("gcc")
    results = {(robot, controller): export_c(robot, controller, tmp_path / f"{robot}_{controller}",
                                             avoid_stack=robot == "planar2")
               for controller in CONTROLLERS
               if not capabilities(CONTROLLERS[controller]).sampled
               and not capabilities(CONTROLLERS[controller]).reads_drives
               and capabilities(CONTROLLERS[controller]).fully_actuated
               and (robot != "spatial6" or controller in SPATIAL_STRICT)}
    objects = {}
    for key, result in results.items():
        objects[key] = [(result.source, result.out_dir / "main.o", ())]
        if result.plan_source is not None:
            objects[key].append((result.plan_source, result.out_dir / "plan.o", ("-O0",)))
    compiles = sorted(([gcc, *STRICT, *extra, "-I", result.out_dir, "-c", source, "-o", target]
                       for key, result in results.items()
                       for source, target, extra in objects[key]),
                      key=lambda command: "-O0" not in command)  # the slow planners first
    with ThreadPoolExecutor(max_workers=os.cpu_count() or 1) as pool:
        list(pool.map(_run, compiles))
    for (_, controller), result in results.items():
        program = result.out_dir / "example"
        _run([gcc, *STRICT, "-I", result.out_dir, result.example,
              *(target for _, target, _ in objects[robot, controller]), "-lm", "-o", program])
        printed = _example_output(_run([program]))
        run = _reference_run(preset(robot), controller)
        np.testing.assert_allclose(printed["final_q"], run.q[-1], rtol=0, atol=1e-9,
                                   err_msg=f"{robot}/{controller}")
        np.testing.assert_allclose(printed["tension_max_N"], run.tau.max(), rtol=1e-9,
                                   err_msg=f"{robot}/{controller}")


@pytest.mark.parametrize(("robot_name", "controller"),
                         [pytest.param("aras3", "linf", marks=pytest.mark.slow),
                          ("planar2", "l2"),
                          pytest.param("planar2", "smooth", marks=pytest.mark.slow)])
def test_other_designs_match_python_law(package, robot_name, controller, rng, random_states,
                                        tmp_path):
    robot = preset(robot_name)
    built = package(robot_name, controller)
    states = _states(robot, controller, rng, random_states, 200)
    n_memory = controller_by_name(controller).memory_size(SymbolicModel(robot))
    c_out = _split(_run_harness(built, states, tmp_path), robot.n, robot.n_j, n_memory)
    python = _python_law(robot, controller, states)
    assert np.all(c_out["ret"] == 0)
    np.testing.assert_array_equal(c_out["flags"], python["flags"])
    names = ("tau", "alpha", "beta", "j", *(("memory_next", "memory0") if n_memory else ()))
    for name in names:
        assert _relative_error(c_out[name], python[name]) <= TOLERANCE, name


@pytest.mark.slow  # ~4 s
def test_two_robots_link_into_one_program(package, tmp_path):
    presets = Path(__file__).parents[1] / "cdpr_sym" / "robot" / "presets"
    toml = (presets / "planar2.toml").read_text()
    robot_file = tmp_path / "bot.toml"
    robot_file.write_text(toml.replace('name = "planar2"', 'name = "my bot-2"'))
    other = export_c(robot_file, "pd-sat", tmp_path / "other")
    assert other.prefix == "cdpr_my_bot_2_pd_sat"
    first = package("aras3", "l2").result
    main_c = tmp_path / "both.c"
    main_c.write_text(f"""#include <stdio.h>
#include "{first.prefix}.h"
#include "{other.prefix}.h"
int main(void) {{
  {first.prefix}_work a; {other.prefix}_work b;
  double zero[3] = {{0, 0, 0}}, t3[3], t2[2];
  int ra = {first.prefix}_control({first.prefix}_case_start, zero,
      {first.prefix}_case_goal, 0, 0, t3, 0, 0, 0, 0, &a);
  int rb = {other.prefix}_control({other.prefix}_case_start, zero,
      {other.prefix}_case_goal, 0, 0, t2, 0, 0, 0, 0, &b);
  printf("%d %d %.17g %.17g %.17g %.17g %.17g\\n", ra, rb, t3[0], t3[1], t3[2], t2[0], t2[1]);
  return 0;
}}
""")
    program = tmp_path / "both"
    _run([_tool("gcc"), *STRICT, "-I", first.out_dir, "-I", other.out_dir, main_c,
          first.source, other.source, "-lm", "-o", program])
    values = np.array(_run([program]).split(), dtype=float)
    assert values[0] == 0 and values[1] == 0
    for robot, controller, tau in ((preset("aras3"), "l2", values[2:5]),
                                   (preset("planar2"), "pd-sat", values[5:7])):
        law = law_function(SymbolicModel(robot), controller_by_name(controller))
        expected = np.array(law(robot.start, np.zeros(robot.n), robot.goal, robot.k,
                                robot.r_d, np.zeros(0), 1e-3)[0].full()).ravel()
        np.testing.assert_allclose(tau, expected, rtol=1e-12)


def test_export_is_deterministic(tmp_path):
    first = export_c("planar2", "box", tmp_path / "a")
    second = export_c("planar2", "box", tmp_path / "b")
    for one, two in zip(first.paths, second.paths, strict=True):
        assert one.read_bytes() == two.read_bytes(), one.name


def test_bench_export_measures_calls_per_second():
    assert bench_export("planar2", "pd", min_seconds=0.03) > 1e4


@pytest.mark.slow
def test_the_bench_of_a_planning_controller_times_code_built_with_o2(monkeypatch):
    from cdpr_sym.export import bench

    commands = []

    def recording(command, **options):
        commands.append([str(part) for part in command])
        return run_command(command, **options)

    monkeypatch.setattr(bench, "run_command", recording)
    assert bench_export("planar2", "smooth", min_seconds=0.03) > 1e3
    *compiles, timing = commands
    assert len(timing) == 1 and timing[0].endswith("bench")  # the program, run once
    timed = next(c for c in compiles if any(part.endswith("bench.c") for part in c))
    assert [part for part in timed if part.startswith("-O")] == ["-O2"]
    assert any(part.endswith("cdpr_bench.c") for part in timed)  # the control step's source


# -- more cables than degrees of freedom ------------------------------------------------------
#: Robot and controller pairs with m > n exported and run in the quick suite (spatial4 with
#: smooth is left out: its planner takes the compiler about ten minutes at -O0).
REDUNDANT = [("planar4", "pd-td"), pytest.param("planar4", "smooth", marks=pytest.mark.slow),
             ("spatial4", "l2"),
             ("spatial4", "pd-td")]


@dataclasses.dataclass(frozen=True)
class Example:
    """An exported package built with make (strict flags) and what its example printed."""

    result: ExportResult
    printed: dict[str, np.ndarray]


def _build_and_run_example(result: ExportResult) -> Example:
    """``result``'s package built by its Makefile with strict gcc flags, its example run."""
    _run([_tool("make"), "CC=gcc", f"CFLAGS={' '.join(STRICT)}"], cwd=result.out_dir)
    return Example(result, _example_output(_run([result.out_dir / "example"])))


@pytest.fixture(scope="module")
def example(tmp_path_factory):
    """``example(robot, controller)``: exported, built with make, example run (cached).

    Unlike :func:`package` it builds no harness, which calls the square-only ``a_matrix``.
    """
    built: dict[tuple[str, str], Example] = {}

    def get(robot: str, controller: str) -> Example:
        if (robot, controller) not in built:
            folder = tmp_path_factory.mktemp(f"{robot}_{controller}_example")
            built[robot, controller] = _build_and_run_example(
                export_c(robot, controller, folder / "pkg"))
        return built[robot, controller]
    return get


def _assert_example_matches_simulation(printed: dict[str, np.ndarray], robot,
                                       controller: str) -> None:
    """The example's final state, last tension (every cable) and tension range against the
    Python closed loop on CasADi's virtual machine (equal bit for bit at -O2, measured)."""
    run = _reference_run(robot, controller)
    label = f"{robot.name}/{controller}"
    assert printed["final_tau_N"].shape == (robot.m,), label
    np.testing.assert_allclose(printed["final_q"], run.q[-1], rtol=0, atol=1e-9, err_msg=label)
    np.testing.assert_allclose(printed["final_dq"], run.dq[-1], rtol=0, atol=1e-9, err_msg=label)
    np.testing.assert_allclose(printed["final_tau_N"], run.tau[-1], rtol=1e-9, err_msg=label)
    np.testing.assert_allclose(printed["tension_min_N"], run.tau.min(), rtol=1e-9, err_msg=label)
    np.testing.assert_allclose(printed["tension_max_N"], run.tau.max(), rtol=1e-9, err_msg=label)
    np.testing.assert_allclose(printed["final_error"], np.linalg.norm(run.q[-1] - robot.goal),
                               rtol=1e-6, atol=1e-300, err_msg=label)


@pytest.mark.parametrize(("robot_name", "controller"), REDUNDANT)
def test_example_of_a_robot_with_more_cables_matches_python_simulation(
        example, robot_name, controller):
    robot = preset(robot_name)
    assert robot.m > robot.n
    _assert_example_matches_simulation(example(robot_name, controller).printed, robot,
                                       controller)


def test_header_sizes_tensions_by_cables_and_coordinates_by_degrees_of_freedom(example):
    """planar4 (n = 2, m = 4) with pd-td: log = tau 4 + alpha + beta + j 1 + flags."""
    result = example("planar4", "pd-td").result
    header, up, prefix = result.header.read_text(), result.prefix.upper(), result.prefix
    for name in ("N 2", "M 4", "NJ 1", "NX 5", "NP 9", "NLOG 8", "LOG_TAU 0", "LOG_ALPHA 4",
                 "LOG_FLAGS 7", "P_DT 6"):
        assert f"#define {up}_{name} " in header or f"#define {up}_{name}\n" in header, name
    declaration = re.sub(r"\s+", " ", header[header.index(f"int {prefix}_control("):])
    assert declaration.startswith(f"int {prefix}_control(const double q[2], const double dq[2], "
                                  f"const double q_goal[2], const double k[2], "
                                  f"const double r_d[2], double tau[4], ")
    assert f"extern const double {prefix}_case_start[{up}_N];" in header
    assert re.search(rf"int {prefix}_static_tension\(const double q\[2\], double tau_1\[4\]",
                     re.sub(r"\s+", " ", header))
    assert f"_{prefix}_a_matrix" not in header and "`_a_matrix`" not in result.readme.read_text()
    readme = " ".join(result.readme.read_text().split())
    assert f"n = `{up}_N` = 2" in readme and f"m = `{up}_M` = 4" in readme


@pytest.mark.parametrize(("robot_name", "controller"), [("planar4", "pd-td"),
                                                         ("spatial4", "l2")])
def test_control_call_of_a_robot_with_more_cables_matches_python_law_under_valgrind(
        example, robot_name, controller, rng, random_states, tmp_path):
    """``_control`` writes one tension per cable (the law's, or T_MIN on every cable for a
    NaN input) into an array of exactly M doubles on the heap, as valgrind checks."""
    robot, result = preset(robot_name), example(robot_name, controller).result
    prefix, up = result.prefix, result.prefix.upper()
    q, dq = random_states(robot, rng, 20)
    states = np.vstack([np.column_stack([q, dq]), np.r_[np.full(robot.n, np.nan),
                                                        np.zeros(robot.n)]])
    rows = ",\n".join("{" + ", ".join("NAN" if np.isnan(value) else repr(float(value))
                                        for value in state) + "}" for state in states)
    program = tmp_path / "call.c"
    program.write_text(f"""#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include "{prefix}.h"
static const double states[][2 * {up}_N] = {{
{rows}}};
int main(void) {{
  {prefix}_work *work = ({prefix}_work *) malloc(sizeof({prefix}_work));
  double *tau = (double *) malloc({up}_M * sizeof(double));
  size_t s;
  int i;
  for (s = 0; s < sizeof states / sizeof states[0]; ++s) {{
    int ret = {prefix}_control(states[s], states[s] + {up}_N, {prefix}_case_goal, 0, 0, tau,
                               0, 0, 0, 0, work);
    printf("%d", ret);
    for (i = 0; i < {up}_M; ++i) printf(" %.17g", tau[i]);
    printf("\\n");
  }}
  free(tau);
  free(work);
  return 0;
}}
""")
    _run([_tool("gcc"), *STRICT, "-g", "-I", result.out_dir, program, result.source, "-lm",
          "-o", tmp_path / "call"])
    output = np.loadtxt(_run([_tool("valgrind"), "--error-exitcode=1", "--leak-check=full",
                              "-q", tmp_path / "call"]).splitlines())
    assert output.shape == (len(states), 1 + robot.m)
    np.testing.assert_array_equal(output[:-1, 0], 0)
    law = law_function(SymbolicModel(robot), controller_by_name(controller)).map(len(q))
    expected = np.array(law(q.T, dq.T, robot.goal, robot.k, robot.r_d, np.zeros((0, len(q))),
                            1e-3)[0].full()).T
    assert _relative_error(output[:-1, 1:], expected) <= TOLERANCE
    assert output[-1, 0] == 1  # CONTROL_INVALID_INPUT, the safe command on every cable
    np.testing.assert_array_equal(output[-1, 1:], robot.t_min)


def test_a_controller_that_inverts_w_is_refused_on_more_cables_naming_it(tmp_path, capsys):
    """Exported like simulated: every design but the redundant ones is refused, in one line
    naming the controller, before any file is written."""
    redundant = {name for name, design in CONTROLLERS.items()
                 if capabilities(design).any_cables}
    assert {"pd-td", "smooth", "l2"} <= redundant
    fewer_only = {name for name, design in CONTROLLERS.items()
                  if not capabilities(design).fully_actuated}
    for robot in (name for name in PRESET_NAMES if preset(name).m > preset(name).n):
        for name in set(CONTROLLERS) - redundant - fewer_only:
            design = controller_by_name(name)
            with pytest.raises(InvalidCase, match=rf"^controller: {re.escape(design.name)} "
                               r"needs as many cables") as raised:
                export_c(robot, name, tmp_path / robot / name)
            assert raised.value.field == "controller"
    assert not any(tmp_path.iterdir())
    with pytest.raises(InvalidCase, match=r"^controller: pd-sat needs as many cables"):
        bench_export("planar4", "pd-sat", min_seconds=0.01)
    out = tmp_path / "pkg"
    assert main(["export-c", "--robot", "planar4", "--controller", "pd-sat", "--out",
                 str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("cdpr-sym: error: controller: pd-sat needs as many cables")
    assert len(err.strip().splitlines()) == 1 and not out.exists()


def _sanitizing_compiler(folder: Path) -> Path:
    """A gcc that builds with AddressSanitizer (the test is skipped where it cannot)."""
    gcc, compiler = _tool("gcc"), folder / "gcc-asan"
    compiler.write_text(f'#!/bin/sh\nexec {gcc} -fsanitize=address -fno-omit-frame-pointer "$@"\n')
    compiler.chmod(0o755)
    probe = folder / "probe.c"
    probe.write_text("int main(void) { return 0; }\n")
    try:
        run_command([compiler, probe, "-o", folder / "probe"])
        run_command([folder / "probe"])
    except CompilationFailed:
        pytest.skip("gcc cannot build with -fsanitize=address here")
    return compiler


def test_bench_export_times_a_robot_with_more_cables(tmp_path, monkeypatch):
    """The timing program holds one tension per cable: built with AddressSanitizer, which
    aborts it on a write past an array sized by the degrees of freedom."""
    monkeypatch.setenv("ASAN_OPTIONS", "detect_leaks=0")  # leak checks need ptrace rights
    compiler = _sanitizing_compiler(tmp_path)
    assert bench_export("planar4", "pd-td", min_seconds=0.03, compiler=str(compiler)) > 1e3


@pytest.mark.slow
@pytest.mark.parametrize("controller", ["pd-td", "l2"])
def test_ipanema8_example_matches_python_simulation(tmp_path, controller):
    """The 6-DOF platform on eight cables (the large exports: each builds in about 10 s)."""
    built = _build_and_run_example(export_c("ipanema8", controller, tmp_path / "pkg"))
    _assert_example_matches_simulation(built.printed, preset("ipanema8"), controller)


# -- bad input -------------------------------------------------------------------------------
def test_unknown_controller_or_robot_raises_unknown_name(tmp_path):
    with pytest.raises(UnknownName, match="unknown controller 'nope'"):
        export_c("aras3", "nope", tmp_path / "out")
    with pytest.raises(UnknownName, match="unknown robot 'nowhere'"):
        export_c("nowhere", "l2", tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_a_law_argument_the_exporter_does_not_know_raises_invalid_case(tmp_path, monkeypatch):
    """A law with an argument that ``<prefix>_control`` has no declaration for is refused
    as the controller's fault, naming the argument, and no file is written."""
    from cdpr_sym.export import description

    def law_with_a_gain(model, controller):
        law = law_function(model, controller)
        inputs = law.sx_in()
        return ca.Function(law.name(), [*inputs, ca.SX.sym("gain")], law.call(inputs),
                           [*law.name_in(), "gain"], law.name_out())

    monkeypatch.setattr(description, "law_function", law_with_a_gain)
    with pytest.raises(InvalidCase, match=r"^controller: .*\['gain'\]") as raised:
        export_c("planar2", "pd", tmp_path / "pkg")
    assert raised.value.field == "controller"
    assert not any((tmp_path / "pkg").iterdir())


def test_existing_file_as_out_dir_raises_invalid_case(tmp_path):
    existing = tmp_path / "file"
    existing.write_text("keep me")
    with pytest.raises(InvalidCase, match="out_dir: expected a folder"):
        export_c("aras3", "l2", existing)
    with pytest.raises(InvalidCase, match="out_dir: cannot create"):
        export_c("aras3", "l2", existing / "below")
    assert existing.read_text() == "keep me"


def test_non_empty_foreign_folder_is_refused_unless_overwrite(tmp_path):
    folder = tmp_path / "mine"
    folder.mkdir()
    (folder / "notes.txt").write_text("keep me")
    with pytest.raises(InvalidCase, match=r"out_dir: the folder .* is not empty") as raised:
        export_c("planar2", "pd", folder)
    assert raised.value.field == "out_dir"
    assert sorted(path.name for path in folder.iterdir()) == ["notes.txt"]
    (folder / "manifest.json").write_text('{"name": "something else"}')
    with pytest.raises(InvalidCase, match="out_dir"):  # another tool's manifest
        export_c("planar2", "pd", folder)
    result = export_c("planar2", "pd", folder, overwrite=True)
    assert result.header.exists() and (folder / "notes.txt").read_text() == "keep me"
    # an earlier export (its manifest), build products included, is re-exported; so is an
    # empty folder
    (tmp_path / "pkg").mkdir()
    export_c("planar2", "pd", tmp_path / "pkg")
    (tmp_path / "pkg" / "example").write_text("a build product")
    again = export_c("planar2", "pd-sat", tmp_path / "pkg")
    assert again.header.exists() and '"pd-sat"' in again.manifest.read_text()


def test_cli_export_c_refuses_a_foreign_folder_in_one_line_unless_force(tmp_path, capsys):
    (tmp_path / "notes.txt").write_text("keep me")
    argv = ["export-c", "--robot", "planar2", "--controller", "pd", "--out", str(tmp_path)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("cdpr-sym: error: out_dir") and len(err.strip().splitlines()) == 1
    assert "--force" in err and not (tmp_path / "cdpr_planar2_pd.h").exists()
    assert main([*argv, "--force"]) == 0
    assert (tmp_path / "cdpr_planar2_pd.h").exists()
    assert (tmp_path / "notes.txt").read_text() == "keep me"
    capsys.readouterr()
    assert main(argv) == 0  # now an earlier export: re-exported without --force


def test_prefix_must_be_a_c_identifier(tmp_path):
    with pytest.raises(InvalidCase, match="prefix"):
        export_c("aras3", "l2", tmp_path, prefix="9-lives")


def test_cli_export_c_writes_package_and_reports_bad_input(tmp_path, capsys):
    assert main(["export-c", "--robot", "planar2", "--controller", "pd", "--out",
                 str(tmp_path / "pkg")]) == 0
    assert (tmp_path / "pkg" / "cdpr_planar2_pd.h").exists()
    assert "cdpr_planar2_pd.h" in capsys.readouterr().out
    (tmp_path / "file").write_text("")
    with pytest.raises(SystemExit) as done:  # --controller lists its choices
        main(["export-c", "--controller", "nope", "--out", str(tmp_path / "x")])
    assert done.value.code == 2 and "invalid choice: 'nope'" in capsys.readouterr().err
    assert main(["export-c", "--robot", "nowhere", "--out", str(tmp_path / "x")]) == 2
    assert capsys.readouterr().err.startswith("cdpr-sym: error: unknown")
    assert main(["export-c", "--out", str(tmp_path / "file")]) == 2
    assert "cdpr-sym: error: out_dir" in capsys.readouterr().err


def test_generated_code_is_casadi_codegen_of_the_law(package):
    built = package("aras3", "l2")
    text = built.result.generated.read_text()
    assert f"Generated by CasADi {ca.__version__}" in text
    assert f"int {built.result.prefix}_cg_control(" in text


def test_default_prefix_names_the_registered_controller(tmp_path):
    """l2 and l2-minnorm share a class name; their packages must not clash when linked."""
    first = export_c("planar2", "l2", tmp_path / "a")
    second = export_c("planar2", "l2-minnorm", tmp_path / "b")
    assert first.prefix == "cdpr_planar2_l2" and second.prefix == "cdpr_planar2_l2_minnorm"


def test_an_export_goes_into_a_new_folder_below_new_folders(tmp_path):
    nested = tmp_path / "a" / "b" / "pkg"
    result = export_c("planar2", "pd", nested)
    assert result.header.parent == nested and result.header.exists()


def test_the_manifest_records_the_robot_exported(tmp_path):
    result = export_c("planar2", "pd", tmp_path / "pkg")
    manifest = json.loads(result.manifest.read_text())
    assert manifest["robot"] == preset("planar2").as_dict()
    assert manifest["controller"] == {"name": "pd", "options": {}}
    assert manifest["prefix"] == "cdpr_planar2_pd" and manifest["casadi_version"] == ca.__version__
    # every file written but the manifest, with the hash of what is on disk
    written = sorted(path.name for path in result.out_dir.iterdir() if path.name != "manifest.json")
    assert sorted(manifest["sha256"]) == written
    for name, digest in manifest["sha256"].items():
        assert hashlib.sha256((result.out_dir / name).read_bytes()).hexdigest() == digest, name


def test_an_export_from_before_the_generator_entry_is_known_by_its_other_entries(tmp_path):
    older = {"prefix": "p", "robot": {}, "controller": "pd", "casadi_version": "3.6",
             "sha256": {}}
    folder = tmp_path / "older"
    folder.mkdir()
    (folder / "p.h").write_text("/* an older package */")
    (folder / "manifest.json").write_text(json.dumps(older))
    assert export_c("planar2", "pd", folder).header.exists()  # re-exported without force
    for missing in older:
        folder = tmp_path / f"without_{missing}"
        folder.mkdir()
        (folder / "p.h").write_text("/* not known as a package */")
        (folder / "manifest.json").write_text(
            json.dumps({key: value for key, value in older.items() if key != missing}))
        with pytest.raises(InvalidCase, match="out_dir"):
            export_c("planar2", "pd", folder)


def test_a_refused_prefix_is_shown_whole_unless_it_is_long():
    assert prefix_problem("a__b").endswith("got 'a__b'")
    assert prefix_problem("p" * 300).endswith(f"got {'p' * 40!r}... (300 characters)")
    assert prefix_problem("main").endswith("the example program's file main.c")
    assert prefix_problem("Main").endswith("file main.c (where file names ignore case)")
    assert prefix_problem("Stdio").endswith("on its include path (where file names ignore case)")


def test_the_result_names_every_file_written(tmp_path):
    planned = export_c("planar2", "smooth", tmp_path / "planned")
    assert planned.plan_source.name == "cdpr_planar2_smooth_plan.c"
    assert planned.plan_generated.name == "cdpr_planar2_smooth_plan_generated.inc"
    assert planned.plan_source.exists() and planned.plan_generated.exists()
    stateless = export_c("planar2", "pd", tmp_path / "stateless")
    assert stateless.plan_source is None and stateless.plan_generated is None
    assert not list(stateless.out_dir.glob("cdpr_planar2_pd_plan*"))


_FK_PROGRAM = """#include <stdio.h>
#include "{prefix}.h"
int main(void) {{
  static {prefix}_work work;
  double q_true[{n}] = {{{q_true}}}, guess[{n}] = {{{guess}}}, far[{n}] = {{{far}}};
  double lengths[{m}], q[{n}], ok, residual;
  int i;
  if ({prefix}_cable_lengths(q_true, lengths, &work) != 0) return 1;
  if ({prefix}_forward_kinematics(lengths, guess, q, &ok, &residual, &work) != 0) return 1;
  printf("%.0f %.17g", ok, residual);
  for (i = 0; i < {n}; ++i) printf(" %.17g", q[i]);
  for (i = 0; i < {m}; ++i) lengths[i] *= 0.1; /* no pose in the frame has these */
  if ({prefix}_forward_kinematics(lengths, far, q, &ok, &residual, &work) != 0) return 1;
  printf(" %.0f\\n", ok);
  return 0;
}}
"""


@pytest.mark.slow
@pytest.mark.parametrize("robot_name", ["planar3", "spatial4"])
def test_exported_forward_kinematics_finds_the_pose_of_the_exported_lengths(
        robot_name, tmp_path, rng):
    """The package's forward kinematics, fed the package's own cable lengths of a pose, finds
    that pose from a guess a millimetre and a milliradian away, as the Python solver does;
    lengths no pose has are flagged. The forward kinematics is the same in every package, so
    a design without a planner keeps the build short (with planar3's smooth planner compiled
    at -O2 this test took 60 s)."""
    robot = preset(robot_name)
    controller = "pd" if robot.m == robot.n else "pd-td"
    result = export_c(robot, controller, tmp_path / "pkg")
    prefix = result.header.stem
    q_true = robot.start + rng.uniform(-0.05, 0.05, robot.n)
    guess = q_true + rng.choice([-1e-3, 1e-3], robot.n)
    source = _FK_PROGRAM.format(prefix=prefix, n=robot.n, m=robot.m,
                                q_true=", ".join(repr(float(v)) for v in q_true),
                                guess=", ".join(repr(float(v)) for v in guess),
                                far=", ".join(repr(float(v)) for v in robot.start))
    (tmp_path / "fk.c").write_text(source)
    program = tmp_path / "fk"
    sources = [str(path) for path in result.out_dir.glob("*.c") if path.name != "main.c"]
    _run([_tool("gcc"), *STRICT, "-I", str(result.out_dir), str(tmp_path / "fk.c"), *sources,
          "-lm", "-o", str(program)])
    values = [float(v) for v in _run([program]).split()]
    ok, residual, q, failed = values[0], values[1], np.array(values[2:-1]), values[-1]
    assert ok == 1 and residual <= 1e-9 and failed == 0
    np.testing.assert_allclose(q, q_true, rtol=0, atol=1e-9)
    from cdpr_sym import forward_kinematics
    lengths = np.array(SymbolicModel(robot).functions["cable_lengths"](q_true)).ravel()
    np.testing.assert_allclose(q, forward_kinematics(robot, lengths, guess).q, rtol=0,
                               atol=1e-12)
