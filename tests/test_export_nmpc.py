"""The exported NMPC: its real-time iteration in C against the Python closed loop.

The reference is :func:`cdpr_sym.simulate` evaluated by CasADi's virtual machine (the
solver's QP in CasADi's own ``qrqp`` plugin, its loop in :mod:`cdpr_sym.closed_loop.sampled`),
so the C is checked against a second implementation of every part but the generated
expressions: the result check, the retry, the safe command and the warm start's shift.
"""

from __future__ import annotations

import dataclasses
import json
import re
from pathlib import Path

import numpy as np
import pytest
from tools import STRICT, run, tool

from cdpr_sym import BuildOptions, SymbolicModel, simulate
from cdpr_sym.cli import main
from cdpr_sym.control import tuning
from cdpr_sym.control.nmpc import Nmpc, NmpcProblem
from cdpr_sym.export import export_c
from cdpr_sym.sweep.config import SweepConfig, draw_pairs

#: What the solver's object may call: libm and the C library's block copies (no heap, I/O).
ALLOWED = {"sqrt", "fabs", "fmin", "fmax", "floor", "ceil", "pow", "exp", "log", "sin", "cos",
           "atan2", "memcpy", "memset", "memmove"}
#: Pair 22 of the committed designs study: at 200 N/s, over the horizon of an eighth of the
#: frame's move (the rule's horizon when the pair was found; over half the frame qrqp's
#: plans pass there), its plan is retried and falls back.
HARD_PAIR = 22


def _build(robot, design, folder: Path):
    result = export_c(robot, design, folder)
    run([tool("make"), "CC=gcc", f"CFLAGS={' '.join(STRICT)}"], cwd=folder)
    return result


def _printed(text: str) -> dict[str, np.ndarray]:
    values = {line.split()[0]: np.array(line.split()[1:], dtype=float)
              for line in text.splitlines() if re.match(r"(final|tension)_", line)}
    counts = re.search(r"nmpc_samples (\d+) solved (\d+) retried (\d+) fallback (\d+) "
                       r"invalid_input (\d+)", text)
    assert counts, text
    values["counts"] = np.array(counts.groups(), dtype=int)
    return values


def _assert_same_closed_loop(printed: dict[str, np.ndarray], robot, design) -> None:
    # the package has no DAQP: it is the design without its last resort
    design = dataclasses.replace(design, last_resort=None)
    reference = simulate(robot, design, duration=10.0,
                         build_options=BuildOptions(backend="casadi"))
    solver = reference.info["solver"]
    np.testing.assert_allclose(printed["final_q"], reference.q[-1], rtol=0, atol=1e-9)
    np.testing.assert_allclose(printed["final_dq"], reference.dq[-1], rtol=0, atol=1e-9)
    np.testing.assert_allclose(printed["final_tau_N"], reference.tau[-1], rtol=1e-9)
    np.testing.assert_allclose(printed["tension_min_N"], reference.tau.min(), rtol=1e-9)
    np.testing.assert_allclose(printed["tension_max_N"], reference.tau.max(), rtol=1e-9)
    retried, failed = solver["retried_samples"], solver["failed_samples"]
    expected = [solver["samples"], solver["samples"] - retried - failed, retried, failed, 0]
    assert printed["counts"].tolist() == expected


@pytest.fixture(scope="module")
def aras3_nmpc(tmp_path_factory):
    return _build("aras3", "nmpc", tmp_path_factory.mktemp("nmpc") / "pkg")


@pytest.mark.slow  # the package's build (~12 s) is shared by the slow checks
def test_the_example_equals_the_python_closed_loop(aras3_nmpc, aras3):
    printed = _printed(run([aras3_nmpc.out_dir / "example"]))
    assert printed["counts"][0] == 500  # 10 s at 50 Hz
    _assert_same_closed_loop(printed, aras3, Nmpc())


@pytest.mark.slow
def test_retries_and_safe_commands_happen_where_python_has_them(aras3, tmp_path):
    """A pair and rate limit where qrqp's plans fail the check: the C retries and falls
    back at the same samples as Python, so the whole 10 s loop agrees."""
    # the pair as the designs study drew it (its sweep table is regenerated, not kept in
    # git; its sidecar, which records the draw, is)
    sidecar = Path(__file__).parents[1] / "reports" / "designs" / "sweep_mass_1.0.csv.json"
    config = json.loads(sidecar.read_text())["config"]
    starts, goals = draw_pairs(aras3, SweepConfig(**{
        key: tuple(value) if isinstance(value, list) else value
        for key, value in config.items()}))
    robot = aras3.with_case(start=starts[HARD_PAIR], goal=goals[HARD_PAIR])
    _, _, eighth = tuning.nmpc_scales(robot, 200.0)
    design = Nmpc(max_rate=200.0, horizon=eighth)
    result = _build(robot, design, tmp_path / "pkg")
    printed = _printed(run([result.out_dir / "example"]))
    assert printed["counts"][2] > 0 and printed["counts"][3] > 0  # retried, fallen back
    _assert_same_closed_loop(printed, robot, design)


