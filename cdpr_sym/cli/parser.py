"""The ``cdpr-sym`` arguments: every option with its help, defaults shown."""

from __future__ import annotations

import argparse
from pathlib import Path

from cdpr_sym.cli.robots import add_wrench_options
from cdpr_sym.closed_loop.case import TRAJECTORY_BUDGET_BYTES
from cdpr_sym.control import CONTROLLERS, DESCRIPTIONS
from cdpr_sym.robot import PRESET_NAMES, UNDERACTUATED_PRESETS
from cdpr_sym.studies.bench import MAX_SECONDS
from cdpr_sym.studies.registry import STUDY_NAMES
from cdpr_sym.sweep.config import FORMATS, MAX_PAIRS
from cdpr_sym.version import __version__
from cdpr_sym.workspace import MAX_GRID_POSES

#: Most local worker processes of a sweep.
MAX_WORKERS = 256

_CONTROLLER_HELP = "controllers:\n" + "\n".join(
    f"  {name:<11} {text}" for name, text in DESCRIPTIONS.items())
_ROBOT_HELP = (f"preset name ({', '.join(PRESET_NAMES + UNDERACTUATED_PRESETS)}) or robot TOML "
               "file")


class _Parser(argparse.ArgumentParser):
    """A parser whose usage errors are one line on stderr (exit status 2), as every other
    refusal of the command is, instead of argparse's usage block before the message."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


class _Formatter(argparse.RawDescriptionHelpFormatter):
    """Defaults in the help (where there is one worth showing); epilogs kept as written."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        if action.default not in (None, False, argparse.SUPPRESS) and "%(default)" not in text:
            text += " (default: %(default)s)"
        return text


def _common(*, progress: bool = False) -> argparse.ArgumentParser:
    """Options every command takes: --json and -q (and --no-progress where there is one).

    Their defaults are suppressed so that a ``-q`` given before the command is kept."""
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--json", action="store_true", default=argparse.SUPPRESS,
                        help="print the result as one JSON object")
    common.add_argument("-q", "--quiet", action="store_true", default=argparse.SUPPRESS,
                        help="no text and no progress: only the JSON result (with --json) "
                             "and errors")
    if progress:
        common.add_argument("--no-progress", action="store_true", default=argparse.SUPPRESS,
                            help="no progress bar (it hides itself when not on a terminal)")
    return common


def _as_built_options(parser: argparse.ArgumentParser, seeded: str) -> None:
    """``--as-built`` and ``--calibration`` (simulate and sweep)."""
    parser.add_argument("--as-built", metavar="SPEC",
                        help="run on the robot as built: 'default' (the robustness study's "
                        f"specification) or an as-built TOML file, drawn from the seed for "
                        f"{seeded}")
    parser.add_argument("--calibration", default="none", choices=["none", "tracker", "self"],
                        help="with --as-built: calibrate the drawn robot first (a simulated "
                        "tracker campaign, or the encoders alone for more cables than "
                        "degrees of freedom) and give the controller the calibrated model")


