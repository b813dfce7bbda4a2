"""Parquet sweeps: same rows as CSV, typed and lazily readable, atomic parts, resume, report."""

from __future__ import annotations

import json
import math
import shutil
import sys
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cdpr_sym import InvalidCase
from cdpr_sym.reporting.sweep_report import write_sweep_report
from cdpr_sym.results import sweep_columns
from cdpr_sym.results.store import (
    append_parquet_part,
    load_table,
    parquet_parts,
    read_parquet_rows,
    sidecar_path,
)
from cdpr_sym.sweep import SweepConfig, run_sweep

pa = pytest.importorskip("pyarrow")
ds = pytest.importorskip("pyarrow.dataset")
pq = pytest.importorskip("pyarrow.parquet")

CONFIG = SweepConfig(robot="aras3", controllers=("pd-sat",), pairs=3, duration=0.5)


def _sweep(out: Path, **options: Any) -> Path:
    return run_sweep(CONFIG, out, workers=1, progress=False, **options)


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return type(a) is type(b) and a == b


def _assert_same_rows(rows: list[dict[str, Any]], expected: list[dict[str, Any]]) -> None:
    assert len(rows) == len(expected)
    for row, reference in zip(rows, expected, strict=True):
        assert list(row) == list(reference)
        for key in reference:
            assert _same(row[key], reference[key]), (key, row[key], reference[key])


def _keyed(rows: list[dict[str, Any]]) -> dict[tuple[int, str], dict[str, Any]]:
    keyed = {(int(row["pair"]), row["controller"]): row for row in rows}
    assert len(keyed) == len(rows), "a (pair, controller) row appears twice"
    return keyed


def _copy(dataset: Path, to: Path) -> Path:
    shutil.copytree(dataset, to)
    shutil.copy(sidecar_path(dataset), sidecar_path(to))
    return to


@pytest.fixture(scope="module")
def csv_sweep(tmp_path_factory) -> Path:
    return _sweep(tmp_path_factory.mktemp("csv") / "results.csv")


@pytest.fixture(scope="module")
def parquet_sweep(tmp_path_factory) -> Path:
    """The reference Parquet sweep: one part per run (chunks of one row)."""
    return _sweep(tmp_path_factory.mktemp("parquet") / "results", format="parquet",
                  chunk_size=1)


def test_parquet_sweep_gives_the_rows_of_a_csv_sweep(csv_sweep, parquet_sweep):
    assert parquet_sweep.is_dir()
    assert len(parquet_parts(parquet_sweep)) == CONFIG.pairs
    rows, meta = load_table(parquet_sweep)
    csv_rows, csv_meta = load_table(csv_sweep)
    assert list(rows[0]) == sweep_columns(3)
    _assert_same_rows(rows, csv_rows)
    assert meta["config"] == csv_meta["config"] == CONFIG.as_dict()
    assert meta["identity"] == csv_meta["identity"]


def test_parquet_layout_is_a_dataset_folder_with_the_sidecar_beside_it(parquet_sweep):
    assert sidecar_path(parquet_sweep) == parquet_sweep.parent / "results.json"
    assert sidecar_path(parquet_sweep).is_file()
    names = sorted(path.name for path in parquet_sweep.iterdir())
    assert all(name.startswith("part-") and name.endswith(".parquet") for name in names)


def test_parquet_dataset_is_read_lazily_with_typed_columns(parquet_sweep):
    dataset = ds.dataset(parquet_sweep, format="parquet")
    schema = dataset.schema
    assert schema.names == sweep_columns(3)
    assert schema.field("pair").type == pa.int64()
    assert schema.field("controller").type == pa.string()
    assert schema.field("status").type == pa.string()
    assert schema.field("stop_reason").type == pa.string()
    for name in ("start_0", "goal_2", "min_tension", "final_error", "settle_time", "duration"):
        assert schema.field(name).type == pa.float64(), name
    for name in ("tension_feasible", "converged"):
        assert schema.field(name).type == pa.bool_(), name
    assert schema.field("fallback_steps").type == pa.int64()
    assert dataset.count_rows() == CONFIG.pairs
    table = dataset.to_table(columns=["pair", "final_error"], filter=ds.field("pair") >= 1)
    assert sorted(table.column("pair").to_pylist()) == [1, 2]


