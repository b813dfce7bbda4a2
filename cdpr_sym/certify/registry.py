"""What the toolkit can certify, and how: the declared protocols of a proof method, a
workspace property and a pair property, and the one table of each.

* A :class:`ProofMethod` decides boxes of positions for the robots it ``covers``
  (:class:`~cdpr_sym.certify.verdict.BoxVerdicts`).
* A :class:`WorkspaceProperty` says what a proven box proves (its statement, its words in
  figures and messages, its pointwise test for the sampled check) and which methods may
  prove it, in order; the first that covers the robot does.
* A :class:`PairProperty` is a design's property over pairs of start and goal boxes: its
  default design, its proof and the kind of its sampled check.

Adding a property or a method is its module plus one line below. The command line reads
its choices from these tables.
"""

from __future__ import annotations

import functools
from typing import Any, Protocol

import numpy as np

from cdpr_sym.certify.verdict import BoxVerdicts
from cdpr_sym.errors import InvalidCase
from cdpr_sym.model import SymbolicModel
from cdpr_sym.robot import Robot


class ProofMethod(Protocol):
    """A way to decide boxes of positions (or whole poses)."""

    #: Its name in certificates.
    key: str
    #: What it computes, in one line (``certificate.json``'s ``method``).
    description: str

    def covers(self, robot: Robot, wrench: bool) -> bool:
        """Whether it decides ``robot``'s boxes (``wrench``: against a wrench box)."""
        ...

    def verdicts(self, model: SymbolicModel, orientation: np.ndarray | None, compiled: bool,
                 wrench: np.ndarray | None) -> BoxVerdicts:
        """The box verdicts at the fixed ``orientation`` (rad; None: boxes span the whole
        pose), in generated C when ``compiled``, against the wrench box ``wrench`` (force N,
        moment N m; None: none)."""
        ...


class WorkspaceProperty(Protocol):
    """A property of poses that a workspace certificate proves over boxes."""

    #: Its name (``certify workspace --property``).
    key: str
    #: The command line's help.
    help: str
    #: The keys of the proof methods that may decide it, in order of preference.
    methods: tuple[str, ...]
    #: The figure's title.
    title: str
    #: The figure's legend for proven and disproven boxes.
    legend: tuple[str, str]
    #: The command's summary words for proven and disproven boxes.
    outcome: tuple[str, str]

    def statement(self, robot: Robot, wrench: bool) -> str:
        """What a proven box proves, in one sentence (``certificate.json``)."""
        ...

    def refusal(self, robot: Robot, wrench: bool) -> str:
        """Why no method of the property covers ``robot``, in one line."""
        ...

    def holds(self, robot: Robot, poses: np.ndarray, half_widths: np.ndarray) -> np.ndarray:
        """Whether the property holds at each pose (rows), by a pointwise computation
        independent of the box proofs (the sampled check's reference)."""
        ...


class PairProperty(Protocol):
    """A design's property over pairs of start and goal boxes."""

    #: The design's registered name (``certify pairs --controller``).
    key: str
    #: What a proven pair box proves.
    statement: str
    #: Its sampled check: a key of :data:`~cdpr_sym.certify.pair_report.SAMPLED_CHECKS`
    #: (``plan``: the plan re-derived; ``loop``: the loop re-derived in numpy), also its
    #: name in ``certificate.json``.
    check: str
    #: What the proof assumes, in one sentence.
    assumptions: str

    def design(self) -> Any:
        """The design with its default options."""
        ...

    def proof(self, model: SymbolicModel, design: Any, tracking_margin: float,
              min_width: float) -> Any:
        """The pair proof: called with the start and goal boxes' corners, it returns their
        :class:`~cdpr_sym.certify.smooth_pairs.PairVerdicts`."""
        ...


@functools.cache
def proof_methods() -> dict[str, ProofMethod]:
    """Every proof method, by key."""
    from cdpr_sym.certify.anchored import AnchoredMethod
    from cdpr_sym.certify.assumption import AssumptionMethod
    from cdpr_sym.certify.cramer import CramerMethod, WrenchCramerMethod
    from cdpr_sym.certify.facets import FacetMethod
    from cdpr_sym.certify.krawczyk import KrawczykMethod

    return _by_key(CramerMethod(), WrenchCramerMethod(), KrawczykMethod(), FacetMethod(),
                   AnchoredMethod(), AssumptionMethod())


@functools.cache
def workspace_properties() -> dict[str, WorkspaceProperty]:
    """Every workspace property, by key (the first is the default)."""
    from cdpr_sym.certify.assumption import AssumptionOne
    from cdpr_sym.certify.static import StaticFeasibility

    return _by_key(StaticFeasibility(), AssumptionOne())


@functools.cache
def pair_properties() -> dict[str, PairProperty]:
    """Every design's pair property, by the design's name (the first is the default)."""
    from cdpr_sym.certify.smooth_pairs import SmoothPairs
    from cdpr_sym.certify.storage_pairs import StoragePairs

    return _by_key(SmoothPairs(), StoragePairs())


def _by_key(*entries: Any) -> dict[str, Any]:
    table = {entry.key: entry for entry in entries}
    if len(table) != len(entries):
        raise ValueError("two registered entries share a key")
    return table


def workspace_property(key: str) -> WorkspaceProperty:
    """The workspace property ``key``; InvalidCase naming ``property`` otherwise."""
    table = workspace_properties()
    if key not in table:
        raise InvalidCase("property", f"expected one of {tuple(table)}, got {key!r}")
    return table[key]


def pair_property(key: str) -> PairProperty:
    """The pair property of design ``key``; InvalidCase naming ``controller`` otherwise."""
    table = pair_properties()
    if key not in table:
        raise InvalidCase("controller", f"pair certificates exist for {sorted(table)}, not "
                          f"{key!r}")
    return table[key]


def method_for(robot: Robot, wrench: bool, prop: str = "static") -> ProofMethod:
    """The proof method that decides ``robot``'s boxes for property ``prop``: the first of
    its methods that covers the robot (``wrench``: a wrench box is asked for); InvalidCase
    naming ``property`` when none does."""
    chosen = workspace_property(prop)
    methods = proof_methods()
    for key in chosen.methods:
        if methods[key].covers(robot, wrench):
            return methods[key]
    raise InvalidCase("property", chosen.refusal(robot, wrench))


def proof_method(robot: Robot, wrench: bool, prop: str = "static") -> str:
    """The key of :func:`method_for`'s method."""
    return method_for(robot, wrench, prop).key
