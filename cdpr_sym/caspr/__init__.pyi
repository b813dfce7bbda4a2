# The names this package exports, read by type checkers and by lazy_loader at import
# time: each is imported from its module on first use (see __init__.py).

from .case import ChosenCase, choose_case
from .convert import pose_from_caspr
from .importer import CasprImport, caspr_import, import_caspr
from .xml_model import CasprModel, read_caspr

__all__ = ["CasprImport", "CasprModel", "ChosenCase", "caspr_import", "choose_case",
           "import_caspr", "pose_from_caspr", "read_caspr"]
