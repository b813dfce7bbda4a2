"""Shared fixtures: the preset robots, models, a private build cache, random states.

The whole session builds into a private cache: ``XDG_CACHE_HOME`` points into the session's
temporary folder (for the library, the command line and its subprocesses alike), and
``build_options`` names the same folder, so each library is compiled once per session and
never in the user's cache.
"""

from __future__ import annotations

import os
import signal
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from cdpr_sym import BuildOptions, Robot, SymbolicModel, preset

#: Seed of every random draw in the suite (reproducible failures).
SEED = 20240611


@pytest.fixture(scope="session")
def aras3() -> Robot:
    """The paper's Section IV robot (3 cables, 3 DOF)."""
    return preset("aras3")


@pytest.fixture(scope="session")
def planar2() -> Robot:
    """A planar point mass on two cables."""
    return preset("planar2")


@pytest.fixture(scope="session")
def planar3() -> Robot:
    """A planar rigid body on three cables (centre of mass off the body-frame origin)."""
    return preset("planar3")


@pytest.fixture(scope="session")
def spatial6() -> Robot:
    """A suspended 6-DOF platform on six cables."""
    return preset("spatial6")


@pytest.fixture(scope="session")
def aras3_model(aras3: Robot) -> SymbolicModel:
    return SymbolicModel(aras3)


@pytest.fixture(scope="session")
def planar2_model(planar2: Robot) -> SymbolicModel:
    return SymbolicModel(planar2)


#: Set (CI sets it), the sessions build into this folder instead of a fresh one, so the slow
#: run reuses the libraries the quick run compiled; unset, each session starts empty.
SHARED_CACHE_HOME = "CDPR_SYM_TEST_CACHE_HOME"


@pytest.fixture(scope="session", autouse=True)
def private_cache_home(tmp_path_factory: pytest.TempPathFactory):
    """``XDG_CACHE_HOME`` of the whole session: a temporary folder, restored afterwards
    (or :data:`SHARED_CACHE_HOME`'s folder, when that is set).

    Parallel workers (pytest-xdist) share one: builds lock their folder and publish by an
    atomic rename, so each library is still compiled once per run."""
    if os.environ.get(SHARED_CACHE_HOME):
        home = Path(os.environ[SHARED_CACHE_HOME])
        home.mkdir(parents=True, exist_ok=True)
    elif os.environ.get("PYTEST_XDIST_WORKER"):
        home = tmp_path_factory.getbasetemp().parent / "cache_home"
        home.mkdir(exist_ok=True)
    else:
        home = tmp_path_factory.mktemp("cache_home")
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("XDG_CACHE_HOME", str(home))
        yield home


@pytest.fixture(scope="session")
def cache_dir(private_cache_home: Path) -> Path:
    """The build cache private to this test session (the default cache under it)."""
    return private_cache_home / "cdpr_sym"


@pytest.fixture(scope="session")
def build_options(cache_dir: Path) -> BuildOptions:
    """Default build options, compiling into the session's private cache."""
    return BuildOptions(cache_dir=cache_dir)


@pytest.fixture
def rng() -> np.random.Generator:
    """A freshly seeded generator (each test sees the same stream)."""
    return np.random.default_rng(SEED)


def draw_states(robot: Robot, rng: np.random.Generator, count: int, *,
                margin: float = 0.1, speed: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """``count`` random states (q, dq) with q inside the frame, away from the anchors.

    q is uniform in the frame shrunk by ``margin`` (a fraction of the frame's span) on every
    side, which keeps it off the anchor plane (det W = 0 there). dq is Gaussian, scaled by
    ``speed`` (m/s) times a log-uniform factor in [1e-3, 3] so slow and fast states both occur.
    """
    lower, upper = robot.frame_lower, robot.frame_upper
    span = upper - lower
    q = lower + margin * span + rng.random((count, robot.n)) * (1 - 2 * margin) * span
    scale = speed * 10.0 ** rng.uniform(-3.0, np.log10(3.0), size=(count, 1))
    dq = rng.normal(size=(count, robot.n)) * scale
    return q, dq


@pytest.fixture
def random_states() -> Callable[..., tuple[np.ndarray, np.ndarray]]:
    """The state sampler :func:`draw_states` (call it with a robot, a generator, a count)."""
    return draw_states


#: Cases of quick checks that each compile a model of their own (about 4-6 s here) while
#: their sibling cases check the same behaviour: they run with the slow checks (CI runs
#: them), so that the quick suite stays near three minutes on two cores.
SLOW_CASES = frozenset({
    "tests/test_box_designs.py::test_fast_path_matches_cvxpy_clarabel_model[box-planar2]",
    "tests/test_box_designs.py::test_box_design_alpha_is_maximal[aras3]",
    "tests/test_rigid_designs.py::"
    "test_controllers_equal_law_3_written_in_momentum_by_the_oracle[spatial6-l2]",
    "tests/test_rigid_designs.py::"
    "test_controllers_equal_law_3_written_in_momentum_by_the_oracle[spatial6-pd]",
})


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Mark :data:`SLOW_CASES` slow before ``-m`` selects (a case that no longer exists
    is an error, so the list cannot rot)."""
    found = {item.nodeid for item in items}
    if config.rootpath / "tests" == Path(__file__).parent and len(items) > 1000:
        missing = SLOW_CASES - found
        if missing:
            raise pytest.UsageError(f"SLOW_CASES names cases that do not exist: {missing}")
    for item in items:
        if item.nodeid in SLOW_CASES:
            item.add_marker(pytest.mark.slow)


@pytest.fixture
def python_sigint():
    """SIGINT raising ``KeyboardInterrupt`` in this process, and at its default in the
    programs it starts, for the test's duration. A runner may start the suite with SIGINT
    ignored (a non-interactive shell's background job): Python then installs no handler,
    children inherit the ignoring, and a test's Ctrl-C would never arrive."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, previous)
