"""Libraries found by recipe: what the generated C is made of, named without generating it.

A recipe names the values a library's C is generated from besides the package's code; a
second build of the same recipe must load the verified library without generating anything,
and any change (the recipe, the package's code, the library on disk) must generate again.
Each test builds into its own cache folder (real compiles of small functions).
"""

from __future__ import annotations

import dataclasses
import importlib
import shutil

import casadi as ca
import numpy as np
import pytest

from cdpr_sym import BuildOptions
from cdpr_sym.closed_loop import Plant, Simulator
from cdpr_sym.closed_loop.batch import batch_rollout
from cdpr_sym.codegen import build_recipe, built_recipe
from cdpr_sym.control import CONTROLLERS, PD
from cdpr_sym.robot import robot_key
from cdpr_sym.workspace import WorkspaceEvaluator, classification_function
from cdpr_sym.workspace.vectorised import LaneEvaluator, pose_evaluator

build_module = importlib.import_module("cdpr_sym.codegen.build")
pytestmark = pytest.mark.skipif(shutil.which("cc") is None, reason="needs a C compiler (cc)")


class _Generator:
    """Makes ``f(x) = scale * x`` and counts how often it was asked to."""

    def __init__(self, scale: float = 2.0) -> None:
        self.scale, self.calls = scale, 0

    def __call__(self) -> tuple[list[ca.Function], str]:
        self.calls += 1
        x = ca.SX.sym("x")
        return [ca.Function("f", [x], [self.scale * x])], ""


def test_a_second_build_of_a_recipe_generates_nothing(tmp_path):
    options = BuildOptions(cache_dir=tmp_path)
    generate = _Generator()
    first = build_recipe("scale=2", "tiny", generate, options=options)
    again = build_recipe("scale=2", "tiny", generate, options=options)
    assert generate.calls == 1
    assert again.path == first.path and again.key == first.key
    assert first.compiled_now and not again.compiled_now
    assert float(again.function("f")(3.0)) == 6.0


def test_another_recipe_or_other_package_code_generates_again(tmp_path, monkeypatch):
    options = BuildOptions(cache_dir=tmp_path)
    build_recipe("scale=2", "tiny", _Generator(2.0), options=options)
    other = _Generator(3.0)
    assert float(build_recipe("scale=3", "tiny", other, options=options).function("f")(1.0)
                 ) == 3.0
    assert other.calls == 1
    monkeypatch.setattr(build_module, "source_digest", lambda full=False: "edited" * 8)
    assert built_recipe("scale=2", "tiny", options=options) is None
    edited = _Generator(2.0)
    build_recipe("scale=2", "tiny", edited, options=options)
    assert edited.calls == 1


def test_a_damaged_library_or_record_is_generated_and_built_again(tmp_path):
    options = BuildOptions(cache_dir=tmp_path)
    first = build_recipe("scale=2", "tiny", _Generator(), options=options)
    first.path.write_bytes(first.path.read_bytes()[:100])  # truncated
    assert built_recipe("scale=2", "tiny", options=options) is None
    generate = _Generator()
    rebuilt = build_recipe("scale=2", "tiny", generate, options=options)
    assert generate.calls == 1 and rebuilt.compiled_now
    for entry in (tmp_path / "recipes").iterdir():
        entry.write_text("not a key")
    assert built_recipe("scale=2", "tiny", options=options) is None


def test_a_simulator_found_by_recipe_runs_as_the_one_that_generated_it(aras3, tmp_path):
    options = BuildOptions(cache_dir=tmp_path)
    first = Simulator(aras3, CONTROLLERS["smooth"], build_options=options)
    assert "step" in first.__dict__  # generated: nothing was built before
    second = Simulator(aras3, CONTROLLERS["smooth"], build_options=options)
    assert "step" not in second.__dict__ and "law" not in second.__dict__
    assert second.library.path == first.library.path
    runs = [simulator.run(aras3.start, aras3.goal, aras3.k, aras3.r_d, duration=0.2,
                          dt=1e-3, plant=Plant()) for simulator in (first, second)]
    assert np.array_equal(runs[0].q, runs[1].q) and np.array_equal(runs[0].tau, runs[1].tau)
    batches = [batch_rollout(simulator, options) for simulator in (first, second)]
    assert "step" not in second.__dict__  # its batched library was found by recipe too
    starts = np.array([aras3.start, aras3.goal])
    summaries = [batch.summaries(simulator.initial_states(starts, starts[::-1], aras3.k,
                                                          aras3.r_d),
                                 np.tile(simulator.parameters(aras3.goal, aras3.k, aras3.r_d,
                                                              1e-3, Plant()), (2, 1)),
                                 100, 0.01)
                 for batch, simulator in zip(batches, (first, second), strict=True)]
    assert np.array_equal(*summaries)