def build_parser() -> argparse.ArgumentParser:
    """The full argument parser of ``cdpr-sym``."""
    parser = _Parser(
        prog="cdpr-sym", formatter_class=_Formatter, epilog=_CONTROLLER_HELP,
        description="Model, simulate and verify tension-feasible control of cable-driven "
        "parallel robots.")
    parser.add_argument("--version", action="version", version=f"cdpr-sym {__version__}")
    parser.add_argument("-q", "--quiet", action="store_true",
                        help="no text and no progress: only the JSON result (with --json) "
                             "and errors")
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    def command(name: str, text: str, *, progress: bool = False) -> argparse.ArgumentParser:
        return commands.add_parser(name, help=text, description=text, formatter_class=_Formatter,
                                   parents=[_common(progress=progress)], epilog=_CONTROLLER_HELP)

    sim = command("simulate", "simulate one closed-loop run")
    sim.add_argument("--robot", default="aras3", help=_ROBOT_HELP)
    sim.add_argument("--controller", choices=list(CONTROLLERS),
                     help="the design (see the list below; default the paper's l2, or "
                          "ida-under for fewer cables than degrees of freedom)")
    sim.add_argument("--start", nargs="+", type=float, metavar="X",
                     help="start q: m (and rad for a rigid body's angles); default the case's")
    sim.add_argument("--goal", nargs="+", type=float, metavar="X",
                     help="goal q: m (rad); default the case's")
    sim.add_argument("--k", nargs="+", type=float,
                     help="stiffness gains K (diagonal), N/m (N m/rad); default the case's")
    sim.add_argument("--r-d", nargs="+", type=float,
                     help="damping gains R_d (diagonal), N s/m (N m s/rad); default the case's")
    sim.add_argument("--duration", type=float, default=10.0,
                     help=f"simulated time, s (the stored run may take at most "
                     f"{TRAJECTORY_BUDGET_BYTES >> 30} GiB)")
    sim.add_argument("--dt", type=float, default=1e-3, help="control period, s")
    sim.add_argument("--mass-scale", type=float, default=1.0,
                     help="plant mass / model mass (model error)")
    sim.add_argument("--slack", action="store_true",
                     help="the plant applies max(tau, 0): a cable cannot push")
    sim.add_argument("--rate-limit", type=float, help="actuator tension-rate limit, N/s")
    sim.add_argument("--seed", type=int, default=0, help="with --as-built: seed of the draw")
    sim.add_argument("--backend", default="auto", choices=["auto", "c", "casadi"],
                     help="generated C, or CasADi's virtual machine (auto: C if a compiler "
                     "is found)")
    sim.add_argument("--save", type=Path, help="write the trajectory to an .npz file (.npz is "
                     "appended to a name without it)")
    sim.add_argument("--animate", type=Path, metavar="FILE",
                     help="write an animation of the run: .gif or .html (matplotlib alone), "
                     ".mp4 (needs ffmpeg); cables coloured by tension against the box")
    sim.add_argument("--fps", type=float, default=25.0,
                     help="with --animate: frames per second, the run shown in real time "
                     "(at most 600 frames)")
    _as_built_options(sim, "the draw")

    study = command("study", "run a study and write its report", progress=True)
    study.add_argument("name", choices=STUDY_NAMES, help="the study")
    study.add_argument("--robot", help=f"{_ROBOT_HELP} (default aras3; the paper's claims are "
                       "about aras3, others are judged on their case; rigid: planar3 and "
                       "spatial6 unless given; redundant compares its own presets and takes "
                       "none)")
    study.add_argument("--out", type=Path, help="output folder (default reports/<name>)")
    study.add_argument("--pairs", type=int,
                       help=f"start/goal pairs of the sweeps (default 200; zoo: 40 per robot; "
                       f"compare, designs, rigid, zoo, "
                       f"redundant; at most {MAX_PAIRS:,})")
    study.add_argument("--seed", type=int, default=0, help="seed of the pair draw (>= 0)")

    workspace = command("workspace", "map the static and wrench-feasible workspaces")
    workspace.add_argument("--robot", default="aras3", help=_ROBOT_HELP)
    workspace.add_argument("--resolution", type=int,
                           help=f"grid points per axis (>= 2; at most {MAX_GRID_POSES:,} "
                           "poses in all; default 61, for fewer cables than coordinates "
                           "64 positions per axis in a plane and 16 in space)")
    workspace.add_argument("--orientation", nargs="+", type=float, metavar="RAD",
                           help="angles held fixed for a rigid body (default: the goal's)")
    add_wrench_options(workspace)
    workspace.add_argument("--out", type=Path, default=Path("reports/workspace"),
                           help="output folder")

    sweep = command("sweep", "run many start/goal pairs (resumable)", progress=True)
    sweep.add_argument("--robot", default="aras3", help=_ROBOT_HELP)
    sweep.add_argument("--controllers",
                       help="comma-separated controller names (see the list below); default "
                            "the designs that run on the robot: the paper's and the two "
                            "recommended ones, l2,smooth,ida-ref with as many cables as "
                            "degrees of freedom and l2,smooth,ida-winch with more; with fewer "
                            "ida-under,ida-under-i")
    sweep.add_argument("--pairs", type=int, required=True,
                       help=f"start/goal pairs (at most {MAX_PAIRS:,})")
    sweep.add_argument("--seed", type=int, default=0, help="seed of the pair draw (>= 0)")
    sweep.add_argument("--duration", type=float, default=10.0, help="simulated time, s")
    sweep.add_argument("--dt", type=float, default=1e-3, help="control period, s")
    sweep.add_argument("--mass-scale", type=float, default=1.0, help="plant mass / model mass")
    sweep.add_argument("--out", type=Path, required=True,
                       help="results: a CSV file, or a folder for Parquet (appended; "
                       "re-running resumes)")
    sweep.add_argument("--format", choices=FORMATS, default="csv",
                       help="csv, or parquet: a typed dataset of parts (pip install "
                       "'cdpr_sym[parquet]')")
    sweep.add_argument("--workers", type=int,
                       help=f"local processes (default: all cores; at most {MAX_WORKERS})")
    sweep.add_argument("--dask", metavar="ADDRESS", help="run on an existing Dask scheduler")
    _as_built_options(sweep, "each pair")

    report = command("report", "build a report from stored results")
    report.add_argument("kind", choices=["sweep", *STUDY_NAMES],
                        help="sweep: a sweep table; a study name: a computed study's folder")
    report.add_argument("results", type=Path,
                        help="sweep results (CSV file or Parquet folder), or a study's folder")
    report.add_argument("--out", type=Path, default=Path("reports/sweep"),
                        help="output folder (sweep only; a study's report is rebuilt in place)")

    bench = command("bench", "print speed benchmarks")
    bench.add_argument("--robot", default="aras3", help=_ROBOT_HELP)
    bench.add_argument("--seconds", type=float, default=1.0,
                       help=f"timing budget per row, s (at most {MAX_SECONDS:g})")

    export = command("export-c", "write a self-contained C99 package")
    export.add_argument("--robot", default="aras3", help=_ROBOT_HELP)
    export.add_argument("--controller", choices=list(CONTROLLERS),
                        help="the design (see the list below; default the paper's l2, or "
                             "ida-under for fewer cables than degrees of freedom; with "
                             "--from-encoders ida-winch)")
    export.add_argument("--out", type=Path, required=True,
                        help="output folder: new, empty or an earlier export (re-export)")
    export.add_argument("--force", action="store_true",
                        help="write into --out even if it holds other files")
    export.add_argument("--prefix", help="C prefix of every symbol (default cdpr_ROBOT_CTRL, "
                        "with --from-encoders cdpr_ROBOT_CTRL_encoders)")
    export.add_argument("--from-encoders", action="store_true",
                        help="package the controller a lab runs: encoder counts in, motor "
                        "torques out, forward kinematics, a guard with latched faults, the "
                        "robot as built in C for software in the loop, a timing program and "
                        "CTest tests")
    export.add_argument("--calibration", type=Path, metavar="FILE",
                        help="with --from-encoders: a calibrated robot file (cdpr-sym "
                        "calibrate) whose anchors and encoder offsets are compiled in")
    export.add_argument("--as-built", default="default", metavar="SPEC",
                        help="with --from-encoders: the robot as built of the software in the "
                        "loop, 'default' or an as-built TOML file (winches and encoders)")
    export.add_argument("--seed", type=int, default=0,
                        help="with --from-encoders: seed of the as-built draw")
    from cdpr_sym.cli.calibrate import add_parser as add_calibrate
    from cdpr_sym.cli.certify import add_parser as add_certify
    from cdpr_sym.cli.design import add_parser as add_design
    from cdpr_sym.cli.importing import add_parser as add_import
    from cdpr_sym.cli.tune import add_parser as add_tune
    from cdpr_sym.cli.view import add_parser as add_view

    add_calibrate(command)
    add_certify(command)
    add_design(command)
    add_tune(command)
    add_import(command)
    add_view(command)
    return parser
