/* A binary that takes its process down on purpose (tests/cosim/crash_fmus.py): the Van der Pol
 * model of vdp.c with CRASH_AT = 1 (in instantiate) or 2 (at the end of initialization) and
 * CRASH_HOW = 1 (SIGSEGV: a write through NULL), 2 (abort(): SIGABRT), 3 (exit(3) from inside the
 * model), 4 (hangs). CRASH_AT = 0 is the healthy model. */
#include <stdlib.h>
#include <unistd.h>
#include "vars.h"
#define N_INDICATORS 0
#define N_STATES 2
#define CS_SUBSTEP_S 1e-3

/* NULL, but volatile and global: the compiler cannot prove the write undefined and drop it */
int* volatile crash_nowhere;

static void crash_now(void) {
#if CRASH_HOW == 1
  *crash_nowhere = 1;
#elif CRASH_HOW == 2
  abort();
#elif CRASH_HOW == 3
  exit(3);
#elif CRASH_HOW == 4
  for (;;) pause();
#endif
}
static void m_start_then_crash(Model* m) { m_start(m); if (CRASH_AT == 1) crash_now(); }
#define m_start m_start_then_crash

static int m_check(Model* m) { return 0; }
static void m_init(Model* m, double t, int* next_def, double* next_t) { *next_def = 0; if (CRASH_AT == 2) crash_now(); }
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
