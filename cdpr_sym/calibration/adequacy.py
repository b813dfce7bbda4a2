"""Whether the model fits the data: the chi-square test of the weighted residuals.

Every residual of :mod:`cdpr_sym.calibration.information` is a measurement error divided by
its stated standard deviation. If the measurement model is right and the noise is as
stated (independent, zero-mean, Gaussian), the weighted cost at the least-squares estimate,

    chi2 = r^T r,   nu = (number of residuals) - (number of unknowns fitted),

is a chi-square draw with nu degrees of freedom (exactly for a linear model, to first order
in the noise for ours: the unknowns are the gauge-free global ones and every pose's own).
``sigma0 = sqrt(chi2 / nu)``, the a posteriori noise factor, is then about 1, and a larger
value says the residuals are larger than the stated noise allows. The test of adequacy is
the upper tail p = P(X >= chi2), X ~ chi2(nu): a fit with p below :data:`SIGNIFICANCE`
(1e-3) is refused; a right model is refused that often by chance, a wrong one (a cable
stiffness that is not the cables', noise larger than stated, an anchor that moved during
the campaign, outliers, a wrong local minimum) almost always once it biases the residuals
by more than their noise. With a hundred residuals sigma0 = 1.3 is already p < 1e-3; the
previous rule (sigma0 above 5) let aras3's anchors be 5 mm off when its cables were
modelled elastic and were rigid (sigma0 4.2).

The tail is computed without scipy by the Wilson-Hilferty approximation: (X / nu)^(1/3)
is nearly normal with mean 1 - 2 / (9 nu) and variance 2 / (9 nu), so

    p ~ Q(((chi2 / nu)^(1/3) - 1 + 2 / (9 nu)) / sqrt(2 / (9 nu))),

Q the standard normal upper tail, erfc(z / sqrt(2)) / 2. Against the exact tail
(scipy.stats.chi2.sf, in the tests) it errs high near p = 1e-3 (so it refuses a little
less, never more): by 17 % of p at nu = 1, 7 % from nu = 10, 1 % from nu = 100; the chi2
at which it refuses is the exact one's within 3.1 % (nu = 1), 1 % from nu = 6. Encoder
rounding is uniform, not Gaussian: its fourth moment is smaller, so the test refuses a
right model even less often than :data:`SIGNIFICANCE` says.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

#: The upper-tail probability below which a fit is refused as inadequate.
SIGNIFICANCE = 1e-3


def chi_square_upper_tail(chi2: float, dof: int) -> float:
    """P(X >= chi2) for X ~ chi-square(dof), by Wilson-Hilferty (module notes).

    Parameters
    ----------
    chi2 : float
        The weighted cost, >= 0.
    dof : int
        Degrees of freedom, >= 1.
    """
    if dof < 1:
        raise ValueError(f"expected at least one degree of freedom, got {dof}")
    if not chi2 > 0:
        return 1.0
    spread = 2.0 / (9.0 * dof)
    z = ((chi2 / dof) ** (1.0 / 3.0) - (1.0 - spread)) / math.sqrt(spread)
    return 0.5 * math.erfc(z / math.sqrt(2.0))


@dataclasses.dataclass(frozen=True)
class Adequacy:
    """The chi-square test of a fit.

    Attributes
    ----------
    chi_square : float
        The weighted cost r^T r at the estimate.
    dof : int
        Residuals less unknowns fitted.
    p_value : float
        P(X >= chi_square), X ~ chi-square(dof) (Wilson-Hilferty).
    """

    chi_square: float
    dof: int
    p_value: float

    @classmethod
    def of(cls, chi_square: float, dof: int) -> Adequacy:
        dof = max(int(dof), 1)
        return cls(float(chi_square), dof, chi_square_upper_tail(chi_square, dof))

    @property
    def sigma0(self) -> float:
        """sqrt(chi_square / dof): about 1 when the noise is as stated."""
        return math.sqrt(self.chi_square / self.dof)

    @property
    def adequate(self) -> bool:
        """Whether the test passes at the default :data:`SIGNIFICANCE`."""
        return self.p_value >= SIGNIFICANCE

    def as_dict(self) -> dict[str, Any]:
        return {"chi_square": self.chi_square, "dof": self.dof, "p_value": self.p_value,
                "significance": SIGNIFICANCE, "adequate": self.adequate}
