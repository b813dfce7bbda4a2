/* The floor: cdpr_sym's closed loop of a 3-DOF point mass on 3 cables, written by hand.

   Per control period: the law at the sample (q, dq), the tension held over one classic RK4
   step of dt (W re-evaluated at each stage), then the stop checks (singular, non-finite,
   left the frame); a stop freezes the state and ends the run.

   W's columns are the unit vectors u_i = (a_i - q) / |a_i - q| towards the anchors, so
   det W = u_0 . (u_1 x u_2) and W^{-1} has the rows c_0 = u_1 x u_2, c_1 = u_2 x u_0,
   c_2 = u_0 x u_1 divided by det W. Vectors are small structs passed by value, which gcc
   -O2 keeps in registers once the helpers are inlined.

   Units: m, s, kg, N. Arrays (row-major, doubles):
     robot  = [anchors (3 x 3, row i = anchor i), mass, gravity, t_min, t_max,
               lower (3), upper (3)]
     par    = [q_goal (3), k (3), r_d (3), dt]
     states = (n_steps + 1) x 7: q, dq, status; row 0 holds the start on entry
     logs   = n_steps x 9: tau (3), alpha, beta, j (3), flags */
#include <math.h>
#include <string.h>

#define SINGULAR_DET 1e-6
#define LOW_SPEED 1e-6
#define BIG 1e300
enum { FLAG_LOW_SPEED = 1, FLAG_BETA = 2, FLAG_SATURATED = 4, FLAG_ALPHA = 8,
       FLAG_SINGULAR = 16 };
enum { CONTROLLER_PD = 0, CONTROLLER_L2 = 1 };
enum { N_X = 7, N_LOG = 9 };

typedef struct { double x, y, z; } Vec3;
typedef struct { Vec3 u0, u1, u2; } Columns; /* the columns of W */

typedef struct {
  Vec3 anchors[3];
  double mass, gravity, t_min, t_max;
  Vec3 lower, upper;
} Robot;

typedef struct {
  Vec3 goal, k, r_d;
  double dt;
} Params;

