"""Batched closed-loop rollouts: many runs of one simulator advanced by one compiled call.

The step is written for several runs at once (:mod:`cdpr_sym.codegen.lanes`), as many as
one of this machine's vector registers holds doubles (:func:`~cdpr_sym.codegen.native_lanes`:
4 with AVX2, 8 with AVX-512), and compiled with the host's vector instructions; a rollout
loop (``templates/rollout_lanes.c.j2``) feeds it blocks of runs and stores each run's states
and logs in their own rows, exactly as single runs do. Sweeps and studies go through
:func:`run_many`, which falls back to one run at a time where no batch can be built
(CasADi's virtual machine, an operation without a C form for lanes).
"""

from __future__ import annotations

import ctypes
import weakref
from collections.abc import Sequence

import numpy as np

from cdpr_sym.closed_loop.case import check_timing
from cdpr_sym.closed_loop.plant import Plant
from cdpr_sym.closed_loop.simulator import Simulator
from cdpr_sym.closed_loop.summaries import run_summaries, summary_fields, summary_source
from cdpr_sym.codegen import (
    BuildOptions,
    CompiledLibrary,
    build_recipe,
    check_lanes,
    lanes_preamble,
    lanes_source,
    render,
    resolve_lanes,
    unsupported_operations,
    vector_build_options,
)
from cdpr_sym.errors import InvalidCase
from cdpr_sym.results import SETTLE_TOLERANCE, RunSummary, Trajectory

#: Runs per call of the compiled loop: bounds the states and logs held at once.
RUNS_PER_CALL = 64


