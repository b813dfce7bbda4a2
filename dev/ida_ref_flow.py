"""A study, not part of the package: a validated flow of ``ida-ref``'s move on its line, the
first piece a pair certificate for ``ida-ref`` would need (docs/certify.md, "What a
reachable set can start from"). It shows how far the method below gets, and where it
stops; run it with the package's environment:

    python dev/ida_ref_flow.py            # about four minutes on two cores

**The system.** For a point mass on the exact model with J_d = 0 (``lam = inf``), started at
rest with the particle on the platform, the platform and the particle stay on the line
through the start q0 and the goal q_g. With the particle xi = q_g + x e and the platform
q = q_g + y e (e the unit vector from the goal to the start, D = |q0 - q_g|):

    x' = v,  m v' = c - q,  q = p(x) + R(x) v,  y' = w,  m w' = -c,  c = k (y - x) + r_d (w - v),

from rest at x = y = D, where p and R are the design's pull and damping (re-derived here from
:class:`~cdpr_sym.control.planned.VirtualReferenceIdaPbc`'s docstring and parameters) for
F = 2 m a, a = boost 5.77 D / T^2. The states are (u, v, e, e', D) with u = D - x the
particle's travel and e = y - x: in these, the start is exact and the coupling c is one
state's combination, so boxes hold them without wrapping; D is a fifth, constant state,
so one flow covers an interval of start distances.

**The enclosure.** f = L X + g(X), L the coupling's spring and damper (constant), g the
particle's force q in two rows. One step of h:

    X(h) = e^{Lh} X + h phi_1(Lh) g(X) + R,  R = int_0^h e^{L(h - s)} (g(X(s)) - g(X)) ds,

R within h^2 / 2 G q' +- h^2 / 2 (e^{|L|h} - I) |G q'|, q' = grad q . f over an a priori box
B (X + [0, h] f(B) inside B, Picard-Lindelöf). The set is carried as centre + A r (Lohner):
the slope e^{Lh} + h phi_1 G grad q(X) times A as a point matrix, re-orthogonalised by QR,
D's column kept apart with its exact half-width; everything else goes into the box of r.
min and max are written (a + b -+ |a - b|) / 2 so that the interval derivative holds both
slopes at a kink, except d0 - |x| = min(u, 2 D - u) in CasADi's own fmin (tight near the
start; its slope is unbounded where x straddles 0, so no enclosure passes over the goal);
grad q is the hull over slices of the travel. For |x| < 1e-12 the design's pull is
F x |x| / (1e-12 delta), not F x / delta: V then differs from F r^2 / (2 delta) by
F 1e-24 / (6 delta), far inside the outward rounding of the bounds that use it. Between
steps, y and c stay within the hull of their enclosures widened by h^2 / 8 sup |y''|,
|c''|. Once H_d = 1/2 m (v^2 + w^2) + 1/2 k e^2 + V(x), which never increases, is below what
bounds |c| by ``final_coupling`` inside the linear well, the storage bound holds the rest.
The flow is of the loop in continuous time; the controller steps its particle by a
semi-implicit Euler step at its rate, a difference of O(dt) a certificate would bound too.

**What it shows** (aras3's gains, m = 4 kg, k = 1200 N/m, r_d = 100 N s/m): a single start
distance is enclosed through the cruise, the brake and the well's kink, the coupling force
to within hundredths of a newton; an interval of D of 0.1 mm, and one of 0.5 mm, is not:
the first-order remainder and the slope's width (second order in the set's width) grow
fastest where the ramp's pull rises with the travel and near the goal, where R's
sqrt(|x|) makes grad q steep, and the flow gives up there before the storage bound can
take over (which needs |x| of a few millimetres for |c| <= 2 N). A certificate over 10 cm
pair boxes would need D intervals of centimetres: a higher-order (Taylor-model) flow and a
terminal set better than H_d's are the missing pieces.
"""

from __future__ import annotations

import dataclasses
import math

import casadi as ca
import numpy as np

from cdpr_sym.certify import interval as iv
from cdpr_sym.certify.interval_c import CompiledIntervalFunction
from cdpr_sym.control.planned import VirtualReferenceIdaPbc

#: The states: the particle's travel u = D - x and its velocity v = x' (x its position along
#: the line, from the goal, m and m/s), the platform's offset from it e = y - x and its rate
#: (m, m/s), and the start distance D (m).
STATES = 5
#: Cells of lambda = y / D per unit; lambda runs over [LAMBDA_LOW, LAMBDA_HIGH].
CELLS_PER_UNIT = 64
LAMBDA_LOW, LAMBDA_HIGH = -0.5, 1.5
CELLS = int((LAMBDA_HIGH - LAMBDA_LOW) * CELLS_PER_UNIT)
#: Relative widening of every float product's bound (gamma_5 = 5.6e-16 would do).
ROUNDING = 1e-13
#: Tries at the a priori enclosure before a flow is given up.
APRIORI_TRIES = 6
#: Slices of the travel over which dq/dX is enclosed (its hull).
GRADIENT_PIECES = 8
#: A flow whose coefficient box grows beyond this (m or m/s) is given up.
BLOWN = 1.0


