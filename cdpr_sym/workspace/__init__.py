"""Workspaces: poses where the weight (static) or a box of wrenches (wrench-feasible) can be
held with tensions in the box, and wrench closure; classified in generated C, several poses
at once in SIMD lanes."""

from cdpr_sym.workspace.classify import (
    MAX_GRID_POSES,
    MAX_SAMPLE_POSES,
    Classification,
    WorkspaceEvaluator,
    classification_function,
    frame_shares,
    interior_box,
    sample_static_workspace,
)
from cdpr_sym.workspace.mapped import BLOCK, MappedEvaluator
from cdpr_sym.workspace.vectorised import LaneEvaluator, pose_evaluator
from cdpr_sym.workspace.wrench import (
    WrenchClassification,
    WrenchEvaluator,
    facet_normals,
    facet_projections,
    wrench_function,
)

__all__ = ["BLOCK", "MAX_GRID_POSES", "MAX_SAMPLE_POSES", "Classification", "LaneEvaluator",
           "MappedEvaluator", "WorkspaceEvaluator", "WrenchClassification", "WrenchEvaluator",
           "classification_function", "facet_normals", "facet_projections", "frame_shares",
           "interior_box", "pose_evaluator", "sample_static_workspace", "wrench_function"]
