"""The static workspace: poses where gravity can be held with tensions in the box."""

from cdpr_sym.workspace.classify import (
    BLOCK,
    MAX_GRID_POSES,
    MAX_SAMPLE_POSES,
    Classification,
    WorkspaceEvaluator,
    classification_function,
    frame_shares,
    interior_box,
    sample_static_workspace,
)

__all__ = ["BLOCK", "MAX_GRID_POSES", "MAX_SAMPLE_POSES", "Classification",
           "WorkspaceEvaluator", "classification_function", "frame_shares", "interior_box",
           "sample_static_workspace"]