@dataclasses.dataclass(frozen=True)
class LineGains:
    """The numbers of the line system: the model's mass m (kg), the gains k (N/m) and r_d
    (N s/m) (one value: the robot's diagonal gains must be equal for the move to stay on the
    line) and the design."""

    mass: float
    k: float
    r_d: float
    design: VirtualReferenceIdaPbc


@dataclasses.dataclass(frozen=True)
class Tubes:
    """Per flow (start-distance interval, duration): ``kappa_low``, ``kappa_high`` (flows,
    CELLS), the hull of c / D (N/m) while lambda = y / D is in each cell (+inf, -inf where it
    never is); ``complete`` whether the flow reached the storage bound within its horizon
    and kept lambda inside [LAMBDA_LOW, LAMBDA_HIGH]; ``seconds`` the time (s) at which the
    storage bound took over, or minus the time at which the flow gave up; ``widest`` the
    widest enclosure of c over one step before that (N); ``left`` the particle's distance
    from the goal where the flow gave up (m)."""

    kappa_low: np.ndarray
    kappa_high: np.ndarray
    complete: np.ndarray
    seconds: np.ndarray
    widest: np.ndarray
    left: np.ndarray


def rhs_functions(gains: LineGains) -> tuple[ca.Function, ca.Function]:
    """f(X, T) (the line system of the module docstring, with the design's own pull and
    damping) and the gradient in X of the particle's nonlinear force q = p(x) + R(x) v, N
    (f = L X + g, g = (0, -q, 0, q, 0) / m)."""
    X, T = ca.SX.sym("X", STATES), ca.SX.sym("T")
    u, v, e, de, D = (X[i] for i in range(STATES))
    x = D - u
    design, m = gains.design, gains.mass
    accel = design.boost * 5.77 * D / T**2
    force = 2 * m * accel
    pull, damping = _particle_forces(design, x, u, D, m, force, accel)
    q = pull + damping * v
    c = gains.k * e + gains.r_d * de
    particle = (c - q) / m
    f = ca.vertcat(-v, particle, de, -c / m - particle, 0)
    return (ca.Function("line_rhs", [ca.vertcat(X, T)], [f, q]),
            ca.Function("line_grad_q", [ca.vertcat(X, T)], [ca.densify(ca.gradient(q, X))]))


def _check_exact(gains: LineGains) -> None:
    """L's entries, 1/m, k + 2 r_d^2 / m and the coupling's row times L must be floats
    exactly (they are for aras3's m = 4 kg, k = 1200 N/m, r_d = 100 N s/m): f - L X = G q
    and c'' = l . (L f + G q') then hold without a residual."""
    from fractions import Fraction

    m, k, r_d = (Fraction(value) for value in (gains.mass, gains.k, gains.r_d))
    # L's entries, 1/m, the storage's gain, and c's row times L (c'' = l . L f + ...)
    for value in (k / m, r_d / m, 2 * k / m, 2 * r_d / m, 1 / m, k + 2 * r_d**2 / m,
                  2 * r_d * k / m, k - 2 * r_d**2 / m):
        if Fraction(float(value)) != value:
            raise ValueError(f"the line system's constants are not exact floats for m = "
                             f"{gains.mass}, k = {gains.k}, r_d = {gains.r_d}")


def linear_part(gains: LineGains) -> np.ndarray:
    """L, the constant part of f = L X + g (coupling spring and damper, the travel's rate)."""
    m, k, r_d = gains.mass, gains.k, gains.r_d
    L = np.zeros((STATES, STATES))
    L[0, 1] = -1.0
    L[1, 2], L[1, 3] = k / m, r_d / m
    L[2, 3] = 1.0
    L[3, 2], L[3, 3] = -2 * k / m, -2 * r_d / m
    return L


def exponential_series(L: np.ndarray, h: float, shift: int, absolute: bool = False
                       ) -> tuple[np.ndarray, np.ndarray]:
    """sum_j (L h)^j / (j + shift)! (shift 0: e^{L h}; 1: phi_1(L h) = (e^{L h} - I) / (L h)),
    or with |L| for ``absolute``, as a midpoint matrix and an entrywise radius that holds
    the series' tail (||L h|| <= 1 asked) and the rounding of the partial sums."""
    Lh = (np.abs(L) if absolute else L) * h
    norm = np.abs(Lh).sum(axis=1).max()
    if norm > 1.0:
        raise ValueError(f"step too long for the linear part: ||L h|| = {norm:.3g} > 1")
    term = np.eye(len(L)) / math.factorial(shift)
    total = term.copy()
    magnitude = np.abs(term)
    for j in range(1, 40):
        term = term @ Lh / (j + shift)
        total = total + term
        magnitude = magnitude + np.abs(term)
    # tail after 40 terms: ||Lh||^40 / 40! / (1 - ||Lh||), far below the rounding term
    radius = 1e-12 * magnitude + 1e-300 + norm**40 / math.factorial(40) * 2
    return total, radius


