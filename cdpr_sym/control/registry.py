"""Registered controllers by their command-line names, and rebuilding one from its options."""

from __future__ import annotations

from typing import Any

from cdpr_sym.control.distributed import DistributedPD
from cdpr_sym.control.exact_box import BoxDesign, LinfDesign
from cdpr_sym.control.ida_pbc import PD, L2Design, SaturatedPD
from cdpr_sym.control.interface import Controller, capabilities
from cdpr_sym.control.nmpc import Nmpc
from cdpr_sym.control.planned import SmoothReference, VirtualReferenceIdaPbc
from cdpr_sym.control.tuning import FROM_ROBOT
from cdpr_sym.control.underactuated import CablePD, UnderactuatedIdaPbc, UnderactuatedIdaPbcIntegral
from cdpr_sym.control.winch_level import WinchIdaPbc
from cdpr_sym.errors import InvalidCase, UnknownName

#: The ``ida-ref-obs`` observer's rate L, 1/s: a 20 ms time constant (8 Hz), faster than
#: the loop's ~3 Hz; L dt = 0.05 at 1 kHz (its Euler step needs L dt < 2).
OBSERVER_RATE = 50.0
#: The ``nmpc-of`` observer's rate L, 1/s: a 50 ms time constant, slower than
#: ``ida-ref-obs``'s since the NMPC reads the estimate only every 20 ms.
NMPC_OBSERVER_RATE = 20.0
#: The ``smooth-lp`` command filter's corner and guard band: from the robot
#: (:func:`cdpr_sym.control.tuning.command_cutoff`, 0.6 f_c, 15 Hz on the paper's robot:
#: 5 times above its loop's ~3 Hz and 5 times below its drum-cable mode; and
#: :func:`~cdpr_sym.control.tuning.guard_band`, a sixtieth of the box, 0.97 N there: room for
#: the true tension of elastic cables on winches to lag or overshoot a command at the box's
#: edge, 0.2-0.5 N measured there with no guard).
COMMAND_CUTOFF = FROM_ROBOT
GUARD = FROM_ROBOT

#: Every design under its command-line name, with its default options. ``l2`` is the
#: paper's; ``smooth`` is the recommended one (see reports/designs).
CONTROLLERS: dict[str, Controller] = {
    "pd": PD(),
    "pd-sat": SaturatedPD(),
    "l2": L2Design(),
    "l2-minnorm": L2Design(construction="min_norm"),
    "linf": LinfDesign(),
    "box": BoxDesign(),
    "smooth": SmoothReference(),
    "ida-ref": VirtualReferenceIdaPbc(),
    "ida-ref-obs": VirtualReferenceIdaPbc(observer_rate=OBSERVER_RATE),
    "smooth-lp": SmoothReference(command_cutoff=COMMAND_CUTOFF, guard=GUARD),
    "pd-td": DistributedPD(),
    "ida-winch": WinchIdaPbc(),
    "nmpc": Nmpc(),
    "nmpc-sqp": Nmpc(solver="sqp"),
    "nmpc-ipopt": Nmpc(solver="ipopt"),
    "nmpc-of": Nmpc(observer_rate=NMPC_OBSERVER_RATE),
    "ida-under": UnderactuatedIdaPbc(),
    "ida-under-i": UnderactuatedIdaPbcIntegral(),
    "pd-under": CablePD(),
}


#: One line per design, for help texts and reports.
DESCRIPTIONS = {
    "pd": "PD + gravity compensation (IDA-PBC with J_d = 0); no tension bound",
    "pd-sat": "the same, clipped to [T_min, T_max] (the paper's Fig. 3); chatters at the bounds",
    "l2": "the paper's design: least-squares J_d (exact, in closed form) and alpha of (24); m >= n",
    "l2-minnorm": "the paper's design with the exact minimum-norm least squares (n >= 4)",
    "linf": "exact tension box, tensions centred in the l-infinity sense (paper's future work)",
    "box": "exact tension box, largest alpha, smallest J_d tension",
    "smooth": "recommended: minimum-jerk plan + feed-forward + PD; feasible, fast and smooth",
    "ida-ref": "IDA-PBC with a virtual reference particle (H_d never increases)",
    "ida-ref-obs": "ida-ref with a momentum observer cancelling the matched force the model "
               "misses (mass error)",
    "smooth-lp": "smooth, command low-passed at 0.6 f_c and kept a sixtieth of the box inside "
                 "it (15 Hz and 0.97 N on aras3): for winches",
    "pd-td": "PD + gravity compensation + tension distribution; any m >= n cables",
    "ida-winch": "IDA-PBC at the motors of the robot as built: energy shaped in the drum "
                 "coordinates, damping on the drum speeds, from the winch encoders alone; any "
                 "m >= n cables",
    "nmpc": "NMPC, hard tension and rate bounds, 50 Hz, horizon from the robot's braking time "
            "(1.2 s on aras3), one SQP step per "
            "sample (real-time iteration, generated C); any m >= n cables",
    "nmpc-sqp": "the same NMPC solved to convergence by CasADi's sqpmethod at every sample",
    "nmpc-ipopt": "the same NMPC solved to convergence by IPOPT (the reference)",
    "nmpc-of": "nmpc, offset-free: predicts with the force a momentum observer estimates the "
               "model misses (mass error)",
    "ida-under": "IDA-PBC for fewer cables than degrees of freedom: energy shaped in the cable "
                 "lengths along a path of stable equilibria, damping through the cables, J_d "
                 "keeping the box; m < n only",
    "ida-under-i": "ida-under with integral action on the cable lengths (k_i from the robot by "
                   "its extended linearisation), for the robot as built; m < n only",
    "pd-under": "PD on the cable lengths about the goal's, the goal's tension fed forward, "
                "from the first sample (no plan, no J_d): the baseline; m < n only",
}