def _harness(package, body: str, folder: Path) -> str:
    source = folder / "harness.c"
    source.write_text(
        '#include <math.h>\n#include <stdio.h>\n#include "cdpr_aras3_nmpc.h"\n'
        "int main(void) {\n"
        "  static cdpr_aras3_nmpc_work work;\n"
        "  static cdpr_aras3_nmpc_nmpc_state state;\n"
        "  static cdpr_aras3_nmpc_nmpc_work nmpc;\n"
        "  double memory[CDPR_ARAS3_NMPC_NMEM], q[3], dq[3] = {0.0, 0.0, 0.0};\n"
        "  int i;\n"
        "  for (i = 0; i < 3; ++i) q[i] = cdpr_aras3_nmpc_case_start[i];\n"
        "  if (cdpr_aras3_nmpc_initial_memory(q, cdpr_aras3_nmpc_case_goal,\n"
        "      cdpr_aras3_nmpc_case_k, cdpr_aras3_nmpc_case_r_d, memory, &work)) return 3;\n"
        "  if (cdpr_aras3_nmpc_nmpc_start(0, &state, &nmpc)) return 4;\n"
        f"{body}\n  return 0;\n}}\n")
    program = folder / "harness"
    run([tool("gcc"), *STRICT, "-I", package.out_dir, source,
         package.out_dir / "libcdpr_aras3_nmpc.a", "-lm", "-o", program])
    return run([program])


@pytest.mark.slow  # the package's build (~12 s) is shared by the slow checks
def test_a_state_that_is_not_finite_holds_the_last_command_and_is_flagged(aras3_nmpc,
                                                                          tmp_path):
    """No plan from NaN: the rate is 0, the sample flagged; the next finite state solves."""
    body = r"""
  q[1] = NAN;
  i = cdpr_aras3_nmpc_nmpc_sample(q, dq, 0, memory, &state, &nmpc);
  printf("%d %g %g %g %g\n", i, memory[3], memory[4], memory[5], memory[6]);
  q[1] = cdpr_aras3_nmpc_case_start[1];
  i = cdpr_aras3_nmpc_nmpc_sample(q, dq, 0, memory, &state, &nmpc);
  printf("%d %g %d\n", i, memory[6], state.warm);
  printf("%d\n", cdpr_aras3_nmpc_nmpc_sample(q, 0, 0, memory, &state, &nmpc));"""
    lines = _harness(aras3_nmpc, body, tmp_path).splitlines()
    header = aras3_nmpc.header.read_text()
    infeasible = int(re.search(r"_FLAG_INFEASIBLE (\d+)", header).group(1))
    invalid = int(re.search(r"_NMPC_INVALID_INPUT (\d+)", header).group(1))
    assert lines[0].split() == [str(invalid), "0", "0", "0", str(infeasible)]
    assert lines[1].split() == ["0", "0", "1"]  # solved, unflagged, warm for the next
    assert lines[2] == "-1"  # a NULL pointer


@pytest.mark.slow  # the package's build (~12 s) is shared by the slow checks
def test_one_sample_writes_the_rate_and_the_shifted_warm_start_of_the_python_problem(
        aras3_nmpc, aras3, tmp_path):
    """From rest at the case's start: the first rate in the memory, and the guess and
    multipliers of the next sample, against the problem's own shift of CasADi's solution."""
    body = r"""
  i = cdpr_aras3_nmpc_nmpc_sample(q, dq, 0, memory, &state, &nmpc);
  printf("%d\n", i);
  for (i = 0; i < CDPR_ARAS3_NMPC_NMEM; ++i) printf("%.17g ", memory[i]);
  printf("\n");
  for (i = 0; i < CDPR_ARAS3_NMPC_NMPC_NV; ++i) printf("%.17g ", state.guess[i]);
  printf("\n");
  for (i = 0; i < CDPR_ARAS3_NMPC_NMPC_NMULT; ++i) printf("%.17g ", state.multipliers[i]);
  printf("\n");"""
    lines = _harness(aras3_nmpc, body, tmp_path).splitlines()
    memory, guess, multipliers = (np.array(line.split(), dtype=float) for line in lines[1:])
    model = SymbolicModel(aras3)
    problem = NmpcProblem(model, Nmpc())
    tau0 = np.array(model.functions["static_tension"](aras3.start)).ravel()
    z0 = np.r_[aras3.start, np.zeros(3), tau0]
    goal_tension = np.array(model.functions["static_tension"](aras3.goal)).ravel()
    v, _, duals = (np.array(value).ravel() for value in problem.rti_function(True)(
        z0, problem.hold(z0), np.zeros(problem.multiplier_size), aras3.goal, goal_tension,
        np.zeros(aras3.m)))
    assert lines[0] == "0"
    np.testing.assert_allclose(memory, np.r_[tau0, v[:3], 0.0], rtol=0, atol=1e-9)
    np.testing.assert_allclose(guess, problem.shifted(v), rtol=0, atol=1e-9)
    np.testing.assert_allclose(multipliers, problem.shifted_multipliers(duals), rtol=0,
                               atol=1e-9)
    assert np.count_nonzero(multipliers) > 0  # some bound or row is active