def _particle_forces(design: VirtualReferenceIdaPbc, x, u, D, m, force, accel):
    """The design's pull along the line and its damping R (N, N s/m) at the particle's
    position x = D - u, from its docstring: f(r) = min(r / delta, 1, max(s, s + (D - r) /
    (ramp D))), pull = F f(|x|) sign(x), R = |pull| / sqrt(2 brake a |x| + 1e-12)
    + R_crit delta^2 / (delta^2 + x^2), R_crit = 2 sqrt(2 m F / delta). D - |x| is written
    min(u, 2 D - u), which interval arithmetic keeps tight near the start."""
    r = ca.fabs(x)
    delta, share = design.delta, design.start_share
    come = ca.fmin(u, 2 * D - u)
    ramp = _maximum(share, share + come / _maximum(design.ramp * D, 1e-9))
    profile = _minimum(_minimum(r / delta, 1.0), ramp)
    pull = x / _maximum(r, 1e-12) * force * profile
    brake_speed = ca.sqrt(2 * design.brake * accel * r + 1e-12)
    critical = 2 * ca.sqrt(2 * m * force / delta)
    return pull, ca.fabs(pull) / brake_speed + critical * delta**2 / (delta**2 + x**2)


def _minimum(a, b):
    """min(a, b) as (a + b - |a - b|) / 2: the same real value, and its derivative (through
    sign(a - b)) is enclosed by the hull of both slopes where the box meets the kink."""
    return 0.5 * (a + b - ca.fabs(a - b))


def _maximum(a, b):
    """max(a, b) as (a + b + |a - b|) / 2 (see :func:`_minimum`)."""
    return 0.5 * (a + b + ca.fabs(a - b))


