"""Everyday use from Python, notebooks and the shell: names for objects, short reprs,
plots and tables, help with defaults, JSON everywhere, quiet runs."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import matplotlib
import numpy as np
import pytest
from matplotlib.figure import Figure

from cdpr_sym import CONTROLLERS, Trajectory, __version__, preset, simulate
from cdpr_sym.cli import main
from cdpr_sym.control import DESCRIPTIONS

PNG = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def run() -> Trajectory:
    return simulate("aras3", "smooth", duration=0.5)


def test_simulate_takes_preset_and_controller_names(run):
    by_object = simulate(preset("aras3"), CONTROLLERS["smooth"], duration=0.5)
    np.testing.assert_array_equal(run.q, by_object.q)


def test_trajectory_repr_is_one_short_line(run):
    text = repr(run)
    assert len(text) < 120 and "\n" not in text and "aras3 / smooth" in text
    assert "500 steps" in text


def test_notebook_views_are_html_tables(run):
    assert "<table>" in run._repr_html_() and "tension feasible" in run._repr_html_()
    robot = preset("spatial6")
    assert len(repr(robot)) < 120 and "<table>" in robot._repr_html_()


def test_plot_returns_a_figure_and_keeps_the_backend(run, tmp_path):
    before = matplotlib.get_backend()
    figure = run.plot(alpha=True)
    assert isinstance(figure, Figure) and len(figure.axes) == 3
    figure.savefig(tmp_path / "run.png")
    assert (tmp_path / "run.png").read_bytes()[:8] == PNG
    assert matplotlib.get_backend() == before


def test_to_pandas_has_a_row_per_sample_and_the_held_command(run):
    frame = run.to_pandas()
    assert len(frame) == len(run.t)
    np.testing.assert_array_equal(frame["q_x"], run.q[:, 0])
    np.testing.assert_array_equal(frame["tau_2"].to_numpy()[:-1], run.tau[:, 1])
    assert np.isnan(frame["tau_2"].iloc[-1]) and frame["flags"].isna().iloc[-1]


def test_version_and_module_entry_point(capsys):
    with pytest.raises(SystemExit) as done:
        main(["--version"])
    assert done.value.code == 0 and __version__ in capsys.readouterr().out
    printed = subprocess.run([sys.executable, "-m", "cdpr_sym", "--version"], check=True,
                             capture_output=True, text=True).stdout
    assert printed.strip() == f"cdpr-sym {__version__}"


def test_help_shows_defaults_and_explains_the_controllers(capsys):
    with pytest.raises(SystemExit):
        main(["simulate", "--help"])
    text = capsys.readouterr().out
    words = " ".join(text.split())
    assert "(default: 10.0)" in text
    assert "default the paper's l2, or ida-under for fewer cables than degrees of freedom" in words
    for name, description in DESCRIPTIONS.items():
        assert f"{name:<11} {description}" in text
    assert set(DESCRIPTIONS) == set(CONTROLLERS)


def test_plain_simulate_output_has_units_and_the_registered_name(capsys):
    assert main(["simulate", "--controller", "l2-minnorm", "--duration", "0.3"]) == 0
    text = capsys.readouterr().out
    assert text.startswith("aras3 / l2-minnorm:") and "None" not in text
    assert " N .. " in text and "never" in text
    assert not any(len(word) > 12 and word[0].isdigit() for word in text.split())


@pytest.mark.parametrize("argv", [
    ["simulate", "--duration", "0.2"],
    ["workspace", "--resolution", "4"],
    ["export-c", "--controller", "pd"],
    ["sweep", "--pairs", "1", "--controllers", "pd", "--duration", "0.2", "--workers", "1"],
])
def test_every_command_that_reports_prints_one_json_object(argv, capsys, tmp_path):
    out = tmp_path / ("sweep.csv" if argv[0] == "sweep" else "out")
    extra = [] if argv[0] == "simulate" else ["--out", str(out)]
    assert main([*argv, *extra, "--json"]) == 0
    text = capsys.readouterr().out.strip()
    assert len(text.splitlines()) == 1 and isinstance(json.loads(text), dict)


def test_quiet_prints_nothing_and_shows_no_progress(capsys, tmp_path):
    assert main(["-q", "sweep", "--pairs", "1", "--controllers", "pd", "--duration", "0.2",
                 "--workers", "1", "--out", str(tmp_path / "s.csv")]) == 0
    assert capsys.readouterr() == ("", "")
    assert main(["simulate", "-q", "--duration", "0.2"]) == 0
    assert capsys.readouterr() == ("", "")


def test_workspace_rerun_leaves_its_files_unchanged(tmp_path, capsys):
    argv = ["workspace", "--resolution", "5", "--out", str(tmp_path)]
    assert main(argv) == 0
    first = {path.name: path.read_bytes() for path in tmp_path.iterdir()}
    assert main(argv) == 0
    assert {path.name: path.read_bytes() for path in tmp_path.iterdir()} == first
    assert "poses/s" in capsys.readouterr().out  # the rate is printed, not stored


def test_save_into_a_missing_folder_is_refused_before_the_run(capsys, tmp_path):
    assert main(["simulate", "--save", str(tmp_path / "no" / "run.npz")]) == 2
    assert "save" in capsys.readouterr().err


def test_the_package_imports_without_fcntl():
    """The compiled path locks builds with fcntl (POSIX); the package itself must import
    where there is none (Windows), with the casadi backend still usable."""
    code = ("import sys; sys.modules['fcntl'] = None\n"
            "import cdpr_sym\n"
            "run = cdpr_sym.simulate('planar2', 'pd', duration=0.05,\n"
            "    build_options=cdpr_sym.BuildOptions(backend='casadi'))\n"
            "print(len(run.t))")
    out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True,
                         text=True).stdout
    assert out.strip() == "51"


def test_the_package_ships_its_licence_and_type_marker():
    from importlib import resources
    from pathlib import Path

    assert resources.files("cdpr_sym").joinpath("py.typed").is_file()
    assert "MIT License" in (Path(__file__).parents[1] / "LICENSE").read_text()


def test_sweep_progress_hides_itself_off_a_terminal(tmp_path):
    """Run as a program with stderr to a file: no progress frames land in the log."""
    log = tmp_path / "log.txt"
    with log.open("w") as handle:
        subprocess.run([sys.executable, "-m", "cdpr_sym", "sweep", "--pairs", "2",
                        "--controllers", "pd", "--duration", "0.2", "--workers", "1",
                        "--out", str(tmp_path / "s.csv")], check=True, stderr=handle,
                       stdout=subprocess.DEVNULL)
    assert "\r" not in log.read_text() and "run" not in log.read_text()


def _public_functions():
    import inspect

    import cdpr_sym

    return [(name, getattr(cdpr_sym, name)) for name in cdpr_sym.__all__
            if inspect.isfunction(getattr(cdpr_sym, name))]


@pytest.mark.parametrize(("name", "function"), _public_functions(),
                         ids=lambda v: v if isinstance(v, str) else "")
def test_public_function_has_numpydoc_sections_naming_every_argument(name, function):
    import inspect

    doc = inspect.getdoc(function) or ""
    assert "Parameters\n----------" in doc and "Returns\n-------" in doc, name
    for argument in inspect.signature(function).parameters:
        assert argument in doc, f"{name}: {argument} undocumented"


def test_sweep_results_have_a_short_repr_a_table_view_and_a_frame(tmp_path):
    from cdpr_sym import load_sweep
    from cdpr_sym.sweep import SweepConfig, run_sweep

    config = SweepConfig(robot="aras3", controllers=("pd-sat", "smooth"), pairs=2,
                         duration=0.3)
    results = load_sweep(run_sweep(config, tmp_path / "s.csv", workers=1, progress=False))
    assert len(results.rows) == 4 and "designs pd-sat, smooth" in repr(results)
    assert len(repr(results)) < 120
    assert results._repr_html_().count("<tr>") == 3  # header and one row per design
    frame = results.to_pandas()
    assert len(frame) == 4 and set(frame["controller"]) == {"pd-sat", "smooth"}


def test_a_sweeps_frame_has_the_stored_column_types():
    """The table parses every number as a float and an empty cell as None; the frame gives
    the pair and the step counts back as integers and the metrics as floats (NaN where empty)."""
    from cdpr_sym.results.sweep_results import SweepResults

    ran = {"pair": 0.0, "controller": "pd", "status": "ok", "error": None, "settle_time": None,
           "final_error": 0.5, "converged": False, "fallback_steps": 3.0, "stop_reason": None}
    failed = {**ran, "pair": 1.0, "status": "error", "error": "diverged", "final_error": None,
              "converged": None, "fallback_steps": None}
    frame = SweepResults(Path("s.csv"), [ran], {}).to_pandas()
    assert str(frame["pair"].dtype) == "int64" and frame["pair"].tolist() == [0]
    assert str(frame["fallback_steps"].dtype) == "int64" and frame["fallback_steps"][0] == 3
    assert str(frame["settle_time"].dtype) == "float64" and np.isnan(frame["settle_time"][0])
    assert str(frame["converged"].dtype) == "bool"
    both = SweepResults(Path("s.csv"), [ran, failed], {}).to_pandas()
    assert str(both["fallback_steps"].dtype) == "Int64"
    assert both["fallback_steps"].isna().tolist() == [False, True]
    assert str(both["converged"].dtype) == "boolean" and both["pair"].tolist() == [0, 1]
    assert both["final_error"].isna().tolist() == [False, True]


def test_sweep_command_writes_parquet_that_report_reads(tmp_path, capsys):
    out = tmp_path / "sweep"
    assert main(["-q", "sweep", "--pairs", "2", "--controllers", "pd", "--duration", "0.2",
                 "--workers", "1", "--format", "parquet", "--out", str(out)]) == 0
    assert out.is_dir() and list(out.glob("part-*.parquet"))
    assert main(["report", "sweep", str(out), "--out", str(tmp_path / "r")]) == 0
    assert (tmp_path / "r" / "report.md").exists()


def test_a_damaged_sweep_sidecar_is_one_line_not_a_traceback(tmp_path, capsys):
    argv = ["-q", "sweep", "--pairs", "1", "--controllers", "pd", "--duration", "0.2",
            "--workers", "1", "--out", str(tmp_path / "s.csv")]
    assert main(argv) == 0
    (tmp_path / "s.csv.json").write_bytes(b"\x00\xff{")
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "is damaged" in err and len(err.strip().splitlines()) == 1
    assert main(["report", "sweep", str(tmp_path / "s.csv"), "--out", str(tmp_path / "r")]) == 2


def test_the_designs_the_readme_names_import_from_the_package():
    """The tour builds ``DistributedPD(method=...)``; ``ida-winch`` is ``WinchIdaPbc``."""
    from cdpr_sym import DistributedPD, WinchIdaPbc

    assert DistributedPD(method="min_norm_2d").name == "pd-td"
    assert WinchIdaPbc().name == "ida-winch"