@dataclasses.dataclass(frozen=True)
class _OwnPD(PD):
    """A controller defined outside the package: the build cache cannot fingerprint its
    code, so its library is always generated (and found by the source's hash)."""

    name: str = "own-pd"


def test_a_controller_from_outside_the_package_is_always_generated(aras3, tmp_path):
    options = BuildOptions(cache_dir=tmp_path)
    simulators = [Simulator(aras3, _OwnPD(), build_options=options) for _ in range(2)]
    assert simulators[0].recipe is None
    assert all("step" in simulator.__dict__ for simulator in simulators)
    assert not (tmp_path / "recipes").exists()


def test_a_pose_evaluator_found_by_recipe_reports_its_sizes_and_agrees(aras3, tmp_path,
                                                                        rng):
    options = BuildOptions(cache_dir=tmp_path)
    first = WorkspaceEvaluator(aras3, build_options=options)
    calls = []

    def made() -> ca.Function:
        calls.append(1)
        return classification_function(first.model)

    found = pose_evaluator(aras3, made, "workspace", build_options=options,
                           recipe=robot_key(aras3))
    assert isinstance(found, LaneEvaluator) and calls == []
    assert found.sizes == (aras3.m, 1, 1)
    points = aras3.start + rng.uniform(-0.2, 0.2, (50, aras3.n))
    again = WorkspaceEvaluator(aras3, build_options=options).classify(points)
    original = first.classify(points)
    assert np.array_equal(again.tau_1, original.tau_1)
    assert np.array_equal(again.feasible, original.feasible)


def test_a_robot_of_the_same_name_with_other_data_is_generated_again(aras3, tmp_path):
    options = BuildOptions(cache_dir=tmp_path)
    light = Simulator(aras3, CONTROLLERS["pd"], build_options=options)
    heavier = dataclasses.replace(aras3, mass=aras3.mass * 1.5)
    assert heavier.name == aras3.name
    heavy = Simulator(heavier, CONTROLLERS["pd"], build_options=options)
    assert "step" in heavy.__dict__  # not found by the lighter robot's recipe
    assert heavy.library.path != light.library.path
    tensions = [simulator.static_tensions(aras3.start[None]) for simulator in (light, heavy)]
    assert np.allclose(tensions[1], 1.5 * tensions[0], rtol=1e-12)


@pytest.mark.slow  # ~4 s: builds three libraries of its own
def test_a_rate_limit_or_another_lane_count_is_another_recipe(aras3, tmp_path):
    options = BuildOptions(cache_dir=tmp_path)
    plain = Simulator(aras3, CONTROLLERS["pd"], build_options=options)
    limited = Simulator(aras3, CONTROLLERS["pd"], build_options=options, rate_limited=True)
    assert limited.recipe != plain.recipe and "step" in limited.__dict__
    assert limited.library.path != plain.library.path
    four = batch_rollout(plain, options, lanes=4)
    again = Simulator(aras3, CONTROLLERS["pd"], build_options=options)
    two = batch_rollout(again, options, lanes=2)  # not the 4-lane library
    assert "step" in again.__dict__
    assert two.library.path != four.library.path


@pytest.mark.parametrize("name", sorted(CONTROLLERS))
def test_every_controllers_recipe_is_the_same_in_every_process(name):
    """A recipe holds the controller's repr: no field may print as an address (which
    would differ between processes and make every build miss)."""
    assert "0x" not in repr(CONTROLLERS[name])