class LineFlow:
    """Validated flows of the line system (module docstring) for one robot's gains and
    design, many at once.

    Parameters
    ----------
    gains : LineGains
    step : float
        h, s.
    settle : float
        s after the plan's duration by which the storage bound must take over (else the
        flow is incomplete).
    final_coupling : float
        N: the flow hands over to the storage bound once that bounds |c| by this.
    """

    def __init__(self, gains: LineGains, *, step: float = 1e-3, settle: float = 10.0,
                 final_coupling: float = 2.0) -> None:
        self.gains, self.h, self.settle = gains, float(step), float(settle)
        rhs, grad_q = rhs_functions(gains)
        self._f = CompiledIntervalFunction(rhs, centred=True, varying=STATES)
        self._grad_q = CompiledIntervalFunction(grad_q)
        _check_exact(gains)
        self.L = linear_part(gains)
        self._E = exponential_series(self.L, self.h, 0)
        self._phi = exponential_series(self.L, self.h, 1)
        # e^{|L| s} - I >= |e^{L s} - I| for s <= h, entrywise
        bound, radius = exponential_series(self.L, self.h, 0, absolute=True)
        self._E_minus_I = _upper(bound - np.eye(STATES) + radius)
        # g = outer(G, q): the rows of the particle's force in f
        self._G = np.array([0.0, -1.0, 0.0, 1.0, 0.0]) / gains.mass
        self.coupling_gain = gains.k + 2 * gains.r_d**2 / gains.mass
        self.final_energy = final_coupling**2 / (2 * self.coupling_gain)
        # the rows of y and of c as linear forms of the state
        self._forms = np.array([[-1.0, 0.0, 1.0, 0.0, 1.0],
                                [0.0, 0.0, gains.k, gains.r_d, 0.0]])

    def run(self, d_low, d_high, durations, trace: dict | None = None) -> Tubes:
        """The flows from rest at every start distance of [d_low, d_high] (m, > 0) for the
        plan durations ``durations`` (s), one flow per entry. ``trace``: filled with each
        flow's enclosure of c at every step, ``trace[flow] = [(t, low, high), ...]``."""
        d_low, d_high = np.asarray(d_low, float), np.asarray(d_high, float)
        T_all = np.asarray(durations, float)
        flows = len(d_low)
        kappa_low = np.full((flows, CELLS), np.inf)
        kappa_high = np.full((flows, CELLS), -np.inf)
        complete = np.zeros(flows, bool)
        escaped = np.zeros(flows, bool)
        seconds = np.full(flows, np.nan)
        widest = np.zeros(flows)
        left = np.full(flows, np.nan)
        ids = np.arange(flows)
        centre, A, rho = _initial_set(d_low, d_high)
        D, T = (d_low, d_high), T_all
        now = self._line_values(centre, A, rho)
        t, h = 0.0, self.h
        while len(ids):
            done, y_bound, c_bound = self._final_bounds(centre, A, rho, D, T)
            if done.any():
                view = (kappa_low[ids[done]], kappa_high[ids[done]])
                escaped[ids[done]] |= _record(*view, (-y_bound[done], y_bound[done]),
                                              (-c_bound[done], c_bound[done]),
                                              (D[0][done], D[1][done]))
                kappa_low[ids[done]], kappa_high[ids[done]] = view
                complete[ids[done]] = True
                seconds[ids[done]] = t
            keep = ~done & (t < T + self.settle)
            if not keep.all():
                ids, centre, A, rho = ids[keep], centre[keep], A[keep], rho[keep]
                D, T = (D[0][keep], D[1][keep]), T[keep]
                now = tuple((part[0][keep], part[1][keep]) for part in now)
                if not len(ids):
                    break
            previous = centre
            centre, A, rho, second_y, second_c, failed = self._step(centre, A, rho, T)
            after = self._line_values(centre, A, rho)
            reach = _constant(0.125 * h * h, 0.125, h, second_y[0])
            y_span = _widen(iv.hull(now[0], after[0]), reach, second_y)
            c_span = _widen(iv.hull(now[1], after[1]), reach, second_c)
            # a flow that gave up at this step (no a priori box) records nothing of it
            good = ids[~failed]
            view = (kappa_low[good], kappa_high[good])
            escaped[good] |= _record(*view, _rows(y_span, ~failed), _rows(c_span, ~failed),
                                     _rows(D, ~failed))
            kappa_low[good], kappa_high[good] = view
            widest[good] = np.maximum(widest[good], (c_span[1] - c_span[0])[~failed])
            now = after
            if trace is not None:
                for j, flow in enumerate(ids):
                    if failed[j]:
                        continue
                    trace.setdefault(int(flow), []).append((t + h, after[1][0][j],
                                                            after[1][1][j]))
            t += h
            if failed.any():
                seconds[ids[failed]] = -t  # given up at t (negative)
                left[ids[failed]] = previous[failed, 4] - previous[failed, 0]
                keep = ~failed
                ids, centre, A, rho = ids[keep], centre[keep], A[keep], rho[keep]
                D, T = (D[0][keep], D[1][keep]), T[keep]
                now = tuple((part[0][keep], part[1][keep]) for part in now)
        return Tubes(kappa_low, kappa_high, complete & ~escaped, seconds, widest, left)

    def _line_values(self, centre, A, rho) -> tuple[iv.Interval, iv.Interval]:
        """y and c over the set {centre + A r : |r| <= rho}."""
        return tuple(_linear_form(form, centre, A, rho) for form in self._forms)

    def _final_bounds(self, centre, A, rho, D, T):
        """Where H_d's upper bound hands over to the storage bound (module docstring): the
        mask, and there the bounds on |y| (m) and |c| (N) for all later time."""
        g, design = self.gains, self.gains.design
        lo, hi = _box(centre, A, rho)
        e = (lo[:, 2], hi[:, 2])
        w = _linear_form(np.array([0.0, 1.0, 0.0, 1.0, 0.0]), centre, A, rho)
        half_m, delta = iv.point(0.5 * g.mass, lo[:, 0]), iv.point(design.delta, lo[:, 0])
        # F = 2 m boost 5.77 D / T^2 over the interval of D
        per_distance = iv.div(iv.point(2 * g.mass * design.boost * 5.77, T),
                              iv.square((T, T)))
        force = iv.mul(per_distance, D)
        r = iv.absolute(_linear_form(np.array([-1.0, 0.0, 0.0, 0.0, 1.0]), centre, A, rho))
        # V(r) <= F r^2 / (2 delta) for r <= delta, F (r - delta / 2) beyond (f <= 1, r / delta)
        well = iv.div(iv.square(r), iv.twice(delta))
        beyond = iv.sub(r, iv.mul(iv.point(0.5, r[0]), delta))
        potential = iv.mul(force, (np.where(r[1] <= design.delta, well[1], beyond[1]),) * 2)
        energy = iv.add(iv.add(iv.mul(half_m, iv.square((lo[:, 1], hi[:, 1]))),
                               iv.mul(half_m, iv.square(w))),
                        iv.add(iv.mul(iv.point(0.5 * g.k, r[0]), iv.square(e)), potential))
        bound = energy[1]
        # inside r*, the pull is the linear well: V = F r^2 / (2 delta) there
        one = iv.point(1.0, r[0])
        core = iv.mul(D, iv.sub(one, iv.mul(iv.point(design.ramp, r[0]),
                                            iv.sub(one, iv.point(design.start_share, r[0])))))
        core = (np.minimum(core[0], design.delta), np.minimum(core[1], design.delta))
        floor = iv.div(iv.mul(force, iv.square(core)), iv.twice(delta))[0]
        done = (bound <= self.final_energy) & (bound < floor)
        h = (bound, bound)
        x_bound = iv.sqrt(iv.div(iv.mul(iv.twice(delta), h), force))[1]
        e_bound = iv.sqrt(iv.div(iv.twice(h), iv.point(g.k, bound)))[1]
        y_bound = iv.add((x_bound, x_bound), (e_bound, e_bound))[1]
        c_bound = iv.sqrt(iv.mul(iv.twice(h), iv.point(self.coupling_gain, bound)))[1]
        done &= np.isfinite(y_bound) & np.isfinite(c_bound)
        return done, y_bound, c_bound

    def _rhs(self, box: iv.Interval, T: np.ndarray, output: int = 0) -> iv.Interval:
        """f (output 0, (flows, 5)) or q (output 1, (flows,)) over boxes."""
        out = self._f((np.vstack([box[0].T, T]), np.vstack([box[1].T, T])))[output]
        return (out[0].T, out[1].T) if output == 0 else (out[0][0], out[1][0])

    def _gradient(self, box: iv.Interval, T: np.ndarray) -> iv.Interval:
        """(flows, 5) bounds of dq / dX over boxes: the hull of the natural extension over
        GRADIENT_PIECES slices of the travel u (q's dependence on the position is where the
        natural extension loses most)."""
        pieces = GRADIENT_PIECES
        share = np.linspace(0.0, 1.0, pieces + 1)
        width = box[1][:, :1] - box[0][:, :1]
        edges = box[0][:, :1] + width * share[None, :]  # (flows, pieces + 1)
        edges[:, 0], edges[:, -1] = box[0][:, 0], box[1][:, 0]
        lo, hi = np.repeat(box[0], pieces, axis=0), np.repeat(box[1], pieces, axis=0)
        # neighbouring slices share their rounded edge, so together they cover [lo, hi]
        lo[:, 0], hi[:, 0] = edges[:, :-1].ravel(), edges[:, 1:].ravel()
        out = self._grad_q((np.vstack([lo.T, np.repeat(T, pieces)]),
                            np.vstack([hi.T, np.repeat(T, pieces)])))[0]
        return (out[0].T.reshape(-1, pieces, STATES).min(axis=1),
                out[1].T.reshape(-1, pieces, STATES).max(axis=1))

    def _apriori(self, box: iv.Interval, T: np.ndarray) -> tuple[iv.Interval, np.ndarray]:
        """A box B with X + [0, h] f(B) inside B, per flow (and a mask of the flows where
        none was found)."""
        h = self.h
        reach = _reach(h, self._rhs(box, T), box)
        B = _inflate(iv.hull(box, reach), box)
        found = np.zeros(len(T), bool)
        for _ in range(APRIORI_TRIES):
            reach = _reach(h, self._rhs(B, T), box)
            inside = np.all((reach[0] >= B[0]) & (reach[1] <= B[1]), axis=1)
            found |= inside
            if found.all():
                break
            widened = _inflate(iv.hull(B, reach), box)
            B = (np.where(found[:, None], B[0], widened[0]),
                 np.where(found[:, None], B[1], widened[1]))
        return B, ~found

    def _step(self, centre, A, rho, T):
        """One step (module docstring): the new set, y'' and c'' over the step, and the
        flows that failed (no a priori box, blown up).

        With f = L X + g(X): X(h) = e^{Lh} X + h phi_1(Lh) g(X) + R,
        R = int_0^h e^{L(h - s)} (g(X(s)) - g(X)) ds, g(X(s)) - g(X) in s G (grad q(B) . f(B)),
        so R is in h^2 / 2 G gamma +- h^2 / 2 (e^{|L|h} - I) |G gamma|, gamma = grad q . f
        over B. Over the set, X + h phi_1 g(X) has the slope e^{Lh} + h phi_1 G grad q(X)."""
        h = self.h
        box = _box(centre, A, rho)
        B, failed = self._apriori(box, T)
        f_B = self._rhs(B, T)
        grad_B = self._gradient(B, T)
        rate = _dot(grad_B, f_B)  # q' over the step, N/s
        G = self._G
        gamma = self._particle_rows(iv.mul(_constant(0.5 * h * h, 0.5, h, rate[0]), rate))
        magnitude = np.maximum(np.abs(gamma[0]), np.abs(gamma[1]))
        extra = _upper(magnitude @ self._E_minus_I.T)
        remainder = iv.add(gamma, (-extra, extra))
        # the image of the centre: E x + h phi_1 g(x)
        E, E_rad = self._E
        phi, phi_rad = self._phi
        g_centre = self._particle_rows(self._rhs((centre, centre), T, output=1))
        g_mid = 0.5 * (g_centre[0] + g_centre[1])
        g_rad = _upper(np.maximum(g_centre[1] - g_mid, g_mid - g_centre[0]))
        image_mid = centre @ E.T + h * (g_mid @ phi.T)
        image_rad = _upper(np.abs(centre) @ E_rad.T + h * (g_rad @ np.abs(phi).T
                                                           + np.abs(g_mid) @ phi_rad.T)
                           + ROUNDING * (np.abs(centre) @ np.abs(E).T
                                         + h * np.abs(g_mid) @ np.abs(phi).T))
        image = iv.add(iv.outward(image_mid - image_rad, image_mid + image_rad), remainder)
        new_centre = 0.5 * (image[0] + image[1])
        loose = _upper(np.maximum(image[1] - new_centre, new_centre - image[0]))
        # the slope over the set: E + h phi_1 G grad q(X)
        grad_X = self._gradient(box, T)
        grad_mid = 0.5 * (grad_X[0] + grad_X[1])
        grad_rad = _upper(np.maximum(grad_X[1] - grad_mid, grad_mid - grad_X[0]))
        column = h * (phi @ G)  # h phi_1 G
        M = E[None] + column[None, :, None] * grad_mid[:, None, :]
        M_rad = _upper(E_rad[None] + np.abs(column)[None, :, None] * grad_rad[:, None, :]
                       + h * (phi_rad @ np.abs(G))[None, :, None]
                       * np.maximum(np.abs(grad_X[0]), np.abs(grad_X[1]))[:, None, :]
                       + ROUNDING * (np.abs(E)[None] + np.abs(column)[None, :, None]
                                     * np.abs(grad_mid)[:, None, :]))
        spread = _upper(np.einsum("fij,fj->fi", np.abs(A), rho))
        C = M @ A
        C_err = ROUNDING * np.abs(M) @ np.abs(A)
        loose = _upper(loose + np.einsum("fij,fj->fi", M_rad, spread)
                       + np.einsum("fij,fj->fi", C_err, rho))
        # D keeps its own column (its sensitivity, carried as a point vector) and its exact
        # half-width; the four moving states are re-orthogonalised among themselves
        moving = STATES - 1
        loose = _upper(loose + ROUNDING * np.einsum("fij,fj->fi", np.abs(M),
                                                    np.abs(A[:, :, moving]))
                       * rho[:, moving:])
        block = C[:, :moving, :moving]
        order = np.argsort(-np.linalg.norm(block * rho[:, None, :moving], axis=1), axis=1)
        Q = np.linalg.qr(np.take_along_axis(block, order[:, None, :], axis=2))[0]
        new_rho = rho.copy()
        new_rho[:, :moving] = _coefficients(Q, block, rho[:, :moving], loose[:, :moving])
        new_A = np.zeros_like(A)
        new_A[:, :moving, :moving] = Q
        new_A[:, :, moving] = C[:, :, moving]
        new_centre[:, moving] = centre[:, moving]  # D is constant: its column holds it
        failed |= ~np.all(np.isfinite(new_rho), axis=1) | (np.max(new_rho, axis=1) > BLOWN)
        failed |= ~np.all(np.isfinite(new_centre), axis=1)
        # y'' = -c / m and c'' = l . (L f + G q') over the step
        second_y = iv.div(_matvec_row(-self._forms[1], B),
                          iv.point(self.gains.mass, B[0][:, 0]))
        c_rate = _matvec_row(self._forms[1] @ self.L, f_B)
        second_c = iv.add(c_rate, _matvec_row(self._forms[1], self._particle_rows(rate)))
        return new_centre, new_A, new_rho, second_y, second_c, failed

    def _particle_rows(self, q: iv.Interval) -> iv.Interval:
        """g for the particle force q (N, per flow): (0, -q, 0, q, 0) / m, (flows, 5)."""
        row = iv.div(q, iv.point(self.gains.mass, q[0]))
        lo, hi = np.zeros((len(q[0]), STATES)), np.zeros((len(q[0]), STATES))
        lo[:, 1], hi[:, 1] = -row[1], -row[0]
        lo[:, 3], hi[:, 3] = row
        return lo, hi


