# The names this package exports, read by type checkers and by lazy_loader at import
# time: each is imported from its module on first use (see __init__.py).

from .campaign import KINDS, Campaign, Noise
from .estimate import Calibration, calibrate, cramer_rao_bound, default_unknowns
from .gauge import gauge_free
from .identifiability import Identifiability
from .measurement import MeasurementModel, Unknowns
from .simulated import Truth, simulate_campaign, true_tensions

__all__ = ["KINDS", "Calibration", "Campaign", "Identifiability", "MeasurementModel", "Noise",
           "Truth", "Unknowns", "calibrate", "cramer_rao_bound", "default_unknowns",
           "gauge_free", "simulate_campaign", "true_tensions"]
