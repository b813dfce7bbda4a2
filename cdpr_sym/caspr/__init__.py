"""CASPR's robots imported: a bodies file and a cables file (the XML of the MATLAB toolbox
CASPR) read, checked and mapped exactly onto a cdpr_sym :class:`~cdpr_sym.robot.Robot`.

:mod:`~cdpr_sym.caspr.xml_model` reads the files (CASPR's conventions stated there);
:mod:`~cdpr_sym.caspr.convert` maps CASPR's joint coordinates onto a robot kind and builds
the frame; :mod:`~cdpr_sym.caspr.case` chooses a statically feasible start and goal;
:mod:`~cdpr_sym.caspr.importer` runs the three (:func:`import_caspr`).
"""

import lazy_loader

# Names are imported on first use, so a command loads only the stages it needs
# (the stub beside this file lists them)
__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
