/* featherstar FMI 3.0 shell: Co-Simulation by an embedded Dormand-Prince 5(4) integrator.
 *
 * Why this method: the exported models are small explicit ODEs whose right-hand side costs
 * well under a microsecond, and a co-simulation master calls fmi3DoStep at a fixed, short
 * communication step with the inputs held constant. An explicit Runge-Kutta pair needs no
 * Jacobian and no linear solve, and its embedded 4th-order solution gives the error estimate
 * for free; FSAL reuses the last stage as the next first stage (6 evaluations per step).
 * The PI step controller (Gustafsson; beta = 0.04 as in Hairer's DOPRI5) damps the step-size
 * oscillation that a plain controller shows when a stiff mode pins the step at the stability
 * limit, so a stiff model stays stable at the cost of ~|lambda| * step / 3 internal steps;
 * MAX_STEPS bounds that cost instead of letting a very stiff or runaway model hang the master.
 * The internal step is carried over between doStep calls so that short communication steps do
 * not restart step selection each time; steps are shortened to land exactly on the
 * communication point, which is simpler and as accurate as dense output here.
 * A non-finite trial stage is treated as a rejected step (a too-long step can leave the
 * model's domain, e.g. sqrt of a negative state); if it persists until the step size
 * underflows, or the derivative at an accepted state is non-finite, doStep fails.
 */
#include <float.h>
#include <math.h>

#include "fmi3Functions.h"
#include "fmi3_shell.h"

#define MAX_STEPS 500000L
#define SAFETY 0.9
#define BETA 0.04
#define EXPO1 (0.2 - 0.75 * BETA)
#define FAC_MIN 0.2  /* largest shrink per step */
#define FAC_MAX 10.0 /* largest growth per step */

static const double A21 = 1.0 / 5;
static const double A31 = 3.0 / 40, A32 = 9.0 / 40;
static const double A41 = 44.0 / 45, A42 = -56.0 / 15, A43 = 32.0 / 9;
static const double A51 = 19372.0 / 6561, A52 = -25360.0 / 2187, A53 = 64448.0 / 6561,
                    A54 = -212.0 / 729;
static const double A61 = 9017.0 / 3168, A62 = -355.0 / 33, A63 = 46732.0 / 5247,
                    A64 = 49.0 / 176, A65 = -5103.0 / 18656;
static const double A71 = 35.0 / 384, A73 = 500.0 / 1113, A74 = 125.0 / 192,
                    A75 = -2187.0 / 6784, A76 = 11.0 / 84;
static const double E1 = 71.0 / 57600, E3 = -71.0 / 16695, E4 = 71.0 / 1920,
                    E5 = -17253.0 / 339200, E6 = 22.0 / 525, E7 = -1.0 / 40;
static const double C2 = 0.2, C3 = 0.3, C4 = 0.8, C5 = 8.0 / 9;

typedef struct {
  fs_instance* s;
  size_t n;
  double *k1, *k2, *k3, *k4, *k5, *k6, *k7, *y, *y_new, *x;
} stepper;

static int all_finite(const double* v, size_t n) {
  size_t i;
  for (i = 0; i < n; ++i)
    if (!isfinite(v[i])) return 0;
  return 1;
}

/* RMS of the error weighted by atol + rtol * |x|: <= 1 means the step meets the tolerance. */
static double error_norm(const stepper* st, const double* err_a, const double* err_b) {
  double sum = 0.0;
  size_t i;
  for (i = 0; i < st->n; ++i) {
    double scale = st->s->dyn.atol +
                   st->s->dyn.rtol * fmax(fabs(st->x[i]), fabs(err_b ? err_b[i] : st->x[i]));
    double e = err_a[i] / scale;
    sum += e * e;
  }
  return st->n ? sqrt(sum / st->n) : 0.0;
}

/* Hairer's starting step: an explicit Euler probe estimates the second derivative. */
static double initial_step(stepper* st, double t, double h_max) {
  double d0 = error_norm(st, st->x, NULL), d1 = error_norm(st, st->k1, NULL), d2, h0, h1;
  size_t i;
  h0 = (d0 < 1e-5 || d1 < 1e-5) ? 1e-6 : 0.01 * d0 / d1;
  h0 = fmin(h0, h_max);
  for (i = 0; i < st->n; ++i) st->y[i] = st->x[i] + h0 * st->k1[i];
  if (st->s->model->rhs(st->s->memory, t + h0, st->y, st->k2) || !all_finite(st->k2, st->n))
    return h0;
  for (i = 0; i < st->n; ++i) st->k3[i] = st->k2[i] - st->k1[i];
  d2 = error_norm(st, st->k3, NULL) / h0;
  h1 = fmax(d1, d2) <= 1e-15 ? fmax(1e-6, h0 * 1e-3) : pow(0.01 / fmax(d1, d2), 0.2);
  return fmin(fmin(100 * h0, h1), h_max);
}

