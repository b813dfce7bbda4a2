"""cdpr_sym: symbolic modelling, generated C and tension-feasible control of CDPRs.

The package follows the flow of the work, one folder a stage: ``robot`` (the description)
→ ``model`` (CasADi) → ``codegen`` (generated C) → ``control`` (the laws) → ``results``
(trajectories and their files) → ``closed_loop`` (simulation) → ``workspace``, ``sweep``
→ ``reporting``, ``studies``, ``export`` → ``cli``.
"""

import lazy_loader

# Names are imported on first use, so a command loads only the stages it needs
# (the stub beside this file lists them)
__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
