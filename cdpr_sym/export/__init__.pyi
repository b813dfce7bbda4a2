# The names this package exports, read by type checkers and by lazy_loader at import
# time: each is imported from its module on first use (see __init__.py).

from .bench import bench_export
from .description import REQUIRED_MODEL_TERMS
from .package import ExportResult, export_c

__all__ = ["REQUIRED_MODEL_TERMS", "ExportResult", "bench_export", "export_c"]