def _dot(x: iv.Interval, y: iv.Interval) -> iv.Interval:
    """Sum over the last axis of x y (intervals, (flows, 5)), rounded outward."""
    total = iv.mul((x[0][:, 0], x[1][:, 0]), (y[0][:, 0], y[1][:, 0]))
    for j in range(1, x[0].shape[1]):
        total = iv.add(total, iv.mul((x[0][:, j], x[1][:, j]), (y[0][:, j], y[1][:, j])))
    return total


def _reach(h: float, rates: iv.Interval, box: iv.Interval) -> iv.Interval:
    """X + [0, h] rates, rounded outward."""
    moved = iv.mul(iv.point(h, rates[0]), rates)
    return iv.add(box, (np.minimum(moved[0], 0.0), np.maximum(moved[1], 0.0)))


def _inflate(box: iv.Interval, start: iv.Interval) -> iv.Interval:
    """``box`` (holding ``start``) widened, on each coordinate it reaches beyond ``start``,
    by a twentieth of its width and a little more: a guess at an a priori box, checked by
    the caller."""
    moving = (box[0] < start[0]) | (box[1] > start[1])
    pad = np.where(moving, 0.05 * (box[1] - box[0])
                   + 1e-12 * (1 + np.abs(box[0]) + np.abs(box[1])), 0.0)
    return box[0] - pad, box[1] + pad


