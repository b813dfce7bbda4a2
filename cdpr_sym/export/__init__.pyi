# The names this package exports, read by type checkers and by lazy_loader at import
# time: each is imported from its module on first use (see __init__.py).

from .bench import bench_export
from .description import REQUIRED_MODEL_TERMS
from .encoder_package import EncoderExportResult, export_encoder_c
from .guard import GuardLimits
from .package import ExportResult, export_c

__all__ = ["REQUIRED_MODEL_TERMS", "EncoderExportResult", "ExportResult", "GuardLimits",
           "bench_export", "export_c", "export_encoder_c"]
