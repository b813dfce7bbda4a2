"""The box helpers the tension-bounded laws share, on numbers: the interval of alpha that
keeps s0 + alpha s1 in [lower, upper] (against a brute-force scan) and the clip flag."""

from __future__ import annotations

import functools

import casadi as ca
import numpy as np
import pytest

from cdpr_sym import UnknownName, controller_by_name
from cdpr_sym.control.parts import alpha_interval, clip_to_box


@functools.cache
def _interval_function(n: int) -> ca.Function:
    """alpha_interval on vectors of length n, alpha within [0, 1]."""
    syms = [ca.SX.sym(name, n) for name in ("s0", "s1", "lower", "upper")]
    return ca.Function("interval", syms, list(alpha_interval(*syms, within=(0.0, 1.0))))


def _interval(s0, s1, lower, upper) -> tuple[float, float]:
    low, high = _interval_function(len(s0))(s0, s1, lower, upper)
    return float(low), float(high)


def _scanned(s0, s1, lower, upper, alphas) -> np.ndarray:
    """The alphas of a fine grid keeping every entry inside [lower, upper]."""
    values = s0[None, :] + alphas[:, None] * s1[None, :]
    return alphas[np.all((values >= lower) & (values <= upper), axis=1)]


@pytest.mark.parametrize("slope_scale", [1e-3, 0.5, 10.0])  # slopes below and above 1 N
def test_the_alpha_interval_is_the_set_a_fine_scan_finds(slope_scale):
    rng = np.random.default_rng(int(slope_scale * 1000))
    alphas = np.linspace(0.0, 1.0, 200_001)
    checked = 0
    for _ in range(60):
        lower, upper = np.full(3, 1.0), np.full(3, 5.0)
        s0 = rng.uniform(0.5, 5.5, 3)
        s1 = rng.normal(scale=slope_scale, size=3)
        low, high = _interval(s0, s1, lower, upper)
        inside = _scanned(s0, s1, lower, upper, alphas)
        if inside.size == 0:
            assert low > high - 1e-5  # empty (up to the scan's step)
            continue
        checked += 1
        assert low == pytest.approx(inside.min(), abs=1e-5)
        assert high == pytest.approx(inside.max(), abs=1e-5)
    assert checked >= 10


def test_a_zero_slope_keeps_everything_or_nothing():
    assert _interval([3.0], [0.0], [1.0], [5.0]) == (0.0, 1.0)
    low, high = _interval([6.0], [0.0], [1.0], [5.0])
    assert low > high


def test_a_small_slope_near_a_bound_limits_alpha():
    # 0.2 N of room above, slope 0.5 N per unit alpha: alpha <= 0.4
    assert _interval([5.0], [0.5], [1.0], [5.2]) == pytest.approx((0.0, 0.4), abs=1e-12)


def test_a_tension_on_the_bound_is_not_clipped(aras3_model):
    robot = aras3_model.robot
    tau = ca.SX.sym("tau", 3)
    function = ca.Function("clip", [tau], list(clip_to_box(aras3_model, tau)))
    clipped, flag = function([robot.t_min, 0.5 * (robot.t_min + robot.t_max), robot.t_max])
    np.testing.assert_array_equal(np.array(clipped).ravel(),
                                  [robot.t_min, 0.5 * (robot.t_min + robot.t_max), robot.t_max])
    assert not bool(flag)
    assert bool(function([robot.t_min - 1e-9, 10.0, 10.0])[1])
    assert bool(function([10.0, 10.0, robot.t_max + 1e-9])[1])


def test_an_unknown_controller_lists_every_registered_name():
    with pytest.raises(UnknownName) as raised:
        controller_by_name("nope")
    assert str(raised.value) == ("unknown controller 'nope'; expected one of pd, pd-sat, l2, "
                                 "l2-minnorm, linf, box, smooth, ida-ref, ida-ref-obs, "
                                 "smooth-lp, pd-td, ida-winch, nmpc, nmpc-sqp, nmpc-ipopt, "
                                 "nmpc-of, ida-under, ida-under-i, pd-under")
