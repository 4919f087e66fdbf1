/* Bouncing ball (Model Exchange only): h' = v, v' = -g; a state event at h = 0 while falling
 * (event indicator z = h) sets v := -e v and counts bounces. */
#include "vars.h"
#define N_INDICATORS 1
#define N_STATES 2
#define CS_SUBSTEP_S 1e-3

static int m_check(Model* m) { return 0; }
static void m_init(Model* m, double t, int* next_def, double* next_t) { *next_def = 0; }
static void m_update(Model* m, double t) { m->der_h_ = m->v; m->der_v_ = -m->g; m->z = m->h; }
static void m_der(Model* m, double t, double dx[]) { dx[0] = m->v; dx[1] = -m->g; }
static void m_get_x(Model* m, double x[]) { x[0] = m->h; x[1] = m->v; }
static void m_set_x(Model* m, const double x[]) { m->h = x[0]; m->v = x[1]; }
static void m_ind(Model* m, double t, double z[]) { z[0] = m->h; }
static int m_event(Model* m, double t, int* next_def, double* next_t) {
  *next_def = 0;
  if (m->h <= 1e-9 && m->v < 0) {
    m->h = 0; m->v = -m->e * m->v; m->bounces += 1;
    return 1;
  }
  return 0;
}
static int m_terminate(Model* m) { return 0; }
