"""qrqp keeping its KKT factors while the KKT matrix is unchanged: CasADi's own C against
the same C with the factorisation reused, solve by solve, to the bit."""

from __future__ import annotations

from pathlib import Path

import casadi as ca
import numpy as np
import pytest
from tools import run, tool

from cdpr_sym import Nmpc
from cdpr_sym.codegen import BuildOptions
from cdpr_sym.codegen.generate import generate_c, reuse_qrqp_factorization
from cdpr_sym.codegen.native import NativeLibrary
from cdpr_sym.control import NmpcProblem


def _casadi_source(function: ca.Function) -> str:
    """CasADi's C of ``function``, exactly as its code generator writes it."""
    generator = ca.CodeGenerator("plain.c", {"with_header": False, "verbose": False})
    generator.add(function)
    return generator.dump()


def _compiled(source: str, folder: Path, name: str):
    path = folder / f"{name}.c"
    path.write_text(source)
    library = folder / f"{name}.so"
    run([tool("gcc"), *BuildOptions().flags, "-shared", "-fPIC", path, "-o", library, "-lm"])
    return NativeLibrary(library).casadi_function("nmpc_rti")


def test_generated_solvers_carry_the_reuse(aras3_model):
    """The installed CasADi's qrqp text is the one the rewrite knows, and the package's
    generator applies it (a CasADi whose text differs would silently lose the saving)."""
    function = NmpcProblem(aras3_model, Nmpc()).rti_function()
    plain = _casadi_source(function)
    assert reuse_qrqp_factorization(plain) != plain
    assert "if (casadi_qrqp_kkt(d) || d->iter == 0)" in generate_c([function], "rti")


@pytest.mark.slow
def test_reused_factors_give_casadis_results_to_the_bit(aras3, aras3_model, rng, tmp_path):
    """Closed-loop-like solves (warm-started from the shifted solution and multipliers, the
    state moved between samples, a cold start among them) give the same plan, residual and
    multipliers from both builds."""
    problem = NmpcProblem(aras3_model, Nmpc())
    function = problem.rti_function()
    plain = _casadi_source(function)
    solvers = [_compiled(plain, tmp_path, "plain"),
               _compiled(reuse_qrqp_factorization(plain), tmp_path, "reused")]
    static = aras3_model.functions["static_tension"]
    goal = np.array(aras3.goal)
    tau_goal = np.array(static(goal)).ravel()
    start = np.array(aras3.start)
    z0 = np.r_[start, np.zeros(3), np.array(static(start)).ravel()]
    guess, multipliers = problem.hold(z0), np.zeros(problem.multiplier_size)
    for sample in range(30):
        if sample == 15:  # a cold start half way
            guess, multipliers = problem.hold(z0), np.zeros(problem.multiplier_size)
        outputs = []
        for solver in solvers:
            out = [np.empty(problem.size), np.empty(1), np.empty(problem.multiplier_size)]
            solver.evaluate([z0, guess, multipliers, goal, tau_goal, np.zeros(aras3.m)], out)
            outputs.append(out)
        for plain_out, reused_out in zip(*outputs, strict=True):
            np.testing.assert_array_equal(reused_out, plain_out)
        v, duals = outputs[0][0], outputs[0][2]
        assert problem.checked(v, float(outputs[0][1][0]))
        guess, multipliers = problem.shifted(v), problem.shifted_multipliers(duals)
        # the next sample starts from the plan's next state, nudged
        z0 = v[problem.m: problem.stage] + rng.normal(0.0, 1e-3, problem.nz)