def test_a_part_keeps_its_column_types_when_values_are_missing(tmp_path):
    types = {"pair": "int64", "x": "float64", "ok": "bool", "reason": "string"}
    part = append_parquet_part(tmp_path / "set", [{"pair": 4, "x": None, "extra": {}}], types)
    assert part.parent == tmp_path / "set" and part.name.startswith("part-")
    assert [path.name for path in (tmp_path / "set").iterdir()] == [part.name]  # no temporary
    table = pq.read_table(part)
    assert table.schema == pa.schema([("pair", pa.int64()), ("x", pa.float64()),
                                      ("ok", pa.bool_()), ("reason", pa.string())])
    assert table.to_pylist() == [{"pair": 4, "x": None, "ok": None, "reason": None}]
    assert load_table(tmp_path / "set")[0] == [{"pair": 4.0, "x": None, "ok": None,
                                                "reason": None}]


def test_pandas_reads_the_parquet_folder(parquet_sweep):
    pd = pytest.importorskip("pandas")
    frame = pd.read_parquet(parquet_sweep)
    assert len(frame) == CONFIG.pairs
    assert str(frame["pair"].dtype) == "int64"
    assert str(frame["final_error"].dtype) == "float64"
    assert str(frame["converged"].dtype) == "bool"


def test_resume_after_deleting_a_part_reruns_exactly_its_rows(parquet_sweep, tmp_path):
    out = _copy(parquet_sweep, tmp_path / "results")
    parts = parquet_parts(out)
    lost = parts[1]
    lost_rows = read_parquet_rows(parquet_sweep)[1:2]
    lost.unlink()
    kept = {path.name: path.read_bytes() for path in parquet_parts(out)}
    _sweep(out, format="parquet", chunk_size=1)
    new = [path for path in parquet_parts(out) if path.name not in kept]
    assert len(new) == 1 and new[0].name != lost.name
    _assert_same_rows(pq.read_table(new[0]).to_pylist(), lost_rows)  # typed values
    assert _keyed(read_parquet_rows(out)).keys() == _keyed(read_parquet_rows(parquet_sweep)).keys()
    for name, data in kept.items():  # written parts are left as they were
        assert (out / name).read_bytes() == data
    _assert_same_rows(sorted(load_table(out)[0], key=lambda row: row["pair"]),
                      load_table(parquet_sweep)[0])


def test_resuming_a_finished_parquet_sweep_runs_nothing(parquet_sweep, tmp_path):
    out = _copy(parquet_sweep, tmp_path / "results")
    before = {path.name: path.read_bytes() for path in out.iterdir()}
    _sweep(out, format="parquet")
    assert {path.name: path.read_bytes() for path in out.iterdir()} == before


