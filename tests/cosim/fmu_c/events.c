/* Time events and a discrete input: counter += 1 at t = k * period (k = 1, 2, ...), odd = counter
 * is odd, x' = level (level: discrete Float64 input). period <= 0 is refused with a log line; the FMU asks to terminate once counter reaches
 * max_count (if > 0). */
#include "vars.h"
#define N_INDICATORS 0
#define N_STATES 1
#define CS_SUBSTEP_S 1e-3

static int m_check(Model* m) {
  if (!(m->period > 0)) {
    snprintf(m_message, sizeof m_message, "parameter period must be > 0 s (got %g)", m->period);
    return 1;
  }
  return 0;
}
static void m_init(Model* m, double t, int* next_def, double* next_t) {
  *next_def = 1;
  *next_t = (m->counter + 1) * m->period;
}
static void m_update(Model* m, double t) { m->odd = m->counter % 2 != 0; m->der_x_ = m->level; }
static void m_der(Model* m, double t, double dx[]) { dx[0] = m->level; }
static void m_get_x(Model* m, double x[]) { x[0] = m->x; }
static void m_set_x(Model* m, const double x[]) { m->x = x[0]; }
static int m_event(Model* m, double t, int* next_def, double* next_t) {
  double due = (m->counter + 1) * m->period;
  if (t >= due - 1e-9 * m->period) m->counter += 1;
  *next_def = 1;
  *next_t = (m->counter + 1) * m->period;
  return 0;
}
static int m_terminate(Model* m) { return m->max_count > 0 && m->counter >= m->max_count; }
static void m_ind(Model* m, double t, double z[]) {}
