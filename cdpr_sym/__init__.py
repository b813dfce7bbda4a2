"""cdpr_sym: symbolic modelling, generated C and tension-feasible control of CDPRs.

The package follows the flow of the work, one folder a stage, each importing only the ones
before it: ``robot`` (the description) → ``linalg`` → ``distribution`` (tensions) →
``model`` (CasADi) → ``underactuated`` (the equilibria of fewer cables than coordinates)
→ ``as_built`` (the real robot's parts) → ``codegen`` (generated C) →
``control`` (the laws) → ``results`` (trajectories and their files) → ``closed_loop``
(simulation) → ``workspace`` → ``certify`` (interval proofs) → ``calibration`` (the geometry
as built, from measurements) → ``geometry`` (the geometry designed, and proven) → ``caspr``
(robots imported from CASPR's files) → ``sweep`` → ``reporting`` → ``export`` → ``studies``
→ ``cli``.
"""

import importlib
import pkgutil

import lazy_loader

# Names are imported on first use, so a command loads only the stages it needs
# (the stub beside this file lists them)
_exported, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
#: The stages (subpackages and modules), attributes of the package as before names were
#: loaded on first use (``cdpr_sym.closed_loop.run_many`` after ``import cdpr_sym``).
_STAGES = frozenset(module.name for module in pkgutil.iter_modules(__path__))


def __getattr__(name: str):
    if name in _STAGES:
        return importlib.import_module(f"{__name__}.{name}")
    return _exported(name)
