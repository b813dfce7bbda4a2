"""Calibration of the robot as built: anchors and encoder offsets identified from
measurements at static poses, with their covariance and an identifiability report.

* :mod:`~cdpr_sym.calibration.measurement`: the encoder reading and statics as CasADi
  functions of the unknown geometry;
* :mod:`~cdpr_sym.calibration.campaign`: what a campaign measured (tracker, self, load cells);
* :mod:`~cdpr_sym.calibration.information`: weighted residuals and their Jacobian, pose by pose;
* :mod:`~cdpr_sym.calibration.gauge`: what no measurement fixes, and how the frame is fixed;
* :mod:`~cdpr_sym.calibration.estimate`: the estimate, its covariance, the Cramér-Rao bound;
* :mod:`~cdpr_sym.calibration.identifiability`: what is identified, named in words;
* :mod:`~cdpr_sym.calibration.simulated`: the campaign a known truth would give.
"""

from cdpr_sym.calibration.campaign import KINDS, Campaign, Noise
from cdpr_sym.calibration.estimate import Calibration, calibrate, cramer_rao_bound
from cdpr_sym.calibration.identifiability import Identifiability, gauge_free
from cdpr_sym.calibration.measurement import MeasurementModel, Unknowns
from cdpr_sym.calibration.simulated import Truth, simulate_campaign, true_tensions

__all__ = ["KINDS", "Calibration", "Campaign", "Identifiability", "MeasurementModel", "Noise",
           "Truth", "Unknowns", "calibrate", "cramer_rao_bound", "gauge_free",
           "simulate_campaign", "true_tensions"]
