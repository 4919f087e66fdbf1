/* FMI 2.0 API around a test model (see shell.h). Enumerations are Integer (I32). */
#include "shell.h"
#include MODEL_SOURCE
#include <stdlib.h>
#include <stdarg.h>
#include "fmi2Functions.h"

enum { M_INSTANTIATED, M_INIT, M_EVENT, M_CONT, M_STEP, M_TERMINATED };
#define N_VARS (sizeof(VARS) / sizeof(VARS[0]))

typedef struct {
  Model m;
  double time;
  int mode, cs, next_def, terminated;
  double next_t;
  char name[64];
  fmi2CallbackFunctions cb;
} Inst;

static void logf_(Inst* s, fmi2Status st, const char* fmt, ...) {
  char buf[512];
  va_list ap; va_start(ap, fmt); vsnprintf(buf, sizeof buf, fmt, ap); va_end(ap);
  if (s->cb.logger) s->cb.logger(s->cb.componentEnvironment, s->name, st, st >= fmi2Error ? "logStatusError" : "logEvents", "%s", buf);
}

static const VarDef* find(unsigned vr, VType type) {
  for (size_t i = 0; i < N_VARS; i++) if (VARS[i].vr == vr && VARS[i].type == type) return &VARS[i];
  return NULL;
}

static const char* mode_name(int mode) {
  static const char* n[] = {"Instantiated", "Initialization Mode", "Event Mode", "Continuous-Time Mode", "Step Mode", "Terminated"};
  return n[mode];
}

static fmi2Status check_set(Inst* s, const VarDef* v) {
  int ok;
  switch (v->caus) {
    case PAR_FIXED: ok = s->mode <= M_INIT; break;
    case PAR_TUNABLE: ok = s->mode <= M_EVENT || s->mode == M_STEP; break;
    case INPUT: ok = !v->discrete || s->mode <= M_EVENT || s->mode == M_STEP; break;
    default: ok = 0;
  }
  if (s->mode == M_TERMINATED) ok = 0;
  if (!ok) {
    if (v->caus == INPUT && v->discrete)
      logf_(s, fmi2Error, "variable %s can only be set in initialization mode or event mode (the FMU is in %s)",
            v->name, mode_name(s->mode));
    else
      logf_(s, fmi2Error, "variable %s cannot be set in %s", v->name, mode_name(s->mode));
    return fmi2Error;
  }
  return fmi2OK;
}

#define GETTER(Name, T, CT, EXPR) \
fmi2Status fmi2Get##Name(fmi2Component c, const fmi2ValueReference vr[], size_t n, CT value[]) { \
  Inst* s = (Inst*)c; m_update(&s->m, s->time); \
  for (size_t i = 0; i < n; i++) { \
    const VarDef* v = find(vr[i], T); \
    if (!v || v->n != 1) { logf_(s, fmi2Error, "value reference %u is not a scalar of this type", vr[i]); return fmi2Error; } \
    char* src = (char*)&s->m + v->offset; value[i] = EXPR; } \
  return fmi2OK; }
#define SETTER(Name, T, CT, STMT) \
fmi2Status fmi2Set##Name(fmi2Component c, const fmi2ValueReference vr[], size_t n, const CT value[]) { \
  Inst* s = (Inst*)c; \
  for (size_t i = 0; i < n; i++) { \
    const VarDef* v = find(vr[i], T); \
    if (!v || v->n != 1) { logf_(s, fmi2Error, "value reference %u is not a scalar of this type", vr[i]); return fmi2Error; } \
    if (check_set(s, v) != fmi2OK) return fmi2Error; \
    char* dst = (char*)&s->m + v->offset; STMT; } \
  return fmi2OK; }
