/* Van der Pol oscillator (Model Exchange only): x0' = x1, x1' = mu (1 - x0^2) x1 - x0. */
#include "vars.h"
#define N_INDICATORS 0
#define N_STATES 2
#define CS_SUBSTEP_S 1e-3

static int m_check(Model* m) { return 0; }
static void m_init(Model* m, double t, int* next_def, double* next_t) { *next_def = 0; }
static void m_update(Model* m, double t) {
  m->der_x0_ = m->x1;
  m->der_x1_ = m->mu * (1 - m->x0 * m->x0) * m->x1 - m->x0;
}
static void m_der(Model* m, double t, double dx[]) { dx[0] = m->der_x0_; dx[1] = m->der_x1_; }
static void m_get_x(Model* m, double x[]) { x[0] = m->x0; x[1] = m->x1; }
static void m_set_x(Model* m, const double x[]) { m->x0 = x[0]; m->x1 = x[1]; }
static int m_event(Model* m, double t, int* next_def, double* next_t) { *next_def = 0; return 0; }
static int m_terminate(Model* m) { return 0; }
static void m_ind(Model* m, double t, double z[]) {}