/* One trial step of size h from (t, x): y_new, k7 = f(t + h, y_new); returns the error norm,
 * or a negative value when a stage is not finite, or -2 when the model evaluation fails. */
static double trial_step(stepper* st, double t, double h) {
  const fs_model* m = st->s->model;
  void* mem = st->s->memory;
  size_t i, n = st->n;
  double *x = st->x, *y = st->y;
  for (i = 0; i < n; ++i) y[i] = x[i] + h * A21 * st->k1[i];
  if (m->rhs(mem, t + C2 * h, y, st->k2)) return -2;
  for (i = 0; i < n; ++i) y[i] = x[i] + h * (A31 * st->k1[i] + A32 * st->k2[i]);
  if (m->rhs(mem, t + C3 * h, y, st->k3)) return -2;
  for (i = 0; i < n; ++i) y[i] = x[i] + h * (A41 * st->k1[i] + A42 * st->k2[i] + A43 * st->k3[i]);
  if (m->rhs(mem, t + C4 * h, y, st->k4)) return -2;
  for (i = 0; i < n; ++i)
    y[i] = x[i] + h * (A51 * st->k1[i] + A52 * st->k2[i] + A53 * st->k3[i] + A54 * st->k4[i]);
  if (m->rhs(mem, t + C5 * h, y, st->k5)) return -2;
  for (i = 0; i < n; ++i)
    y[i] = x[i] + h * (A61 * st->k1[i] + A62 * st->k2[i] + A63 * st->k3[i] + A64 * st->k4[i] +
                       A65 * st->k5[i]);
  if (m->rhs(mem, t + h, y, st->k6)) return -2;
  for (i = 0; i < n; ++i)
    st->y_new[i] = x[i] + h * (A71 * st->k1[i] + A73 * st->k3[i] + A74 * st->k4[i] +
                               A75 * st->k5[i] + A76 * st->k6[i]);
  if (m->rhs(mem, t + h, st->y_new, st->k7)) return -2;
  if (!all_finite(st->y_new, n) || !all_finite(st->k7, n) || !all_finite(st->k2, n) ||
      !all_finite(st->k3, n) || !all_finite(st->k4, n) || !all_finite(st->k5, n) ||
      !all_finite(st->k6, n))
    return -1;
  for (i = 0; i < n; ++i)
    y[i] = h * (E1 * st->k1[i] + E3 * st->k3[i] + E4 * st->k4[i] + E5 * st->k5[i] +
                E6 * st->k6[i] + E7 * st->k7[i]);
  return error_norm(st, y, st->y_new);
}

/* Integrates from s->dyn.time to t_end; on failure returns the cause, t and x at the last
 * accepted point are left in the instance. */