def test_a_torn_temporary_part_is_ignored_and_its_rows_rerun(parquet_sweep, tmp_path):
    """A crash while writing a part leaves only its temporary dot-name file."""
    out = _copy(parquet_sweep, tmp_path / "results")
    lost = parquet_parts(out)[-1]
    data = lost.read_bytes()
    torn = out / f".{lost.name}.tmp"
    torn.write_bytes(data[: len(data) // 2])
    lost.unlink()
    assert len(load_table(out)[0]) == CONFIG.pairs - 1  # the torn file is not read
    assert ds.dataset(out, format="parquet").count_rows() == CONFIG.pairs - 1
    _sweep(out, format="parquet")
    assert len(parquet_parts(out)) == CONFIG.pairs
    _assert_same_rows(load_table(out)[0], load_table(parquet_sweep)[0])
    assert ds.dataset(out, format="parquet").count_rows() == CONFIG.pairs


def test_sweep_report_reads_the_parquet_folder(csv_sweep, parquet_sweep, tmp_path):
    summary_md = write_sweep_report(parquet_sweep, tmp_path / "report")
    text = summary_md.read_text()
    assert f"| pd-sat | {CONFIG.pairs} |" in text
    assert (tmp_path / "report" / "maps_xy.png").stat().st_size > 1000
    write_sweep_report(csv_sweep, tmp_path / "csv_report")
    assert (json.loads((tmp_path / "report" / "summary.json").read_text())
            == json.loads((tmp_path / "csv_report" / "summary.json").read_text()))


@pytest.mark.parametrize("format", ["feather", "CSV", ""])
def test_an_unknown_format_is_refused(format, tmp_path):
    out = tmp_path / "results"
    with pytest.raises(InvalidCase) as raised:
        _sweep(out, format=format)
    assert raised.value.field == "format"
    assert not out.exists() and not sidecar_path(out).exists()


def test_parquet_without_pyarrow_names_the_extra(monkeypatch, tmp_path):
    monkeypatch.setitem(sys.modules, "pyarrow", None)
    out = tmp_path / "results"
    with pytest.raises(InvalidCase, match=r"cdpr_sym\[parquet\]") as raised:
        _sweep(out, format="parquet")
    assert raised.value.field == "format"
    assert not out.exists() and not sidecar_path(out).exists()


def test_parquet_refuses_a_csv_file_and_csv_refuses_a_parquet_folder(csv_sweep, parquet_sweep,
                                                                     tmp_path):
    csv_out = tmp_path / "results.csv"
    shutil.copy(csv_sweep, csv_out)
    shutil.copy(sidecar_path(csv_sweep), sidecar_path(csv_out))
    with pytest.raises(InvalidCase) as raised:
        _sweep(csv_out, format="parquet")
    assert raised.value.field == "out"
    assert csv_out.read_bytes() == csv_sweep.read_bytes()
    folder = _copy(parquet_sweep, tmp_path / "results")
    with pytest.raises(InvalidCase) as raised:
        _sweep(folder)
    assert raised.value.field == "out"
    assert len(parquet_parts(folder)) == CONFIG.pairs


def test_parquet_refuses_a_folder_without_sidecar_but_accepts_an_empty_one(parquet_sweep,
                                                                           tmp_path):
    foreign = tmp_path / "foreign"
    shutil.copytree(parquet_sweep, foreign)
    with pytest.raises(InvalidCase) as raised:
        _sweep(foreign, format="parquet")
    assert raised.value.field == "out" and not sidecar_path(foreign).exists()
    empty = tmp_path / "empty"
    empty.mkdir()
    _sweep(empty, format="parquet")
    _assert_same_rows(load_table(empty)[0], load_table(parquet_sweep)[0])


def test_restart_if_stale_replaces_a_parquet_sweep_of_another_configuration(parquet_sweep,
                                                                            tmp_path):
    out = _copy(parquet_sweep, tmp_path / "results")
    other = SweepConfig(robot="aras3", controllers=("pd-sat",), pairs=2, duration=0.5)
    run_sweep(other, out, workers=1, progress=False, format="parquet", restart_if_stale=True)
    rows, meta = load_table(out)
    assert meta["config"] == other.as_dict()
    assert sorted(int(row["pair"]) for row in rows) == [0, 1]


def test_dask_parquet_sweep_gives_the_same_rows(parquet_sweep, tmp_path):
    distributed = pytest.importorskip("dask.distributed")
    out = tmp_path / "results"
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=":0") as cluster:  # any free port
        run_sweep(CONFIG, out, dask_address=cluster.scheduler_address, progress=False,
                  format="parquet", chunk_size=1)
    assert len(parquet_parts(out)) == CONFIG.pairs
    _assert_same_rows(sorted(load_table(out)[0], key=lambda row: row["pair"]),
                      load_table(parquet_sweep)[0])


# -- tables a report reads: one row per run, only this sweep's -------------------------------
def _report(capsys, table: Path, tmp_path: Path) -> tuple[int, str]:
    from cdpr_sym.cli import main

    status = main(["report", "sweep", str(table), "--out", str(tmp_path / "report")])
    return status, capsys.readouterr().err


def test_a_csv_with_a_repeated_row_is_refused_naming_the_line(capsys, csv_sweep, tmp_path):
    table = tmp_path / "results.csv"
    lines = csv_sweep.read_text().splitlines()
    table.write_text("\n".join([*lines, lines[2]]) + "\n")
    shutil.copy(sidecar_path(csv_sweep), sidecar_path(table))
    status, err = _report(capsys, table, tmp_path)
    assert status == 2 and len(err.strip().splitlines()) == 1
    assert f"line {len(lines) + 1} of" in err and "repeats pair" in err and "line 3" in err


def test_a_csv_row_of_another_sweep_is_refused(capsys, csv_sweep, tmp_path):
    table = tmp_path / "results.csv"
    header, first, *rest = csv_sweep.read_text().splitlines()
    foreign = first.replace("pd-sat", "smooth", 1)
    table.write_text("\n".join([header, first, *rest, foreign]) + "\n")
    shutil.copy(sidecar_path(csv_sweep), sidecar_path(table))
    status, err = _report(capsys, table, tmp_path)
    assert status == 2 and "is not of this sweep" in err


def test_a_copied_parquet_part_is_refused_not_counted(capsys, parquet_sweep, tmp_path):
    dataset = _copy(parquet_sweep, tmp_path / "results")
    part = parquet_parts(dataset)[0]
    shutil.copy(part, part.with_name("part-copied.parquet"))
    status, err = _report(capsys, dataset, tmp_path)
    assert status == 2 and "repeats pair" in err
    assert _report(capsys, parquet_sweep, tmp_path)[0] == 0


# -- a resume judges each part whole: a copy or a part of another sweep is set aside ---------
def _rejected(out: Path) -> list[str]:
    aside = out.with_name(out.name + ".rejected")
    return sorted(path.name for path in aside.iterdir()) if aside.exists() else []


def test_resume_sets_a_copied_part_aside_and_runs_nothing(parquet_sweep, tmp_path):
    out = _copy(parquet_sweep, tmp_path / "results")
    part = parquet_parts(out)[0]
    copy = part.with_name("part-~copied.parquet")  # sorts after every written part
    shutil.copy(part, copy)
    _sweep(out, format="parquet")
    assert _rejected(out) == [copy.name]
    assert sorted(path.name for path in parquet_parts(out)) == sorted(
        path.name for path in parquet_parts(parquet_sweep))
    _assert_same_rows(load_table(out)[0], load_table(parquet_sweep)[0])


def test_resume_sets_aside_a_part_of_another_sweep_and_reruns_its_rows(parquet_sweep,
                                                                       tmp_path):
    other = run_sweep(SweepConfig(robot="aras3", controllers=("pd-sat",), pairs=3,
                                  duration=0.5, seed=CONFIG.seed + 1),
                      tmp_path / "other", workers=1, progress=False, format="parquet",
                      chunk_size=1)
    out = _copy(parquet_sweep, tmp_path / "results")
    lost = parquet_parts(out)[1]
    lost.unlink()
    foreign = parquet_parts(other)[1]  # the same key (pair, design), another start and goal
    shutil.copy(foreign, out / "part-foreign.parquet")
    _sweep(out, format="parquet", chunk_size=1)
    assert _rejected(out) == ["part-foreign.parquet"]
    _assert_same_rows(load_table(out)[0], load_table(parquet_sweep)[0])


def test_resume_sets_aside_an_unreadable_part_and_reruns_its_rows(parquet_sweep, tmp_path):
    out = _copy(parquet_sweep, tmp_path / "results")
    damaged = parquet_parts(out)[2]
    damaged.write_bytes(damaged.read_bytes()[:100])
    _sweep(out, format="parquet", chunk_size=1)
    assert _rejected(out) == [damaged.name]
    _assert_same_rows(load_table(out)[0], load_table(parquet_sweep)[0])


def test_a_part_with_a_row_of_another_design_is_set_aside(parquet_sweep, tmp_path):
    out = _copy(parquet_sweep, tmp_path / "results")
    part = parquet_parts(out)[0]
    table = pq.read_table(part)
    renamed = table.set_column(table.schema.get_field_index("controller"), "controller",
                               pa.array(["smooth"] * table.num_rows))
    pq.write_table(renamed, part)
    _sweep(out, format="parquet", chunk_size=1)
    assert _rejected(out) == [part.name]
    _assert_same_rows(load_table(out)[0], load_table(parquet_sweep)[0])


_DAMAGE = ("delete", "copy", "truncate", "empty", "foreign")


@pytest.fixture(scope="module")
def other_sweep(tmp_path_factory) -> Path:
    """A sweep of the same shape with another draw: its parts are foreign to the reference."""
    return run_sweep(SweepConfig(robot="aras3", controllers=("pd-sat",), pairs=3, duration=0.5,
                                 seed=CONFIG.seed + 7),
                     tmp_path_factory.mktemp("other") / "results", workers=1, progress=False,
                     format="parquet", chunk_size=1)


def _damage(out: Path, other: Path, kind: str, index: int, step: int) -> None:
    parts = parquet_parts(out)
    if not parts and kind != "foreign":
        return
    part = parts[index % len(parts)] if parts else None
    if kind == "delete":
        part.unlink()
    elif kind == "copy":
        shutil.copy(part, out / f"part-copy{step}.parquet")
    elif kind == "truncate":
        part.write_bytes(part.read_bytes()[: len(part.read_bytes()) // 2])
    elif kind == "empty":
        part.write_bytes(b"")
    else:
        foreign = parquet_parts(other)
        shutil.copy(foreign[index % len(foreign)], out / f"part-foreign{step}.parquet")


@pytest.mark.slow  # a dozen damaged datasets, each resumed: left to CI
def test_any_damage_to_a_parquet_dataset_is_repaired_by_a_resume(parquet_sweep, other_sweep,
                                                                tmp_path_factory):
    """Property: whatever parts are deleted, copied, cut, emptied or brought in from
    another sweep, one resume leaves exactly the reference sweep's rows, each once."""
    damages = st.lists(st.tuples(st.sampled_from(_DAMAGE), st.integers(0, 5)),
                       min_size=1, max_size=4)

    @settings(max_examples=12, deadline=None,
              suppress_health_check=[HealthCheck.function_scoped_fixture])
    @given(damages)
    def check(steps):
        out = _copy(parquet_sweep, tmp_path_factory.mktemp("damaged") / "results")
        for step, (kind, index) in enumerate(steps):
            _damage(out, other_sweep, kind, index, step)
        _sweep(out, format="parquet", chunk_size=1)
        _assert_same_rows(load_table(out)[0], load_table(parquet_sweep)[0])

    check()


# -- a report counts only the rows of the sweep its sidecar names ----------------------------
@pytest.fixture(scope="module")
def other_csv_sweep(tmp_path_factory) -> Path:
    """A CSV sweep of the same shape, drawn with another seed."""
    return run_sweep(SweepConfig(robot="aras3", controllers=("pd-sat",), pairs=3, duration=0.5,
                                 seed=CONFIG.seed + 7),
                     tmp_path_factory.mktemp("other_csv") / "results.csv", workers=1,
                     progress=False)


def test_a_row_of_another_draw_in_its_place_is_refused(capsys, csv_sweep, other_csv_sweep,
                                                       tmp_path):
    table = tmp_path / "results.csv"
    header, _, *rest = csv_sweep.read_text().splitlines()
    foreign = other_csv_sweep.read_text().splitlines()[1]  # pair 0 of pd-sat, another start
    table.write_text("\n".join([header, foreign, *rest]) + "\n")
    shutil.copy(sidecar_path(csv_sweep), sidecar_path(table))
    status, err = _report(capsys, table, tmp_path)
    assert status == 2 and len(err.strip().splitlines()) == 1
    assert "seed 0 does not draw for pair 0" in err


def test_a_sidecar_of_another_sweep_is_refused(capsys, csv_sweep, other_csv_sweep, tmp_path):
    table = tmp_path / "results.csv"
    shutil.copy(csv_sweep, table)
    shutil.copy(sidecar_path(other_csv_sweep), sidecar_path(table))
    status, err = _report(capsys, table, tmp_path)
    assert status == 2 and "does not draw" in err


def test_a_parquet_part_of_another_draw_replacing_one_is_refused(capsys, parquet_sweep,
                                                                other_sweep, tmp_path):
    dataset = _copy(parquet_sweep, tmp_path / "results")
    parquet_parts(dataset)[0].unlink()
    shutil.copy(parquet_parts(other_sweep)[0], dataset / "part-foreign.parquet")
    status, err = _report(capsys, dataset, tmp_path)
    assert status == 2 and "does not draw" in err


@pytest.mark.parametrize("damage", ["no sidecar", "header only", "binary"])
def test_tables_a_report_cannot_count_are_refused_in_one_line(capsys, csv_sweep, tmp_path,
                                                             damage):
    table = tmp_path / "results.csv"
    text = csv_sweep.read_text()
    if damage == "header only":
        text = text.splitlines()[0] + "\n"
    elif damage == "binary":
        text = "\x7fELF\x02\x01\x01" + "\x00" * 40
    table.write_text(text)
    if damage != "no sidecar":
        shutil.copy(sidecar_path(csv_sweep), sidecar_path(table))
    status, err = _report(capsys, table, tmp_path)
    assert status == 2 and len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert not (tmp_path / "report" / "report.md").exists()


def test_a_study_refuses_a_table_of_another_configuration(csv_sweep):
    """What a study reading its own folder passes: the pairs, seed and designs it ran."""
    from cdpr_sym.sweep.tables import load_sweep_table

    rows, _ = load_sweep_table(csv_sweep, pairs=CONFIG.pairs, seed=CONFIG.seed,
                               controllers=list(CONFIG.controllers))
    assert len(rows) == CONFIG.pairs
    for wrong in ({"controllers": ["l2", "pd-sat"]}, {"seed": CONFIG.seed + 1},
                  {"pairs": CONFIG.pairs + 1}):
        with pytest.raises(InvalidCase, match=r"not the .* of the study that reads it"):
            load_sweep_table(csv_sweep, **wrong)
