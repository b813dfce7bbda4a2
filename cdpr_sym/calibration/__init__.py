"""Calibration of the robot as built: anchors and encoder offsets identified from
measurements at static poses, with their covariance and an identifiability report.

* :mod:`~cdpr_sym.calibration.measurement`: the encoder reading and statics as CasADi
  functions of the unknown geometry;
* :mod:`~cdpr_sym.calibration.campaign`: what a campaign measured (tracker, self, load cells);
* :mod:`~cdpr_sym.calibration.information`: weighted residuals and their Jacobian, pose by pose;
* :mod:`~cdpr_sym.calibration.gauge`: what no measurement fixes, and how the frame is fixed;
* :mod:`~cdpr_sym.calibration.schur`: the reduced (Schur-complement) normal equations;
* :mod:`~cdpr_sym.calibration.estimate`: the estimate, its covariance, the Cramér-Rao bound;
* :mod:`~cdpr_sym.calibration.adequacy`: the chi-square test of whether the model fits;
* :mod:`~cdpr_sym.calibration.identifiability`: what is identified, named in words;
* :mod:`~cdpr_sym.calibration.simulated`: the campaign a known truth would give;
* :mod:`~cdpr_sym.calibration.plan`: D-optimal calibration poses;
* :mod:`~cdpr_sym.calibration.table`: the measurement CSV, read and checked;
* :mod:`~cdpr_sym.calibration.drawn`: a pair's robot as built, calibrated before its run.

The stage sits above the workspace (it draws candidate poses there) and the closed loop (a
pair's robot as built, calibrated, :mod:`~cdpr_sym.calibration.drawn`, is a plant of it): it
reads the model's kinematics and writes a :class:`~cdpr_sym.robot.Robot` (anchors,
attachments, encoder offsets) that every stage takes like any other.
"""

import lazy_loader

# Names are imported on first use (the stub beside this file lists them)
__getattr__, __dir__, __all__ = lazy_loader.attach_stub(__name__, __file__)
