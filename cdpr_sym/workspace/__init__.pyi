# The names this package exports, read by type checkers and by lazy_loader at import
# time: each is imported from its module on first use (see __init__.py).

from .classify import (
    MAX_GRID_POSES,
    MAX_SAMPLE_POSES,
    Classification,
    WorkspaceEvaluator,
    classification_function,
    frame_shares,
    interior_box,
    sample_static_workspace,
)
from .mapped import BLOCK, MappedEvaluator
from .vectorised import LaneEvaluator, pose_evaluator
from .wrench import (
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
