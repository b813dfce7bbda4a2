"""Export: a robot's controller, model and closed-loop step as a self-contained C99 package."""

from cdpr_sym.export.package import REQUIRED_MODEL_TERMS, ExportResult, bench_export, export_c

__all__ = ["REQUIRED_MODEL_TERMS", "ExportResult", "bench_export", "export_c"]