def controller_by_name(name: str | Controller) -> Controller:
    """A registered controller by its command-line name; a controller as it is (every
    function that takes a controller or its name coerces it here).

    Parameters
    ----------
    name : str or Controller
        One of :data:`CONTROLLERS` (``"pd"``, ``"pd-sat"``, ``"l2"``, ``"smooth"``,
        ``"ida-winch"``, ``"nmpc"``, ...; ``cdpr-sym --help`` lists them all with a line
        each), or a controller.

    Returns
    -------
    Controller
        The design with its default options.

    Raises
    ------
    UnknownName
        ``name`` is not registered.
    """
    if not isinstance(name, str):
        return name
    try:
        return CONTROLLERS[name]
    except KeyError:
        raise UnknownName(f"unknown controller {name!r}; expected one of "
                          f"{', '.join(CONTROLLERS)}") from None


def controller_from_options(name: str, options: dict[str, Any]) -> Controller:
    """The controller of class ``CONTROLLERS[name]`` built from ``options`` (as
    ``controller.options()`` returns them); the options are validated."""
    return type(controller_by_name(name))(**options)


def check_cables(controller: Controller, n: int, m: int) -> None:
    """Raise :class:`InvalidCase` (``controller``) when ``controller`` cannot run a robot of
    n degrees of freedom on m cables: most designs invert a square W, a few take m > n, and
    only the underactuated ones take m < n (and nothing else)."""
    underactuated = capabilities(controller).underactuated
    if m < n and not underactuated:
        fewer = [name for name, design in CONTROLLERS.items()
                 if capabilities(design).underactuated]
        raise InvalidCase("controller", f"{controller.name} needs at least as many cables as "
                          f"degrees of freedom, got {m} cables for n = {n}; for fewer use "
                          f"{', '.join(fewer)}")
    if m >= n and not capabilities(controller).fully_actuated:
        raise InvalidCase("controller", f"{controller.name} is for fewer cables than degrees "
                          f"of freedom, got {m} cables for n = {n}")
    if m > n and not capabilities(controller).any_cables:
        redundant = [name for name, design in CONTROLLERS.items()
                     if capabilities(design).any_cables]
        raise InvalidCase("controller", f"{controller.name} needs as many cables as degrees "
                          f"of freedom (it inverts W), got {m} cables for n = {n}; use "
                          f"{', '.join(redundant)}")


#: The designs a sweep runs when none are named, by the robot's cables against its degrees
#: of freedom: the paper's design and the two recommended ones where they run (m = n); with
#: more cables the motor-level IDA-PBC in place of ``ida-ref``, which inverts W; with fewer
#: the underactuated IDA-PBC and its integral twin for the robot as built (the paper's
#: design and every fully actuated one refuse such a robot).
DEFAULT_SWEEP = {"square": ("l2", "smooth", "ida-ref"), "redundant": ("l2", "smooth", "ida-winch"),
                 "underactuated": ("ida-under", "ida-under-i")}


def robot_class(n: int, m: int) -> str:
    """"square" (m = n), "redundant" (m > n) or "underactuated" (m < n)."""
    return "square" if m == n else ("redundant" if m > n else "underactuated")


def default_sweep_designs(n: int, m: int) -> tuple[str, ...]:
    """The designs a sweep of a robot with ``n`` degrees of freedom on ``m`` cables runs
    by default (:data:`DEFAULT_SWEEP`); each of them runs on it (:func:`check_cables`)."""
    return DEFAULT_SWEEP[robot_class(n, m)]


def default_controller(n: int, m: int, *, encoders: bool = False) -> str:
    """The design ``simulate`` and ``export-c`` use when none is named: the paper's ``l2``
    where it runs (m >= n), else ``ida-under``; for an encoder-level package
    (``encoders``, m >= n) ``ida-winch``, the design that reads the drives (``l2`` trips
    that package's guard on the robot as built)."""
    if m < n:
        return "ida-under"
    return "ida-winch" if encoders else "l2"