class BatchRollout:
    """The compiled batched rollout of a :class:`Simulator`'s step, ``lanes`` runs per call
    of the vectorised step (default: :func:`~cdpr_sym.codegen.native_lanes`)."""

    def __init__(self, simulator: Simulator, build_options: BuildOptions = BuildOptions(),
                 lanes: int | None = None) -> None:
        lanes = resolve_lanes(lanes, build_options)
        self.layout, self.lanes = simulator.layout, lanes
        self.library = _lanes_library(simulator, build_options, lanes)
        self._native = self.library.native()
        self._call = self._native.entry("rollout_lanes", None, [ctypes.c_void_p] * 4 + [
            ctypes.c_longlong] * 2 + [ctypes.c_void_p])
        self._summarise = self._native.entry("summarise_lanes", None, [ctypes.c_void_p] * 3 + [
            ctypes.c_longlong] * 2 + [ctypes.c_double])

    def __call__(self, x0: np.ndarray, p: np.ndarray, n_steps: int
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """States (runs, n_steps + 1, x size), logs (runs, n_steps, log size) and steps
        taken per run, from initial states ``x0`` (runs, x size) and parameters ``p``
        (runs, p size). Rows after a run's stop are zeros."""
        x0, p = np.ascontiguousarray(x0, float), np.ascontiguousarray(p, float)
        runs = len(x0)
        states = np.zeros((runs, n_steps + 1, self.layout.x.size))
        logs = np.zeros((runs, n_steps, self.layout.log.size))
        taken = np.zeros(runs, dtype=np.int64)
        if runs:
            self._call(x0.ctypes.data, p.ctypes.data, states.ctypes.data, logs.ctypes.data,
                       n_steps, runs, taken.ctypes.data)
        return states, logs, taken

    def summaries(self, x0: np.ndarray, p: np.ndarray, n_steps: int, band: float
                  ) -> np.ndarray:
        """Summary rows (runs, :func:`summary_fields` size) of the runs from ``x0`` with
        ``p``, as :meth:`__call__` would run them; ``band`` is the settling band, m."""
        x0, p = np.ascontiguousarray(x0, float), np.ascontiguousarray(p, float)
        rows = np.zeros((len(x0), summary_fields(self.layout).size))
        if len(x0):
            self._summarise(x0.ctypes.data, p.ctypes.data, rows.ctypes.data, n_steps,
                            len(x0), band * band)
        return rows


def _lanes_name(simulator: Simulator) -> str:
    """The base name of the batched library of ``simulator``."""
    return simulator.library_name + "_lanes"


def _lanes_recipe(simulator: Simulator, lanes: int) -> str | None:
    """The recipe of the batched library: the simulator's, on ``lanes`` lanes."""
    return None if simulator.recipe is None else f"{simulator.recipe}\0lanes={lanes}"


def _lanes_library(simulator: Simulator, build_options: BuildOptions, lanes: int
                   ) -> CompiledLibrary:
    """The vectorised step, its rollout loop and its summarising loop, compiled with the
    host's vector instructions (found by recipe when built before)."""
    layout = simulator.layout

    def generate() -> tuple[list, str]:
        if unsupported_operations(simulator.step):
            raise _NoLaneForm
        source = (lanes_preamble(lanes) + lanes_source(simulator.step, "step_lanes", lanes)
                  + render("cdpr_sym.closed_loop", "rollout_lanes.c.j2", step="step_lanes",
                           lanes=lanes, n_x=layout.x.size, n_p=layout.p.size,
                           n_log=layout.log.size, status=layout.status_index)
                  + summary_source(layout, "step_lanes", lanes))
        return [simulator.step], source

    return build_recipe(_lanes_recipe(simulator, lanes), _lanes_name(simulator), generate,
                        options=vector_build_options(build_options))


class _NoLaneForm(Exception):
    """The step holds an operation without a lane form: no batched library for it."""


#: Each simulator's batched rollouts by lane count (None: none can be built), kept while it
#: lives.
_BATCHES: weakref.WeakKeyDictionary[Simulator, dict[int, BatchRollout | None]] = (
    weakref.WeakKeyDictionary())


def batch_rollout(simulator: Simulator, build_options: BuildOptions = BuildOptions(),
                  lanes: int | None = None) -> BatchRollout | None:
    """The batched rollout of ``simulator`` on ``lanes`` runs per vector (default:
    :func:`~cdpr_sym.codegen.native_lanes`; built once per simulator and lane count), or
    None where its step runs in CasADi's virtual machine or cannot be written for lanes."""
    built = _BATCHES.setdefault(simulator, {})
    lanes = resolve_lanes(lanes, build_options)
    if lanes not in built:
        built[lanes] = _batch_or_none(simulator, build_options, lanes)
    return built[lanes]


def _batch_or_none(simulator: Simulator, build_options: BuildOptions, lanes: int
                   ) -> BatchRollout | None:
    """The batched rollout, or None where the step runs in CasADi's virtual machine or has
    an operation without a lane form (checked only when the library is generated: one
    found by recipe was checked when it was built)."""
    if simulator.backend != "c" or simulator.sampled is not None:
        return None
    try:
        return BatchRollout(simulator, build_options, lanes)
    except _NoLaneForm:
        return None


def run_many(simulator: Simulator, starts: Sequence, goals: Sequence, k: np.ndarray,
             r_d: np.ndarray, *, duration: float, dt: float,
             plant: Plant | Sequence[Plant] = Plant(),
             build_options: BuildOptions = BuildOptions(), lanes: int | None = None
             ) -> list[Trajectory]:
    """Simulate every (start, goal) pair with the same gains, plant and timing.

    ``[simulator.run(s, g, k, r_d, ...) for s, g in zip(starts, goals)]``, advanced
    ``lanes`` runs at a time in vectorised compiled code. Lanes are independent, so a
    run's result does not depend on the others in its block, and every operation is
    rounded as written (:data:`~cdpr_sym.codegen.build.EXACT_FLAGS`), so it equals
    ``simulator.run`` of the same compiled simulator, and itself on any other lane count,
    bit for bit.

    Parameters
    ----------
    simulator : Simulator
    starts, goals : array_like, shape (runs, n)
        Start (at rest) and goal poses, m (rad for angles).
    k, r_d : array_like, shape (n,)
        Gain diagonals, N/m and N s/m.
    duration, dt : float
        Simulated time and control period, s.
    plant : Plant or sequence of Plant
        The plant of every run, or of each run: as-built plants (each run its own draw,
        the same structure) may differ from run to run, the ideal plant may not.
    build_options : BuildOptions
        Cache folder and compiler of the batched library.
    lanes : int, optional
        Runs per vector of the compiled step, a power of two up to
        :data:`~cdpr_sym.codegen.MAX_LANES` (:func:`~cdpr_sym.codegen.check_lanes`);
        default: the doubles one vector register of this machine holds
        (:func:`~cdpr_sym.codegen.native_lanes`). Checked even where the runs go one at a
        time (CasADi's virtual machine).

    Raises
    ------
    InvalidCase
        ``starts``/``goals`` of different lengths or shapes, bad timing, a plant that
        does not match the simulator, a bad ``lanes``.
    """
    check_lanes(lanes)
    starts, goals, plants, n_steps = _checked(simulator, starts, goals, duration, dt, plant)
    batch = batch_rollout(simulator, build_options, lanes)
    if batch is None:
        return [simulator.run(s, g, k, r_d, duration=duration, dt=dt, plant=one)
                for s, g, one in zip(starts, goals, plants, strict=True)]
    out: list[Trajectory] = []
    for first in range(0, len(starts), RUNS_PER_CALL):
        block = slice(first, first + RUNS_PER_CALL)
        states, logs, _ = batch(*_inputs(simulator, starts[block], goals[block], k, r_d, dt,
                                         plants[block]), n_steps)
        out.extend(simulator.trajectory(states[i], logs[i], n_steps, dt, goal, k, r_d, one)
                   for i, (goal, one) in enumerate(zip(goals[block], plants[block],
                                                       strict=True)))
    return out


def summarise_many(simulator: Simulator, starts: Sequence, goals: Sequence, k: np.ndarray,
                   r_d: np.ndarray, *, duration: float, dt: float,
                   plant: Plant | Sequence[Plant] = Plant(),
                   build_options: BuildOptions = BuildOptions(), lanes: int | None = None,
                   settle_band: float = SETTLE_TOLERANCE) -> list[RunSummary]:
    """``[run.summary(settle_band=settle_band) for run in run_many(...)]`` without storing
    the runs (``settle_band``, m: the band the settle times are measured in).

    The batched loop keeps each run's running extremes and counts as it advances, so a
    sweep of any length holds one summary row per run; the metrics equal those of
    :func:`run_many`'s trajectories bit for bit (the C loop adds errors and tension changes
    in the order :meth:`~cdpr_sym.results.Trajectory.summary` does). Same parameters and
    errors as :func:`run_many`.
    """
    check_lanes(lanes)
    starts, goals, plants, n_steps = _checked(simulator, starts, goals, duration, dt, plant)
    batch = batch_rollout(simulator, build_options, lanes)
    if batch is None:
        return [simulator.run(s, g, k, r_d, duration=duration, dt=dt, plant=one).summary(
            settle_band=settle_band) for s, g, one in zip(starts, goals, plants, strict=True)]
    if not len(starts):
        return []
    rows = batch.summaries(*_inputs(simulator, starts, goals, k, r_d, dt, plants), n_steps,
                           settle_band)
    robot = simulator.robot
    return run_summaries(rows, simulator.layout, goals, dt,
                         static_tensions=simulator.static_tensions(starts),
                         t_min=robot.t_min, t_max=robot.t_max)


def _inputs(simulator: Simulator, starts: np.ndarray, goals: np.ndarray, k: np.ndarray,
            r_d: np.ndarray, dt: float, plants: list[Plant]) -> tuple[np.ndarray, np.ndarray]:
    """The runs' initial states x0 (runs, x size) and parameters p (runs, p size), equal
    row by row to ``simulator.initial_state`` and ``simulator.parameters`` of each run
    with its plant of ``plants``: on the ideal (or rate-limited) plant, all the same,
    made at once; as built, each run's own (:meth:`Simulator.prepared`: its checks and the
    controller's plans made for all runs at once)."""
    if plants and plants[0].as_built is not None:
        simulator.check_as_built_runs(starts, goals, dt, plants)
        memories = simulator.initial_memories(starts, goals, k, r_d)
        prepared = [simulator.started(start, goal, k, r_d, dt, one,
                                      memory=None if memories is None else memories[run])
                    for run, (start, goal, one) in enumerate(zip(starts, goals, plants,
                                                                 strict=True))]
        size_x, size_p = simulator.layout.x.size, simulator.layout.p.size
        return (np.array([x0 for x0, _ in prepared]).reshape(-1, size_x),
                np.array([p for _, p in prepared]).reshape(-1, size_p))
    x0 = simulator.initial_states(starts, goals, k, r_d)
    p = np.tile(simulator.parameters(goals[0], k, r_d, dt, plants[0]), (len(goals), 1))
    p[:, simulator.layout.p.slice("q_goal")] = goals  # the only field that differs by run
    return x0, p


def _checked(simulator: Simulator, starts: Sequence, goals: Sequence, duration: float,
             dt: float, plant: Plant | Sequence[Plant]
             ) -> tuple[np.ndarray, np.ndarray, list[Plant], int]:
    """Starts and goals as (runs, n) arrays, the plant of each run and the number of steps,
    checked: one plant for every run, or one per run, all of the simulator's kind."""
    starts, goals = np.atleast_2d(starts).astype(float), np.atleast_2d(goals).astype(float)
    if starts.shape != goals.shape or starts.shape[1:] != (simulator.robot.n,):
        raise InvalidCase("starts", f"expected starts and goals of shape (runs, "
                          f"{simulator.robot.n}), got {starts.shape} and {goals.shape}")
    plants = [plant] * len(starts) if isinstance(plant, Plant) else list(plant)
    if len(plants) != len(starts) or not all(isinstance(one, Plant) for one in plants):
        raise InvalidCase("plant", f"expected a Plant or one Plant per run ({len(starts)}), "
                          f"got {len(plants)} items")
    for one in {id(one): one for one in plants}.values():  # each distinct object once
        simulator.check_plant(one)
    if plants and plants[0].as_built is None and any(one is not plants[0]
                                                     and one != plants[0] for one in plants):
        raise InvalidCase("plant", "the ideal plant is one for all runs; only as-built "
                          "plants (their draws) may differ from run to run")
    n_steps = check_timing(duration, dt, values_per_step=simulator.values_per_step)
    return starts, goals, plants, n_steps