GETTER(Real, F64, fmi2Real, *(double*)src)
GETTER(Integer, I32, fmi2Integer, *(int32_t*)src)
GETTER(Boolean, BOOL, fmi2Boolean, *(int*)src != 0)
GETTER(String, STR, fmi2String, (const char*)src)
SETTER(Real, F64, fmi2Real, *(double*)dst = value[i])
SETTER(Integer, I32, fmi2Integer, *(int32_t*)dst = value[i])
SETTER(Boolean, BOOL, fmi2Boolean, *(int*)dst = value[i] != 0)
SETTER(String, STR, fmi2String, strncpy(dst, value[i], sizeof(StrVal) - 1); dst[sizeof(StrVal) - 1] = 0)

const char* fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char* fmi2GetVersion(void) { return fmi2Version; }
fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String cat[]) { return fmi2OK; }

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String res,
                              const fmi2CallbackFunctions* f, fmi2Boolean visible, fmi2Boolean logging) {
#ifdef NO_CS
  if (type == fmi2CoSimulation) return NULL;
#endif
  Inst* s = (Inst*)calloc(1, sizeof(Inst));
  if (!s) return NULL;
  strncpy(s->name, name ? name : "", sizeof s->name - 1);
  if (f) s->cb = *f;
  s->cs = type == fmi2CoSimulation;
  s->mode = M_INSTANTIATED;
  m_start(&s->m);
  return s;
}
void fmi2FreeInstance(fmi2Component c) { free(c); }
fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean a, fmi2Real tol, fmi2Real t0, fmi2Boolean b, fmi2Real t1) {
  ((Inst*)c)->time = t0; return fmi2OK;
}
fmi2Status fmi2EnterInitializationMode(fmi2Component c) { ((Inst*)c)->mode = M_INIT; return fmi2OK; }
fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
  Inst* s = (Inst*)c;
  if (m_check(&s->m)) { logf_(s, fmi2Error, "%s", m_message); return fmi2Error; }
  m_init(&s->m, s->time, &s->next_def, &s->next_t);
  s->mode = s->cs ? M_STEP : M_EVENT;
  return fmi2OK;
}
fmi2Status fmi2Terminate(fmi2Component c) { ((Inst*)c)->mode = M_TERMINATED; return fmi2OK; }
fmi2Status fmi2Reset(fmi2Component c) { Inst* s = (Inst*)c; m_start(&s->m); s->mode = M_INSTANTIATED; s->time = 0; s->terminated = 0; return fmi2OK; }

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate* st) {
  Inst* copy = (Inst*)malloc(sizeof(Inst));
  if (!copy) return fmi2Error;
  memcpy(copy, c, sizeof(Inst));
  if (*st) free(*st);
  *st = copy;
  return fmi2OK;
}
fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate st) { memcpy(c, st, sizeof(Inst)); return fmi2OK; }
fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate* st) { free(*st); *st = NULL; return fmi2OK; }
fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate s, size_t* n) { return fmi2Error; }
fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate s, fmi2Byte b[], size_t n) { return fmi2Error; }
fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte b[], size_t n, fmi2FMUstate* s) { return fmi2Error; }
fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference a[], size_t na,
                                        const fmi2ValueReference b[], size_t nb, const fmi2Real dv[], fmi2Real out[]) { return fmi2Error; }