@pytest.mark.slow  # the package's build (~12 s) is shared by the slow checks
def test_the_solver_neither_prints_nor_allocates(aras3_nmpc):
    objects = run([tool("nm"), "-u", aras3_nmpc.out_dir / f"{aras3_nmpc.prefix}_nmpc.o"])
    undefined = {symbol.split("@")[0] for symbol in objects.split()
                 if symbol != "U" and not symbol.startswith(f"{aras3_nmpc.prefix}_")}
    assert undefined <= ALLOWED, undefined - ALLOWED
    for path in (aras3_nmpc.nmpc_source, aras3_nmpc.nmpc_generated):
        assert not re.search(r"\b(printf|fprintf|puts|malloc|calloc|realloc|free)\s*\(",
                             path.read_text())


@pytest.mark.slow  # the package's build (~12 s) is shared by the slow checks
def test_the_manifest_and_result_name_the_solver_files(aras3_nmpc):
    assert aras3_nmpc.nmpc_source.exists() and aras3_nmpc.nmpc_generated.exists()
    assert {aras3_nmpc.nmpc_source, aras3_nmpc.nmpc_generated} <= set(aras3_nmpc.paths)
    manifest = aras3_nmpc.manifest.read_text()
    assert aras3_nmpc.nmpc_generated.name in manifest
    assert f"{aras3_nmpc.prefix}_nmpc_cg_rti" in manifest
    # the package is the design without DAQP, and says so
    assert json.loads(manifest)["controller"]["options"]["last_resort"] is None


@pytest.mark.slow
def test_cmake_builds_the_solver_and_its_example_prints_the_same(aras3_nmpc, tmp_path):
    run([tool("cmake"), "-S", aras3_nmpc.out_dir, "-B", tmp_path, "-DCMAKE_C_COMPILER=gcc",
         "-DCMAKE_C_FLAGS=-Wall -Wextra -Werror"])
    run([tool("cmake"), "--build", tmp_path])
    assert run([tmp_path / "example"]) == run([aras3_nmpc.out_dir / "example"])


@pytest.mark.parametrize("controller", ["nmpc-sqp", "nmpc-ipopt"])
def test_a_converged_solver_is_refused_in_one_line_before_writing(controller, tmp_path,
                                                                  capsys):
    out = tmp_path / "package"
    assert main(["export-c", "--robot", "aras3", "--controller", controller, "--out",
                 str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("cdpr-sym: error: solver:"), err
    assert not out.exists()


@pytest.mark.parametrize(("controller", "field"), [("nmpc-of", "observer_rate"),
                                                   ("ida-winch", "controller")])
def test_a_design_the_package_cannot_feed_is_refused_in_one_line(controller, field, tmp_path,
                                                                 capsys):
    """The offset-free NMPC's observer is not exported; ida-winch reads the winch encoders,
    which a package of state-based laws does not take."""
    out = tmp_path / "package"
    assert main(["export-c", "--robot", "aras3", "--controller", controller, "--out",
                 str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"cdpr-sym: error: {field}:"), err
    assert not out.exists()


def test_the_export_says_its_nmpc_has_no_last_resort(tmp_path, capsys):
    """The package is the design without DAQP: the command says so beside its files, and a
    package of a law that is no NMPC says nothing."""
    assert main(["export-c", "--robot", "aras3", "--controller", "nmpc", "--out",
                 str(tmp_path / "nmpc"), "--json"]) == 0
    notes = json.loads(capsys.readouterr().out)["notes"]
    assert len(notes) == 1 and "last_resort=None" in notes[0]
    assert main(["export-c", "--robot", "aras3", "--controller", "pd", "--out",
                 str(tmp_path / "pd"), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["notes"] == []
