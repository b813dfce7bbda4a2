# The names this package exports, read by type checkers and by lazy_loader at import
# time: each is imported from its module on first use (see __init__.py).

from .equilibrium import Equilibrium, EquilibriumManifold, check_equilibrium, reduced_stiffness

__all__ = ["Equilibrium", "EquilibriumManifold", "check_equilibrium", "reduced_stiffness"]
