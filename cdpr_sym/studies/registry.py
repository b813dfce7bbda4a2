"""The studies by name: what ``cdpr-sym study NAME`` and ``cdpr-sym report NAME`` run.

Each study module defines one :class:`~cdpr_sym.studies.interface.Study` as ``STUDY``.
Study modules load the simulator, cvxpy and matplotlib, so the registry names their
modules and imports one only when its study is asked for: building the command line's
parser (which lists the names) loads none of them.
"""

from __future__ import annotations

import importlib

from cdpr_sym.errors import UnknownName
from cdpr_sym.studies.interface import Study

#: Study name -> the module defining its ``STUDY``, in the order the command line lists them.
_MODULES = {"paper": "cdpr_sym.studies.paper", "compare": "cdpr_sym.studies.compare",
            "designs": "cdpr_sym.studies.designs", "rigid": "cdpr_sym.studies.rigid",
            "redundant": "cdpr_sym.studies.redundant",
            "robustness": "cdpr_sym.studies.robustness",
            "calibration": "cdpr_sym.studies.calibration", "zoo": "cdpr_sym.studies.zoo",
            "geometry": "cdpr_sym.studies.geometry",
            "underactuated": "cdpr_sym.studies.underactuated"}
#: The registered studies' names.
STUDY_NAMES = tuple(_MODULES)


def study_by_name(name: str) -> Study:
    """The registered study called ``name`` (its module imported on first use).

    Raises
    ------
    UnknownName
        No study of that name.
    """
    if name not in _MODULES:
        raise UnknownName(f"unknown study {name!r}; choose one of {', '.join(STUDY_NAMES)}")
    return importlib.import_module(_MODULES[name]).STUDY
