"""Export the controller a lab runs: encoder counts in, motor torques out, guarded, in C99.

``cdpr-sym export-c --from-encoders`` writes one folder (``<prefix>`` defaults to
``cdpr_<robot>_<controller>_encoders``):

* ``<prefix>.h``: the one public header: the controller's state struct, ``<prefix>_init``,
  ``_reset``, ``_sample``, ``_clear_fault``, the fault codes, the limits and the static
  operation counts;
* ``<prefix>.c`` with ``<prefix>_generated.inc``: one control period
  (:mod:`cdpr_sym.export.encoder_loop`) and the guard (:mod:`cdpr_sym.export.guard`);
* ``<prefix>_plan.c`` with ``<prefix>_plan_generated.inc``: the design's plan, run by
  ``init`` and ``reset`` (built without optimisation: large, and run once per move);
* ``<prefix>_plant.c`` with ``<prefix>_plant_generated.inc`` and ``plant_data.inc``: the
  robot as built in C (:mod:`cdpr_sym.export.software_in_loop`), for the programs below
  only, never linked into the controller's library;
* ``sil.c`` (software in the loop against the Python run, ``sil_reference.inc``),
  ``timing.c`` (time per sample over a million samples, as JSON), ``guard_test.c`` (every
  fault path), ``CMakeLists.txt`` (the library, the three programs, two CTest tests,
  ``cmake --install`` with a ``find_package`` configuration), ``README.md`` and
  ``manifest.json``.

The run the package reproduces is ``cdpr-sym simulate --robot R --controller D --as-built
SPEC --seed S`` from the robot's case (``--calibration FILE``: with the calibrated robot as
the controller's model, the same true plant). Staged as the state package is: everything is
checked before the first function is built (:mod:`.encoder_checks`), the package is
described (:mod:`.encoder_description`), rendered (:mod:`.encoder_render`) and written, with
a manifest that records the robot, the design, the draw and a hash of every file.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from pathlib import Path

import casadi as ca

from cdpr_sym.closed_loop.simulator import built_options
from cdpr_sym.control import Controller
from cdpr_sym.export.encoder_checks import CheckedExport, check_export
from cdpr_sym.export.encoder_description import (
    EncoderPackageDescription,
    describe_encoders,
)
from cdpr_sym.export.encoder_render import render_encoder_package
from cdpr_sym.export.guard import GuardLimits
from cdpr_sym.export.package import _GENERATOR, _make_folder
from cdpr_sym.robot import Robot
from cdpr_sym.version import __version__

#: Seconds of the reference run the package's loop reproduces, by default.
SIL_DURATION = 3.0


@dataclasses.dataclass(frozen=True)
class EncoderExportResult:
    """The files of one encoder-level package (see the module docstring).

    Attributes
    ----------
    out_dir : Path
    prefix : str
    files : dict of str to Path
        Every file written, by name.
    operations : dict of str to int
        Static operation counts: ``sample`` (every sample after the first), ``first_sample``
        (with the global start), ``plan`` (``init``), ``reset`` (an accepted reset).
    """

    out_dir: Path
    prefix: str
    files: dict[str, Path]
    operations: dict[str, int]

    @property
    def header(self) -> Path:
        return self.files[f"{self.prefix}.h"]



def export_encoder_c(robot: Robot | str | Path, controller: Controller | str,
                     out_dir: str | Path, *, calibration: str | Path | None = None,
                     as_built: str | Path = "default", seed: int = 0,
                     duration: float = SIL_DURATION, dt: float = 1e-3,
                     limits: GuardLimits = GuardLimits(), prefix: str | None = None,
                     overwrite: bool = False) -> EncoderExportResult:
    """Write the encoder-level C99 package of ``controller`` on ``robot`` to ``out_dir``.

    Parameters
    ----------
    robot : Robot, preset name or robot file
        The robot as designed (the true plant is drawn relative to it).
    controller : Controller or registered name
        A design of the state (``export-c``'s designs but the NMPC) or one that reads the
        winches (``ida-winch``).
    out_dir : str or Path
        The package folder (empty, new, or an earlier export).
    calibration : path, optional
        A calibrated robot file (``cdpr-sym calibrate``'s output): the controller's model,
        its anchors and encoder offsets compiled in. Same name, cables and dimension as
        ``robot``.
    as_built : "default" or path
        The as-built specification the plant of the software in the loop is drawn from
        (pair 0 of ``seed``, as ``simulate --as-built``); it must have winches and encoders
        (the counts' scale is its encoder resolution, the torque its drum radius).
    seed : int
        The draw's seed.
    duration : float
        s of the reference run (0 < duration <= 30).
    dt : float
        The control period, s.
    limits : GuardLimits
        The guard's default limits.
    prefix : str, optional
        The C prefix (default ``cdpr_<robot>_<controller>_encoders``).
    overwrite : bool
        Write into a non-empty folder that is not an earlier export.

    Returns
    -------
    EncoderExportResult

    Raises
    ------
    UnknownName, InvalidRobot
        Unknown preset or controller; a robot file missing or malformed.
    InvalidCase
        Naming the field: an NMPC (``controller``: its solver is exported by ``export-c``
        without ``--from-encoders``), more cables than degrees of freedom for a design that
        inverts W, a calibration of another robot, an as-built specification without
        winches or encoders, ``duration``, ``dt``, ``prefix`` or ``out_dir``.
    """
    checked = check_export(robot, controller, out_dir, calibration=calibration,
                           as_built=as_built, seed=seed, duration=duration, dt=dt,
                           limits=limits, prefix=prefix, overwrite=overwrite)
    description = describe_encoders(checked, duration=duration, dt=dt, limits=limits)
    texts = render_encoder_package(description)
    out = _make_folder(checked.out, overwrite)
    texts["manifest.json"] = _manifest(checked, description, texts, as_built, seed)
    files = {}
    for name, text in texts.items():
        (out / name).write_text(text)
        files[name] = out / name
    return EncoderExportResult(out, checked.prefix, files, description.operations.calls())


def _manifest(checked: CheckedExport, description: EncoderPackageDescription,
              texts: dict[str, str], as_built: str | Path, seed: int) -> str:
    """``manifest.json``: the robot, the design, the draw, the operation counts and the
    sha256 of every other file's text."""
    manifest = {"generator": _GENERATOR, "kind": "encoders", "version": __version__,
                "prefix": checked.prefix, "robot": checked.model_robot.as_dict(),
                "controller": {"name": checked.controller.name,
                               "options": built_options(checked.controller,
                                                        checked.model_robot)},
                "as_built": {"specification": str(as_built), "seed": seed,
                             **checked.draw_record},
                "casadi_version": ca.__version__,
                "operations": description.operations.calls(),
                "sha256": {name: hashlib.sha256(text.encode()).hexdigest()
                           for name, text in texts.items()}}
    return json.dumps(manifest, indent=2) + "\n"