def _matvec_row(form: np.ndarray, vector: iv.Interval) -> iv.Interval:
    """The exact row ``form`` times an interval vector (flows, 5), rounded outward."""
    row = np.broadcast_to(form, vector[0].shape)
    return _dot((row, row), vector)


def _widen(interval: iv.Interval, reach: iv.Interval, second: iv.Interval) -> iv.Interval:
    """interval +- reach sup |second|, rounded outward."""
    by = iv.mul(reach, iv.absolute(second))[1]
    return iv.add(interval, (-by, by))


def _constant(value: float, factor: float, h: float, like: np.ndarray) -> iv.Interval:
    """factor h^2 (``value`` its float) as an interval holding the real product."""
    exact = iv.mul(iv.point(factor, like), iv.square(iv.point(h, like)))
    return np.minimum(exact[0], value), np.maximum(exact[1], value)


def _rows(interval: iv.Interval, mask: np.ndarray) -> iv.Interval:
    return interval[0][mask], interval[1][mask]


def _box(centre: np.ndarray, A: np.ndarray, rho: np.ndarray) -> iv.Interval:
    """The interval hull of {centre + A r : |r| <= rho}, rounded outward."""
    radius = _upper(np.einsum("fij,fj->fi", np.abs(A), rho))
    return iv.outward(centre - radius, centre + radius)