fmi2Status fmi2EnterEventMode(fmi2Component c) { ((Inst*)c)->mode = M_EVENT; return fmi2OK; }
fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo* info) {
  Inst* s = (Inst*)c;
  if (s->mode != M_EVENT) { logf_(s, fmi2Error, "fmi2NewDiscreteStates outside event mode"); return fmi2Error; }
  info->valuesOfContinuousStatesChanged = m_event(&s->m, s->time, &s->next_def, &s->next_t) ? fmi2True : fmi2False;
  info->newDiscreteStatesNeeded = fmi2False; info->terminateSimulation = m_terminate(&s->m) ? fmi2True : fmi2False;
  info->nominalsOfContinuousStatesChanged = fmi2False;
  info->nextEventTimeDefined = s->next_def ? fmi2True : fmi2False; info->nextEventTime = s->next_t;
  return fmi2OK;
}
fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c) { ((Inst*)c)->mode = M_CONT; return fmi2OK; }
fmi2Status fmi2CompletedIntegratorStep(fmi2Component c, fmi2Boolean noSet, fmi2Boolean* enter, fmi2Boolean* term) {
  *enter = fmi2False; *term = fmi2False; return fmi2OK;
}
fmi2Status fmi2SetTime(fmi2Component c, fmi2Real t) { ((Inst*)c)->time = t; return fmi2OK; }
fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t n) {
  if (n != N_STATES) return fmi2Error; m_set_x(&((Inst*)c)->m, x); return fmi2OK;
}
fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real dx[], size_t n) {
  Inst* s = (Inst*)c; if (n != N_STATES) return fmi2Error;
  m_update(&s->m, s->time); m_der(&s->m, s->time, dx); return fmi2OK;
}
fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real z[], size_t n) {
  Inst* s = (Inst*)c;
  if (n != N_INDICATORS) return fmi2Error;
  m_update(&s->m, s->time); m_ind(&s->m, s->time, z); return fmi2OK;
}
fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t n) {
  if (n != N_STATES) return fmi2Error; m_get_x(&((Inst*)c)->m, x); return fmi2OK;
}
fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real x[], size_t n) {
  for (size_t k = 0; k < n; k++) x[k] = 1.0; return fmi2OK;
}

static void rk4(Inst* s, double t, double h) {
#if N_STATES > 0
  double x[N_STATES], k1[N_STATES], k2[N_STATES], k3[N_STATES], k4[N_STATES], y[N_STATES];
  m_get_x(&s->m, x);
  #define EVAL(K, tt, base, f) for (int j = 0; j < N_STATES; j++) y[j] = x[j] + (f) * base[j]; m_set_x(&s->m, y); m_update(&s->m, tt); m_der(&s->m, tt, K);
  m_update(&s->m, t); m_der(&s->m, t, k1);
  EVAL(k2, t + h / 2, k1, h / 2) EVAL(k3, t + h / 2, k2, h / 2) EVAL(k4, t + h, k3, h)
  for (int j = 0; j < N_STATES; j++) y[j] = x[j] + h / 6 * (k1[j] + 2 * k2[j] + 2 * k3[j] + k4[j]);
  m_set_x(&s->m, y);
#endif
}

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                       const fmi2Integer order[], const fmi2Real v[]) { return fmi2Error; }
fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                        const fmi2Integer order[], fmi2Real v[]) { return fmi2Error; }
fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean noSetPrior) {
  Inst* s = (Inst*)c;
  double t_end = t + h, eps = 1e-12 * (1 + fabs(t_end));
  s->time = t;
  while (s->time < t_end - eps) {
    double stop = t_end;
    if (s->next_def && s->next_t < stop && s->next_t > s->time + eps) stop = s->next_t;
    int n = (int)ceil((stop - s->time) / CS_SUBSTEP_S);
    if (n < 1) n = 1;
    double dt = (stop - s->time) / n, t0 = s->time;
    for (int k = 0; k < n; k++) rk4(s, t0 + k * dt, dt);
    s->time = stop;
    if (s->next_def && fabs(s->time - s->next_t) <= eps) m_event(&s->m, s->time, &s->next_def, &s->next_t);
    /* the model is done: stop here and say so the FMI 2.0 way (fmi2Discard + fmi2Terminated) */
    if (m_terminate(&s->m)) { s->terminated = 1; return fmi2Discard; }
  }
  s->time = t_end;
  return fmi2OK;
}
fmi2Status fmi2CancelStep(fmi2Component c) { return fmi2Error; }
fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind k, fmi2Status* v) { return fmi2Error; }
fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind k, fmi2Real* v) {
  if (k != fmi2LastSuccessfulTime) return fmi2Error;
  *v = ((Inst*)c)->time; return fmi2OK;
}
fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind k, fmi2Integer* v) { return fmi2Error; }
fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind k, fmi2Boolean* v) {
  if (k != fmi2Terminated) return fmi2Error;
  *v = ((Inst*)c)->terminated ? fmi2True : fmi2False; return fmi2OK;
}
fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind k, fmi2String* v) { return fmi2Error; }