/* fmax(x, bound) and fmin(x, bound) for a number bound (gcc -O2 calls libm for those) */
static inline double at_least(double x, double bound) { return x > bound ? x : bound; }
static inline double at_most(double x, double bound) { return x < bound ? x : bound; }
static inline Vec3 vec3(double x, double y, double z) { Vec3 v = {x, y, z}; return v; }
static inline Vec3 load(const double *p) { return vec3(p[0], p[1], p[2]); }
static inline double dot(Vec3 a, Vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
static inline Vec3 cross(Vec3 a, Vec3 b) {
  return vec3(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}
/* x + h dx */
static inline Vec3 ahead(Vec3 x, double h, Vec3 dx) {
  return vec3(x.x + h * dx.x, x.y + h * dx.y, x.z + h * dx.z);
}
/* W w = w_0 u_0 + w_1 u_1 + w_2 u_2 */
static inline Vec3 combine(Columns w, Vec3 t) {
  return vec3(w.u0.x * t.x + w.u1.x * t.y + w.u2.x * t.z,
              w.u0.y * t.x + w.u1.y * t.y + w.u2.y * t.z,
              w.u0.z * t.x + w.u1.z * t.y + w.u2.z * t.z);
}

static inline Vec3 unit_towards(Vec3 anchor, Vec3 q) {
  Vec3 d = vec3(anchor.x - q.x, anchor.y - q.y, anchor.z - q.z);
  double inverse_length = 1.0 / sqrt(dot(d, d));
  return vec3(d.x * inverse_length, d.y * inverse_length, d.z * inverse_length);
}

static inline Columns columns(const Robot *robot, Vec3 q) {
  Columns w = {unit_towards(robot->anchors[0], q), unit_towards(robot->anchors[1], q),
               unit_towards(robot->anchors[2], q)};
  return w;
}

typedef struct { Vec3 tau; double det; } LawResult;

/* The law at (q, dq), w = W(q): tau (N) and det W(q); writes the log row. */
static inline LawResult control_law(int controller, const Robot *robot, const Params *par,
                                    Vec3 q, Vec3 dq, Columns w, double *log) {
  Vec3 c0 = cross(w.u1, w.u2), c1 = cross(w.u2, w.u0), c2 = cross(w.u0, w.u1);
  double det = dot(w.u0, c0), inverse_det = 1.0 / det;
  double weight = robot->mass * robot->gravity;
  double t_min = robot->t_min, t_max = robot->t_max, mid = 0.5 * (t_min + t_max);
  Vec3 f = vec3(par->k.x * (q.x - par->goal.x) + par->r_d.x * dq.x,
                par->k.y * (q.y - par->goal.y) + par->r_d.y * dq.y,
                par->k.z * (q.z - par->goal.z) + par->r_d.z * dq.z);  /* K e + R_d dq */
  Vec3 tau_1 = vec3(c0.z * weight * inverse_det, c1.z * weight * inverse_det,
                    c2.z * weight * inverse_det);  /* W^{-1} grad V, grad V = (0, 0, m g) */
  Vec3 tau_2 = vec3(-dot(c0, f) * inverse_det, -dot(c1, f) * inverse_det,
                    -dot(c2, f) * inverse_det);  /* -W^{-1} (K e + R_d dq) */
  Vec3 offset = vec3(tau_1.x - mid, tau_1.y - mid, tau_1.z - mid);
  double beta = 0.5 * (t_max - t_min) - sqrt(dot(offset, offset)), alpha = 1.0;
  Vec3 pd = vec3(tau_1.x + tau_2.x, tau_1.y + tau_2.y, tau_1.z + tau_2.z);
  Vec3 tau = pd, j = vec3(0.0, 0.0, 0.0);
  int flags = fabs(det) < SINGULAR_DET ? FLAG_SINGULAR : 0;
  if (controller == CONTROLLER_L2) {
    double speed = sqrt(dot(dq, dq)), scale = at_least(speed, LOW_SPEED);
    if (beta <= 0.0 || speed < LOW_SPEED) { /* fallback: PD clipped to the box */
      int clipped = pd.x < t_min || pd.x > t_max || pd.y < t_min || pd.y > t_max
                    || pd.z < t_min || pd.z > t_max;
      tau = vec3(at_most(at_least(pd.x, t_min), t_max), at_most(at_least(pd.y, t_min), t_max),
                 at_most(at_least(pd.z, t_min), t_max));
      flags |= (speed < LOW_SPEED ? FLAG_LOW_SPEED : 0) | (beta <= 0.0 ? FLAG_BETA : 0)
               | (clipped ? FLAG_SATURATED : 0);
    } else {
      /* v = W^T d spans the left null space of A = W^{-1} P(d): the least-squares
         tau_3 = A j is -tau_2 + v (v . tau_2) / |v|^2, its residual |v . tau_2| / |v| */
      Vec3 d = vec3(dq.x / scale, dq.y / scale, dq.z / scale);
      Vec3 v = vec3(dot(w.u0, d), dot(w.u1, d), dot(w.u2, d));
      double ratio = dot(v, tau_2) / dot(v, v);
      double residual = fabs(ratio) * sqrt(dot(v, v));
      alpha = residual < beta ? 1.0 : beta / at_least(residual, 1e-300);
      tau = ahead(tau_1, alpha * ratio, v);
      /* minimum-norm j = P(d)^T W tau_3 / |d|^2, with W tau_3 = K e + R_d dq + ratio W v */
      Vec3 y = ahead(f, ratio, combine(w, v));
      double gain = alpha / scale / dot(d, d);
      j = vec3((d.y * y.x - d.x * y.y) * gain, (d.z * y.x - d.x * y.z) * gain,
               (d.z * y.y - d.y * y.z) * gain);
      flags |= alpha < 1.0 ? FLAG_ALPHA : 0;
    }
  }
  log[0] = tau.x; log[1] = tau.y; log[2] = tau.z;
  log[3] = alpha; log[4] = beta;
  log[5] = j.x; log[6] = j.y; log[7] = j.z;
  log[8] = (double)flags;
  LawResult result = {tau, det};
  return result;
}

/* ddq of the plant with the tension tau held: M ddq = W(q) tau - grad V. */
static inline Vec3 acceleration(const Robot *robot, Vec3 q, Vec3 tau) {
  Vec3 force = combine(columns(robot, q), tau);
  double inverse_mass = 1.0 / robot->mass;
  return vec3(inverse_mass * force.x, inverse_mass * force.y,
              inverse_mass * (force.z - robot->mass * robot->gravity));
}

static inline Vec3 rk4_sum(Vec3 x, double h, Vec3 k1, Vec3 k2, Vec3 k3, Vec3 k4) {
  return vec3(x.x + h / 6.0 * (k1.x + 2.0 * k2.x + 2.0 * k3.x + k4.x),
              x.y + h / 6.0 * (k1.y + 2.0 * k2.y + 2.0 * k3.y + k4.y),
              x.z + h / 6.0 * (k1.z + 2.0 * k2.z + 2.0 * k3.z + k4.z));
}

static inline int finite3(Vec3 v) {
  return fabs(v.x) <= BIG && fabs(v.y) <= BIG && fabs(v.z) <= BIG;
}

static inline int outside(const Robot *robot, Vec3 q) {
  return q.x < robot->lower.x || q.y < robot->lower.y || q.z < robot->lower.z
         || q.x > robot->upper.x || q.y > robot->upper.y || q.z > robot->upper.z;
}

/* Runs up to n_steps control periods; returns the number taken (fewer after a stop, whose
   row holds the frozen state and the status: 1 singular, 2 non-finite, 3 left the frame). */
long long cdpr_run(int controller, const double *robot_data, const double *par_data,
                   double *states, double *logs, long long n_steps) {
  Robot robot;
  Params par;
  memcpy(&robot, robot_data, sizeof robot); /* 21 doubles, no padding */
  memcpy(&par, par_data, sizeof par);       /* 10 doubles */
  double h = par.dt;
  Columns w = columns(&robot, load(states)); /* W at the sample, carried from step to step */
  for (long long step = 0; step < n_steps; ++step) {
    const double *x = states + step * N_X;
    double *next = states + (step + 1) * N_X, *log = logs + step * N_LOG;
    Vec3 q = load(x), dq = load(x + 3);
    LawResult law = control_law(controller, &robot, &par, q, dq, w, log);
    Vec3 a1 = dq, b1 = acceleration(&robot, q, law.tau);
    Vec3 a2 = ahead(dq, 0.5 * h, b1), b2 = acceleration(&robot, ahead(q, 0.5 * h, a1), law.tau);
    Vec3 a3 = ahead(dq, 0.5 * h, b2), b3 = acceleration(&robot, ahead(q, 0.5 * h, a2), law.tau);
    Vec3 a4 = ahead(dq, h, b3), b4 = acceleration(&robot, ahead(q, h, a3), law.tau);
    Vec3 q_next = rk4_sum(q, h, a1, a2, a3, a4), dq_next = rk4_sum(dq, h, b1, b2, b3, b4);
    w = columns(&robot, q_next);
    int crossed = law.det * dot(w.u0, cross(w.u1, w.u2)) <= 0.0;
    int singular = ((int)log[8] & FLAG_SINGULAR) || crossed;
    int finite = finite3(q_next) && finite3(dq_next) && finite3(law.tau);
    int status = singular ? 1 : !finite ? 2 : outside(&robot, q_next) ? 3 : 0;
    if (status) {
      memcpy(next, x, 6 * sizeof(double));
    } else {
      next[0] = q_next.x; next[1] = q_next.y; next[2] = q_next.z;
      next[3] = dq_next.x; next[4] = dq_next.y; next[5] = dq_next.z;
    }
    next[6] = (double)status;
    if (status) return step + 1;
  }
  return n_steps;
}