def _upper(values: np.ndarray) -> np.ndarray:
    """A bound on a computed sum of non-negative products: widened by ROUNDING and by the
    smallest normal float."""
    return values * (1 + ROUNDING) + 1e-300


def _linear_form(form: np.ndarray, centre, A, rho) -> iv.Interval:
    """l . X over {centre + A r : |r| <= rho}: l . centre +- |l| |A| rho, rounded outward."""
    middle = centre @ form
    radius = _upper(np.einsum("j,fjk,fk->f", np.abs(form), np.abs(A), rho)
                    + ROUNDING * (np.abs(centre) @ np.abs(form)))
    return iv.outward(middle - radius, middle + radius)


def _coefficients(Q: np.ndarray, C: np.ndarray, rho: np.ndarray, loose: np.ndarray):
    """rho' with {C r + z : |r| <= rho, |z| <= loose} inside {Q s : |s| <= rho'}.

    With P = Q^T: s = P y + (I - P Q) s, so |s| <= |P y| + eps ||s|| and
    ||s|| <= ||P y|| / (1 - eps), eps >= ||I - P Q||_inf (rounding of P Q included)."""
    P = np.swapaxes(Q, 1, 2)
    PC = P @ C
    base = (np.einsum("fij,fj->fi", np.abs(PC) + ROUNDING * (np.abs(P) @ np.abs(C)), rho)
            + np.einsum("fij,fj->fi", np.abs(P), loose))
    base = _upper(base)
    residual = np.abs(np.eye(Q.shape[-1]) - P @ Q) + ROUNDING * (np.abs(P) @ np.abs(Q))
    eps = _upper(residual.sum(axis=2).max(axis=1))
    eps = np.where(eps < 0.5, eps, np.nan)  # no usable inverse: the flow fails
    return _upper(base + (eps / (1 - eps) * (1 + ROUNDING))[:, None]
                  * base.max(axis=1, keepdims=True))


def _initial_set(d_low: np.ndarray, d_high: np.ndarray):
    """The start {(0, 0, 0, 0, D) : d_low <= D <= d_high} as centre + A r, |r| <= rho."""
    middle = 0.5 * (d_low + d_high)
    centre = np.zeros((len(d_low), STATES))
    centre[:, 4] = middle
    rho = np.zeros((len(d_low), STATES))
    rho[:, 4] = _upper(np.maximum(d_high - middle, middle - d_low))
    return centre, np.broadcast_to(np.eye(STATES), (len(d_low), STATES, STATES)).copy(), rho


