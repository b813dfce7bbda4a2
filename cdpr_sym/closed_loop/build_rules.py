"""Design rules that read the robot's build: what the closed loop attaches to a design before
it checks or builds it.

A design's defaults come from the robot by rules its own layer can work out (the ideal
plant's linearised loop, :mod:`cdpr_sym.control.sampled_loop`). One rule needs more: whether
``ida-winch``'s feedback filter helps or harms depends on the drum-cable modes of the robot's
build, which only the closed loop's as-built step has
(:func:`~cdpr_sym.closed_loop.built_loop.build_damping`). Such a design takes that reading as
a callable (``judged_by``), so the control layer imports nothing above it; :func:`judged`
attaches it. The simulator, the period checks, the exports, ``tune`` and the zoo study's
derived gains call it, so the design they check, run, export and report is one. A design
made and evaluated by hand (``WinchIdaPbc().stages_for``, ``step_function``) is not judged:
its rule then reads the ideal plant alone.
"""

from __future__ import annotations

from typing import Any


def judged(controller: Any) -> Any:
    """``controller`` with the closed loop's reading of the robot's build attached where its
    rules ask for one (its ``judged_by``); else ``controller`` itself."""
    attach = getattr(controller, "judged_by", None)
    return controller if attach is None else attach(_build_damping)


def _build_damping(controller: Any, robot: Any) -> float:
    """:func:`~cdpr_sym.closed_loop.built_loop.build_damping` (imported on first use: that
    module builds on the simulator)."""
    from cdpr_sym.closed_loop.built_loop import build_damping

    return build_damping(controller, robot)


def built_options(controller: Any, robot: Any) -> dict[str, Any]:
    """``controller``'s options as a loop builds it on ``robot`` (:func:`judged`): a filter
    stage count its rule chose (``feedback_stages="robot"``) written as the count the
    memory's layout has, for the records of an exported package."""
    options = controller.options()
    if options.get("feedback_stages") == "robot" and hasattr(controller, "stages_for"):
        options["feedback_stages"] = judged(controller).stages_for(robot)
    return options
