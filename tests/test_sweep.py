"""Start/goal sweeps: rows equal runs of their pair, resume, Dask, refusals, sidecar, report."""

from __future__ import annotations

import csv
import json
import shutil
import subprocess
import sys
import time
from pathlib import Path

import casadi
import matplotlib.pyplot as plt
import numpy as np
import pytest

from cdpr_sym import InvalidCase, SymbolicModel, UnknownName, __version__, preset, simulate
from cdpr_sym.closed_loop import get_simulator, run_many
from cdpr_sym.control import controller_by_name
from cdpr_sym.reporting.sweep_report import maps_figure, write_sweep_report
from cdpr_sym.results import SCALAR_METRICS, sweep_columns
from cdpr_sym.results.store import load_table, sidecar_path
from cdpr_sym.sweep import SweepConfig, run_sweep

CONFIG = SweepConfig(robot="aras3", controllers=("l2", "box"), pairs=3, seed=11,
                     duration=2.0)
#: Metrics compared with a direct ``simulate`` run (``duration`` is the simulated span).
NUMBERS = ("min_tension", "max_tension", "settle_time", "final_error", "min_alpha",
           "share_alpha_below_one", "share_fallback", "fallback_steps", "infeasible_steps",
           "tension_total_variation", "max_tension_step", "start_jump", "duration")
FLAGS = ("tension_feasible", "converged")
PNG = b"\x89PNG\r\n\x1a\n"