def _record(kappa_low, kappa_high, y, c, D) -> np.ndarray:
    """Widen, in place, the kappa = c / D hull of every lambda = y / D cell the intervals
    meet (rows: flows); returns where lambda left [LAMBDA_LOW, LAMBDA_HIGH]."""
    lam = iv.div(y, D)
    kappa = iv.div(c, D)
    unbounded = ~np.isfinite(lam[0] + lam[1] + kappa[0] + kappa[1])
    kappa = (np.where(unbounded, np.inf, kappa[0]), np.where(unbounded, -np.inf, kappa[1]))
    first = np.floor((lam[0] - LAMBDA_LOW) * CELLS_PER_UNIT - 1e-6)
    last = np.floor((lam[1] - LAMBDA_LOW) * CELLS_PER_UNIT + 1e-6)
    escaped = unbounded | (first < 0) | (last >= CELLS)  # an unbounded flow has failed
    first, last = np.where(unbounded, 0, first), np.where(unbounded, -1, last)
    cells = np.arange(CELLS)
    met = (cells >= first[:, None]) & (cells <= last[:, None])
    np.minimum(kappa_low, np.where(met, kappa[0][:, None], np.inf), out=kappa_low)
    np.maximum(kappa_high, np.where(met, kappa[1][:, None], -np.inf), out=kappa_high)
    return escaped


def reference_path(design: VirtualReferenceIdaPbc, gains: LineGains, D: float, T: float,
                   until: float, dt: float = 1e-4) -> tuple[np.ndarray, np.ndarray]:
    """(lambda, kappa) along the move from a numpy re-derivation in the original coordinates
    (x, v, y, w), fourth-order Runge-Kutta at ``dt``: what the flow's cells must hold."""
    m, k, r_d = gains.mass, gains.k, gains.r_d
    accel = design.boost * 5.77 * D / T**2
    force, delta = 2 * m * accel, design.delta

    def rates(state):
        x, v, y, w = state
        r = abs(x)
        profile = min(r / delta, 1.0, max(design.start_share, design.start_share
                                          + (D - r) / (design.ramp * D)))
        pull = np.sign(x) * force * profile
        damping = (abs(pull) / np.sqrt(2 * design.brake * accel * r + 1e-12)
                   + 2 * np.sqrt(2 * m * force / delta) * delta**2 / (delta**2 + x**2))
        c = k * (y - x) + r_d * (w - v)
        return np.array([v, (c - pull - damping * v) / m, w, -c / m])

    state, path = np.array([D, 0.0, D, 0.0]), []
    for _ in range(int(until / dt)):
        path.append((state[2] / D, (k * (state[2] - state[0]) + r_d * (state[3] - state[1])) / D))
        k1 = rates(state)
        k2 = rates(state + 0.5 * dt * k1)
        k3 = rates(state + 0.5 * dt * k2)
        k4 = rates(state + dt * k3)
        state = state + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    path = np.array(path)
    return path[:, 0], path[:, 1]


def main() -> None:
    """The flows the module docstring reports: start distances of aras3's range, each as a
    point and as intervals of 0.1 mm and 0.5 mm, with a duration the plan picks for it; the
    point flows' cells checked against :func:`reference_path`."""
    import time

    design = VirtualReferenceIdaPbc()
    gains = LineGains(4.0, 1200.0, 100.0, design)
    flow = LineFlow(gains, step=5e-4)
    starts = np.array([0.1, 0.3, 0.5, 1.0, 1.5])
    durations = np.array([1.0, 1.5, 1.75, 2.0, 2.5])
    for width in (0.0, 1e-4, 5e-4):
        began = time.perf_counter()
        trace: dict = {}
        tubes = flow.run(starts, starts + width, durations, trace if width == 0.0 else None)
        print(f"D intervals of {1e3 * width:.1f} mm ({time.perf_counter() - began:.0f} s):")
        for k, start in enumerate(starts):
            state = (f"storage bound from {tubes.seconds[k]:.2f} s" if tubes.complete[k]
                     else f"gave up at {-tubes.seconds[k]:.2f} s, the particle "
                          f"{100 * tubes.left[k]:.1f} cm from the goal")
            print(f"  D = {start:.1f} m, T = {durations[k]} s: {state}; widest enclosure of "
                  f"the coupling over a step before {tubes.widest[k]:.3f} N")
            if width == 0.0:  # up to where the flow gave up, or 2 s into the storage bound
                covered = tubes.seconds[k] + 2.0 if tubes.complete[k] else -tubes.seconds[k]
                lam, kappa = reference_path(design, gains, start, durations[k],
                                            covered - flow.h)
                cell = np.floor((lam - LAMBDA_LOW) * CELLS_PER_UNIT).astype(int)
                outside = np.sum((kappa < tubes.kappa_low[k][cell])
                                 | (kappa > tubes.kappa_high[k][cell]))
                # the steps' own enclosures of c, at the reference's matching instants
                times, low, high = (np.array(column) for column in zip(*trace[k], strict=True))
                index = np.rint(times / 1e-4).astype(int)
                kept = index < len(kappa)
                coupling = kappa[index[kept]] * start
                missed = np.sum((coupling < low[kept]) | (coupling > high[kept]))
                print(f"    numpy re-derivation: {outside} of {len(lam):,} instants outside "
                      f"their cell's enclosure, {missed} of {int(kept.sum()):,} steps' "
                      f"enclosures of c missing it")

if __name__ == "__main__":
    main()
