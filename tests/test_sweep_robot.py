"""A sweep runs every chunk on the robot it started with: its workers receive the robot's
description, never its file, so a robot file edited or deleted mid-sweep changes no row."""

from __future__ import annotations

import csv
import pickle
from importlib import resources
from pathlib import Path

import numpy as np
import pytest

import cdpr_sym.sweep.job as job_module
import cdpr_sym.sweep.runner as runner
from cdpr_sym.closed_loop import get_simulator
from cdpr_sym.control import controller_by_name
from cdpr_sym.errors import InvalidCase
from cdpr_sym.robot import preset, robot_key
from cdpr_sym.sweep import SweepConfig, SweepJob, run_sweep

#: Settings of every sweep here; the robot is planar2, by name or as a copy of its file.
SETTINGS = {"controllers": ("pd-sat", "pd"), "pairs": 3, "seed": 4, "duration": 0.3}


def _read(path: Path) -> dict[tuple[str, str], dict[str, str]]:
    with open(path, newline="") as handle:
        rows = list(csv.DictReader(handle))
    keyed = {(row["pair"], row["controller"]): row for row in rows}
    assert len(keyed) == len(rows), "a (pair, controller) row appears twice"
    return keyed


@pytest.fixture(scope="module")
def preset_rows(tmp_path_factory) -> dict[tuple[str, str], dict[str, str]]:
    """The rows of the sweep on the planar2 preset, one process, nothing changed."""
    out = tmp_path_factory.mktemp("preset") / "rows.csv"
    run_sweep(SweepConfig(robot="planar2", **SETTINGS), out, workers=1, progress=False)
    return _read(out)


def _robot_file(folder: Path) -> Path:
    """A copy of the planar2 preset's TOML file (the same robot, by path)."""
    path = folder / "robot.toml"
    path.write_text(resources.files("cdpr_sym.robot.presets").joinpath("planar2.toml")
                    .read_text())
    return path


def _edit(path: Path) -> None:
    """Make the file describe a heavier robot (every metric of every run changes)."""
    text = path.read_text()
    assert "mass = 1.0\n" in text
    path.write_text(text.replace("mass = 1.0\n", "mass = 1.7\n"))


def _remove(path: Path) -> None:
    path.unlink()


class _ChangeAfterFirstChunk:
    """A progress bar that changes the robot file when the first chunk's rows are stored,
    and counts the runs stored after that."""

    disable = True

    def __init__(self, change, path: Path) -> None:
        self.change, self.path, self.after = change, path, None

    def __enter__(self) -> _ChangeAfterFirstChunk:
        return self

    def __exit__(self, *exception: object) -> None:
        return None

    def update(self, runs: int) -> None:
        if self.after is None:
            self.change(self.path)
            self.after = 0
        else:
            self.after += runs


@pytest.mark.parametrize("workers", [1, 2])
@pytest.mark.parametrize("change", [_edit, _remove], ids=["edited", "removed"])
def test_a_robot_file_changed_between_chunks_changes_no_row(change, workers, preset_rows,
                                                             tmp_path, monkeypatch):
    path = _robot_file(tmp_path)
    bar = _ChangeAfterFirstChunk(change, path)
    monkeypatch.setattr(runner, "progress_bar", lambda total, enabled: bar)
    out = tmp_path / "rows.csv"
    run_sweep(SweepConfig(robot=str(path), **SETTINGS), out, workers=workers, chunk_size=1)
    assert bar.after >= 4  # most runs were stored after the file changed
    assert _read(out) == preset_rows


def test_a_resume_on_an_edited_robot_file_is_refused(tmp_path):
    """The sidecar keeps the robot the rows were run on: the same command on the edited
    file is another robot."""
    path = _robot_file(tmp_path)
    out = tmp_path / "rows.csv"
    config = SweepConfig(robot=str(path), **{**SETTINGS, "pairs": 1})
    run_sweep(config, out, workers=1, progress=False)
    _edit(path)
    with pytest.raises(InvalidCase) as refused:
        run_sweep(config, out, workers=1, progress=False)
    assert "written by another robot description" in str(refused.value)


def test_a_dask_sweep_runs_on_the_robot_it_started_with(preset_rows, tmp_path, monkeypatch):
    """The robot file removed once the scheduler answers, before any task has run: every
    task still runs on the robot read when the sweep started."""
    distributed = pytest.importorskip("dask.distributed")
    path = _robot_file(tmp_path)
    connect = runner.dask_client
    sent = []

    def connect_then_remove(address, timeout):
        client = connect(address, timeout)
        _remove(path)
        mapped = client.map
        client.map = lambda work, jobs, chunks, **options: (
            sent.extend(jobs), mapped(work, jobs, chunks, **options))[1]
        return client

    monkeypatch.setattr(runner, "dask_client", connect_then_remove)
    out = tmp_path / "rows.csv"
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=":0") as cluster:  # any free port
        run_sweep(SweepConfig(robot=str(path), **SETTINGS), out,
                  dask_address=cluster.scheduler_address, chunk_size=1, progress=False)
    assert not path.exists()
    assert _read(out) == preset_rows
    # the job went to the cluster once: each of the six tasks names the same scattered copy
    assert len(sent) == 6 and not any(isinstance(job, SweepJob) for job in sent)
    assert len({future.key for future in sent}) == 1


@pytest.mark.parametrize("name", ["planar2", "planar3", "spatial6"])
def test_a_job_arrives_as_an_equal_validated_robot(name):
    robot = preset(name)
    job = SweepJob(SweepConfig(robot=name, controllers=("pd",), pairs=1), robot)
    arrived = pickle.loads(pickle.dumps(job))
    assert arrived.robot is not robot and robot_key(arrived.robot) == robot_key(robot)
    assert arrived.digest == job.digest and arrived.config == job.config
    assert not arrived.robot.anchors.flags.writeable  # rebuilt by Robot, hence validated


def test_a_process_rebuilds_each_robot_once_and_reuses_its_simulator(monkeypatch):
    """Every copy of a job a process receives (a Dask task's argument each time, were it
    not scattered) gives the one robot, hence the one simulator."""
    built = []
    monkeypatch.setattr(job_module, "Robot", lambda **data: built.append(data) or
                        preset("planar2").with_case(**data))
    job_module._rebuilt.cache_clear()
    job = SweepJob(SweepConfig(robot="planar2", controllers=("pd",), pairs=1),
                   preset("planar2"))
    copies = [pickle.loads(pickle.dumps(job)) for _ in range(3)]
    assert copies[0].robot is copies[1].robot is copies[2].robot and len(built) == 1
    controller = controller_by_name("pd")
    assert get_simulator(copies[0].robot, controller) is get_simulator(copies[2].robot,
                                                                       controller)


def test_a_damaged_description_is_refused_naming_its_digest():
    job = SweepJob(SweepConfig(robot="planar2", controllers=("pd",), pairs=1),
                   preset("planar2"))
    state = job.__getstate__()
    damaged = pickle.loads(pickle.dumps(job))
    damaged.__setstate__((state[0], state[1].replace("1.0", "1.5", 1), *state[2:]))
    with pytest.raises(InvalidCase) as refused:
        _ = damaged.robot
    assert refused.value.field == "robot"
    assert f"does not match its digest {job.digest[:12]}" in str(refused.value)
    assert np.array_equal(job.robot.anchors, preset("planar2").anchors)