def _read(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as handle:
        return list(csv.DictReader(handle))


def _keyed(rows: list[dict[str, str]]) -> dict[tuple[int, str], dict[str, str]]:
    keyed = {(int(row["pair"]), row["controller"]): row for row in rows}
    assert len(keyed) == len(rows), "a (pair, controller) row appears twice"
    return keyed


def _number(text: str) -> float | None:
    return None if text == "" else float(text)


@pytest.fixture(scope="module")
def local_sweep(tmp_path_factory) -> Path:
    """The uninterrupted reference sweep, one local process."""
    out = tmp_path_factory.mktemp("sweep") / "results.csv"
    run_sweep(CONFIG, out, workers=1, progress=False)
    return out


def test_sweep_writes_one_row_per_pair_and_controller(local_sweep):
    text = local_sweep.read_text()
    assert text.splitlines()[0] == ",".join(sweep_columns(3))
    rows = _read(local_sweep)
    assert sorted(_keyed(rows)) == [(pair, name) for pair in range(CONFIG.pairs)
                                    for name in sorted(CONFIG.controllers)]
    for row in rows:
        assert row["status"] == ("stopped" if row["stop_reason"] else "ok"), row
        assert row["error"] == ""


def test_sweep_rows_equal_runs_of_their_pair_alone(local_sweep, build_options):
    robot = preset(CONFIG.robot)
    static_tension = SymbolicModel(robot).functions["static_tension"]
    for row in _read(local_sweep):
        start = np.array([float(row[f"start_{i}"]) for i in range(robot.n)])
        goal = np.array([float(row[f"goal_{i}"]) for i in range(robot.n)])
        # the sweep advances runs in vectorised blocks; a block of one pair repeats a row
        # exactly (lanes are independent, and a single run gives the same bits:
        # tests/test_batch.py compares the two)
        simulator = get_simulator(robot, controller_by_name(row["controller"]),
                                  build_options=build_options)
        [run] = run_many(simulator, [start], [goal], robot.k, robot.r_d,
                         duration=CONFIG.duration, dt=CONFIG.dt, build_options=build_options)
        metrics = run.metrics(static_tension=np.array(static_tension(start)).ravel())
        for key in NUMBERS:
            expected = metrics[key]
            if expected is None:
                assert row[key] == "", (key, row)
            else:
                assert _number(row[key]) == pytest.approx(expected, rel=1e-12, abs=1e-12), (
                    key, row)
        for key in FLAGS:
            assert row[key] == str(metrics[key]), (key, row)
        assert row["stop_reason"] == (metrics["stop_reason"] or "")


def test_sweep_pairs_come_from_the_static_workspace(local_sweep):
    robot = preset(CONFIG.robot)
    static_tension = SymbolicModel(robot).functions["static_tension"]
    for row in _read(local_sweep):
        for prefix in ("start", "goal"):
            q = np.array([float(row[f"{prefix}_{i}"]) for i in range(robot.n)])
            tau_1 = np.array(static_tension(q)).ravel()
            assert np.all(tau_1 >= robot.t_min) and np.all(tau_1 <= robot.t_max)
            assert np.all(q > robot.frame_lower) and np.all(q < robot.frame_upper)


def test_resume_after_an_interruption_writes_each_row_exactly_once(local_sweep, tmp_path):
    lines = local_sweep.read_text().splitlines(keepends=True)
    out = tmp_path / "results.csv"
    shutil.copy(sidecar_path(local_sweep), sidecar_path(out))
    torn = lines[4][: len(lines[4]) // 2]  # half of the fourth row, no newline
    out.write_text("".join(lines[:4]) + torn)
    run_sweep(CONFIG, out, workers=1, progress=False)
    resumed = out.read_text()
    assert resumed.count(lines[0]) == 1  # one header
    assert torn not in resumed.replace(lines[4], "")
    assert _keyed(_read(out)) == _keyed(_read(local_sweep))
    assert resumed.splitlines(keepends=True)[:4] == lines[:4]  # written rows are kept


def test_resuming_a_finished_sweep_runs_nothing(local_sweep, tmp_path):
    out = tmp_path / "results.csv"
    shutil.copy(local_sweep, out)
    shutil.copy(sidecar_path(local_sweep), sidecar_path(out))
    run_sweep(CONFIG, out, workers=1, progress=False)
    assert out.read_text() == local_sweep.read_text()


def test_resume_after_a_torn_header_writes_the_header_once(tmp_path):
    config = SweepConfig(robot="planar2", controllers=("pd-sat",), pairs=2, seed=1,
                         duration=0.5)
    whole, torn = tmp_path / "whole.csv", tmp_path / "torn.csv"
    run_sweep(config, whole, workers=1, progress=False)
    shutil.copy(sidecar_path(whole), sidecar_path(torn))
    torn.write_text(whole.read_text()[:7])
    run_sweep(config, torn, workers=1, progress=False)
    assert torn.read_text() == whole.read_text()


def test_dask_local_cluster_gives_the_same_table(local_sweep, tmp_path):
    distributed = pytest.importorskip("dask.distributed")
    out = tmp_path / "results.csv"
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=":0") as cluster:  # any free port
        run_sweep(CONFIG, out, dask_address=cluster.scheduler_address, progress=False)
    assert _keyed(_read(out)) == _keyed(_read(local_sweep))


@pytest.mark.parametrize("pairs", [0, -2, True, 2.5])
def test_sweep_refuses_a_non_positive_or_non_integer_pair_count(pairs):
    with pytest.raises(InvalidCase) as raised:
        SweepConfig(robot="aras3", controllers=("l2",), pairs=pairs)
    assert raised.value.field == "pairs"


def test_sweep_refuses_an_unknown_controller():
    with pytest.raises(UnknownName, match="lqr"):
        SweepConfig(robot="aras3", controllers=("l2", "lqr"), pairs=2)


def test_sweep_refuses_another_configuration_on_an_existing_results_file(local_sweep, tmp_path):
    out = tmp_path / "results.csv"
    shutil.copy(local_sweep, out)
    shutil.copy(sidecar_path(local_sweep), sidecar_path(out))
    before, sidecar_before = out.read_text(), sidecar_path(out).read_text()
    other = SweepConfig(**{**CONFIG.as_dict(), "controllers": CONFIG.controllers, "seed": 12})
    with pytest.raises(InvalidCase) as raised:
        run_sweep(other, out, workers=1, progress=False)
    assert raised.value.field == "out"
    assert out.read_text() == before and sidecar_path(out).read_text() == sidecar_before


def test_sweep_refuses_a_results_file_without_sidecar(local_sweep, tmp_path):
    out = tmp_path / "results.csv"
    shutil.copy(local_sweep, out)
    before = out.read_text()
    with pytest.raises(InvalidCase) as raised:
        run_sweep(CONFIG, out, workers=1, progress=False)
    assert raised.value.field == "out"
    assert out.read_text() == before and not sidecar_path(out).exists()


def test_sidecar_records_config_versions_and_seed(local_sweep):
    sidecar = json.loads(sidecar_path(local_sweep).read_text())
    assert sidecar["config"] == CONFIG.as_dict()
    assert sidecar["config"]["seed"] == 11
    assert SweepConfig(**{**sidecar["config"],
                          "controllers": tuple(sidecar["config"]["controllers"])}) == CONFIG
    assert sidecar["versions"]["cdpr_sym"] == __version__
    assert sidecar["versions"]["numpy"] == np.__version__
    assert sidecar["versions"]["casadi"] == casadi.__version__
    assert "cvxpy" not in sidecar["versions"]  # no run calls it
    assert sidecar["versions"]["python"]


def test_sweep_report_writes_summary_and_maps(local_sweep, tmp_path):
    summary_md = write_sweep_report(local_sweep, tmp_path / "report")
    assert summary_md == tmp_path / "report" / "report.md"
    text = summary_md.read_text()
    for name in CONFIG.controllers:
        assert f"| {name} | {CONFIG.pairs} |" in text
    assert "seed 11" in text
    for figure in ("maps_xy.png", "maps_xz.png"):
        path = tmp_path / "report" / figure
        assert path.stat().st_size > 1000 and path.read_bytes()[:8] == PNG
        assert f"({figure})" in text
    summary = json.loads((tmp_path / "report" / "summary.json").read_text())
    assert {name: row["runs"] for name, row in summary.items()} == dict.fromkeys(
        CONFIG.controllers, CONFIG.pairs)


def test_metric_columns_are_the_simulate_metrics(planar2, build_options):
    metrics = simulate(planar2, controller_by_name("pd-sat"), duration=0.1,
                       build_options=build_options).metrics(static_tension=np.zeros(2))
    assert set(SCALAR_METRICS) <= set(metrics)


def test_resume_keeps_the_sidecar_and_refuses_a_changed_identity(tmp_path):
    import json

    from cdpr_sym.results.store import sidecar_path
    from cdpr_sym.sweep import SweepConfig, run_sweep

    config = SweepConfig(robot="planar2", controllers=("pd-sat",), pairs=1, seed=0,
                         duration=0.2)
    out = run_sweep(config, tmp_path / "rows.csv", workers=1, progress=False)
    first = sidecar_path(out).read_text()
    run_sweep(config, out, workers=1, progress=False)
    assert sidecar_path(out).read_text() == first
    stored = json.loads(first)
    stored["identity"]["controller_options"]["pd-sat"] = {"changed": True}
    sidecar_path(out).write_text(json.dumps(stored))
    with pytest.raises(InvalidCase, match="controller options"):
        run_sweep(config, out, workers=1, progress=False)


def test_rows_of_other_code_are_never_resumed_into(tmp_path, monkeypatch):
    """Same configuration and version number, other sources: a resume refuses in one line
    and a study's own sweep starts over, rather than mixing rows of two versions."""
    import cdpr_sym.version
    from cdpr_sym.studies.outline import study_sweep

    config = SweepConfig(robot="planar2", controllers=("pd-sat",), pairs=1, seed=0,
                         duration=0.2)
    out = run_sweep(config, tmp_path / "rows.csv", workers=1, progress=False)
    recorded = json.loads(sidecar_path(out).read_text())["identity"]["versions"]
    assert recorded["cdpr_sym_source"] == cdpr_sym.version.source_digest()
    monkeypatch.setattr(cdpr_sym.version, "source_digest", lambda: "edited-code")
    with pytest.raises(InvalidCase, match="versions"):
        run_sweep(config, out, workers=1, progress=False)
    study_sweep(config, out, progress=False)
    versions = json.loads(sidecar_path(out).read_text())["identity"]["versions"]
    assert versions["cdpr_sym_source"] == "edited-code"
    assert len(_read(out)) == 1


def test_sweep_maps_are_labelled_with_the_robots_coordinates(local_sweep):
    rows, _ = load_table(local_sweep)
    fig = maps_figure(rows, axes=(0, 1), names=("x", "z"))
    try:
        assert fig.axes[len(fig.axes) // 2].get_xlabel() == "x [m]"  # bottom row
        assert fig.axes[0].get_ylabel() == "z [m]"
    finally:
        plt.close(fig)


@pytest.mark.slow  # over ~10 s on 2 cores: left to CI
def test_an_nmpc_sweep_of_a_redundant_robot_on_dask_equals_the_local_one(tmp_path):
    """The sampled design (its solver in Python between compiled segments) and a robot
    with more cables than DOF, through a real scheduler: the same rows as one process."""
    distributed = pytest.importorskip("dask.distributed")
    config = SweepConfig(robot="planar4", controllers=("nmpc", "pd-td"), pairs=3, seed=5,
                         duration=2.0)
    local, remote = tmp_path / "local.csv", tmp_path / "dask.csv"
    run_sweep(config, local, workers=1, progress=False)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=":0") as cluster:  # any free port
        run_sweep(config, remote, dask_address=cluster.scheduler_address, progress=False)
    rows = _keyed(_read(local))
    assert len(rows) == 6 and {row["status"] for row in rows.values()} == {"ok"}
    assert _keyed(_read(remote)) == rows


def test_rows_read_back_in_the_order_the_sweep_defines_whatever_finished_first(tmp_path):
    """Workers return chunks as they finish, so a file's rows may start mid-way; a reader
    gets them by pair, then in the configured order of the designs (reports list designs
    in the order they first appear)."""
    out = tmp_path / "rows.csv"
    names = sweep_columns(2)
    written = [(3, "pd"), (3, "l2"), (0, "l2"), (1, "pd"), (0, "pd"), (1, "l2")]
    with open(out, "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=names, extrasaction="ignore")
        writer.writeheader()
        writer.writerows({"pair": pair, "controller": name, "status": "ok"}
                         for pair, name in written)
    sidecar_path(out).write_text(json.dumps({"config": {"controllers": ["pd", "l2"]}}))
    rows, _ = load_table(out)
    assert [(row["pair"], row["controller"]) for row in rows] == [
        (0, "pd"), (0, "l2"), (1, "pd"), (1, "l2"), (3, "pd"), (3, "l2")]


@pytest.mark.slow  # a real scheduler and worker started and killed: about 30 s
def test_a_lost_dask_scheduler_ends_the_sweep_in_one_line_and_keeps_its_rows(tmp_path):
    """The scheduler process is killed mid-sweep: one ``cdpr-sym:`` line saying how to
    resume, exit status 1, the finished rows kept; the resume (here on local processes)
    completes the table without a repeated row."""
    pytest.importorskip("dask.distributed")
    bin_dir = Path(sys.executable).parent
    address_file = tmp_path / "scheduler.json"
    scheduler = subprocess.Popen([str(bin_dir / "dask"), "scheduler", "--port", "0",
                                  "--no-dashboard", "--scheduler-file", str(address_file)],
                                 stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    worker = None
    try:
        for _ in range(300):
            if address_file.exists() and address_file.stat().st_size:
                break
            time.sleep(0.1)
        address = json.loads(address_file.read_text())["address"]
        worker = subprocess.Popen([str(bin_dir / "dask"), "worker", address, "--nworkers", "1",
                                   "--nthreads", "1", "--no-dashboard"],
                                  stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        out = tmp_path / "rows.csv"
        command = [str(bin_dir / "cdpr-sym"), "sweep", "--robot", "aras3", "--controllers",
                   "pd-sat", "--pairs", "3000", "--duration", "1", "--out", str(out)]
        sweep = subprocess.Popen([*command, "--dask", address], stdout=subprocess.PIPE,
                                 stderr=subprocess.PIPE, text=True)
        for _ in range(1200):  # until some rows are stored
            if out.exists() and len(out.read_text().splitlines()) > 100:
                break
            time.sleep(0.1)
        scheduler.kill()
        _, err = sweep.communicate(timeout=180)
    finally:
        for process in (scheduler, worker):
            if process is not None:
                process.kill()
                process.wait()
    lines = err.strip().splitlines()
    assert sweep.returncode == 1, err
    assert len(lines) == 1 and lines[0].startswith("cdpr-sym:"), err
    assert "Dask cluster stopped answering" in lines[0] and "again to resume" in lines[0]
    kept = len(out.read_text().splitlines()) - 1
    assert 100 <= kept < 3000
    resumed = subprocess.run([*command, "--workers", "2"], capture_output=True, text=True,
                             timeout=600)
    assert resumed.returncode == 0, resumed.stderr
    rows = _keyed(_read(out))
    assert len(rows) == 3000