static const char* integrate(fs_instance* s, double t_end) {
  stepper st;
  double t = s->dyn.time, h = s->dyn.h, err;
  long steps = 0;
  int rejected = 0;
  size_t i;
  const char* cause = NULL;
  st.s = s;
  st.n = s->model->n_x;
  st.k1 = s->work;
  st.k2 = st.k1 + st.n, st.k3 = st.k2 + st.n, st.k4 = st.k3 + st.n, st.k5 = st.k4 + st.n;
  st.k6 = st.k5 + st.n, st.k7 = st.k6 + st.n, st.y = st.k7 + st.n, st.y_new = st.y + st.n;
  st.x = st.y_new + st.n;
  s->model->get_states(s->memory, st.x);
  if (st.n == 0) t = t_end;
  if (t < t_end && !s->dyn.fsal_valid) {
    if (s->model->rhs(s->memory, t, st.x, st.k1)) return "model evaluation failed";
    s->dyn.fsal_valid = 1;
  }
  if (t < t_end && !all_finite(st.k1, st.n)) {
    s->dyn.fsal_valid = 0;
    return "state derivative is not finite";
  }
  if (t < t_end && h <= 0) h = initial_step(&st, t, t_end - t);
  while (t < t_end) {
    double remaining = t_end - t, h_min = 16 * DBL_EPSILON * fmax(fabs(t), 1e-3), hs;
    int last;
    /* What rounding leaves of the interval is below what the state could resolve. */
    if (remaining <= h_min) break;
    if (++steps > MAX_STEPS) {
      cause = "too many internal steps (stiff model? use a shorter communication step)";
      break;
    }
    if (h < h_min) {
      cause = rejected ? "step size underflow (state derivative not finite near here?)"
                       : "step size underflow";
      break;
    }
    last = h >= remaining;
    hs = last ? remaining : h;
    err = trial_step(&st, t, hs);
    if (err == -2) {
      cause = "model evaluation failed";
      break;
    }
    if (err < 0 || err > 1) {
      h = hs * (err < 0 ? 0.25 : fmax(FAC_MIN, SAFETY * pow(err, -0.2)));
      rejected = 1;
      continue;
    }
    double fac = fmin(1.0 / FAC_MIN, fmax(1.0 / FAC_MAX, pow(err, EXPO1) /
                                                             pow(s->dyn.err_old, BETA) / SAFETY));
    double h_new = hs / fac;
    if (rejected) h_new = fmin(h_new, hs);
    /* A step shortened to hit t_end says nothing about a longer one: only let it shrink h. */
    h = last ? fmin(h, h_new) : h_new;
    s->dyn.err_old = fmax(err, 1e-4);
    rejected = 0;
    t = last ? t_end : t + hs;
    for (i = 0; i < st.n; ++i) {
      st.x[i] = st.y_new[i];
      st.k1[i] = st.k7[i];
    }
  }
  s->dyn.h = h;
  s->dyn.time = cause ? t : t_end;
  s->model->set_states(s->memory, s->dyn.time, st.x);
  return cause;
}

FMI3_Export fmi3Status fmi3EnterStepMode(fmi3Instance instance) {
  fs_instance* s = fs_check(instance, "fmi3EnterStepMode", FS_EVENT, FS_CO_SIMULATION);
  if (!s) return fmi3Error;
  s->dyn.mode = FS_STEP;
  return fmi3OK;
}

FMI3_Export fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                                  fmi3Float64 communicationStepSize,
                                  fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                  fmi3Boolean* eventHandlingNeeded, fmi3Boolean* terminateSimulation,
                                  fmi3Boolean* earlyReturn, fmi3Float64* lastSuccessfulTime) {
  fs_instance* s = fs_check(instance, "fmi3DoStep", FS_STEP, FS_CO_SIMULATION);
  const char* cause;
  char why[256];
  (void)noSetFMUStatePriorToCurrentPoint;
  if (!s) return fmi3Error;
  if (eventHandlingNeeded) *eventHandlingNeeded = fmi3False;
  if (terminateSimulation) *terminateSimulation = fmi3False;
  if (earlyReturn) *earlyReturn = fmi3False;
  if (lastSuccessfulTime) *lastSuccessfulTime = s->dyn.time;
  if (!isfinite(communicationStepSize) || communicationStepSize < 0 ||
      !isfinite(currentCommunicationPoint)) {
    fs_error(s, "fmi3DoStep: invalid communication point %g or step size %g",
             currentCommunicationPoint, communicationStepSize);
    return fmi3Error;
  }
  /* Importers accumulate time in their own way; only a real mismatch is an error. */
  if (fabs(currentCommunicationPoint - s->dyn.time) >
      1e-9 * fmax(1.0, fmax(fabs(s->dyn.time), communicationStepSize))) {
    fs_error(s, "fmi3DoStep: currentCommunicationPoint %.17g differs from the FMU time %.17g",
             currentCommunicationPoint, s->dyn.time);
    return fmi3Error;
  }
  s->dyn.time = currentCommunicationPoint;
  cause = integrate(s, currentCommunicationPoint + communicationStepSize);
  if (!cause) cause = fs_outputs_problem(s, why, sizeof why);
  if (lastSuccessfulTime) *lastSuccessfulTime = s->dyn.time;
  if (cause) {
    s->dyn.mode = FS_FAILED;
    fs_error(s, "doStep failed at t=%.10g : %s", s->dyn.time, cause);
    return fmi3Error;
  }
  return fmi3OK;
}
