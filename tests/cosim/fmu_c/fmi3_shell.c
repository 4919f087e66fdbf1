/* FMI 3.0 API around a test model (see shell.h). */
#include "shell.h"
#include MODEL_SOURCE
#include <stdlib.h>
#include <stdarg.h>
#include "fmi3Functions.h"

enum { M_INSTANTIATED, M_INIT, M_EVENT, M_CONT, M_STEP, M_TERMINATED };
#define N_VARS (sizeof(VARS) / sizeof(VARS[0]))

typedef struct {
  Model m;
  double time;
  int mode, cs, next_def;
  double next_t;
  char name[64];
  fmi3InstanceEnvironment env;
  fmi3LogMessageCallback log;
} Inst;

static void logf_(Inst* s, fmi3Status st, const char* fmt, ...) {
  char buf[512];
  va_list ap; va_start(ap, fmt); vsnprintf(buf, sizeof buf, fmt, ap); va_end(ap);
  if (s->log) s->log(s->env, st, st >= fmi3Error ? "logStatusError" : "logEvents", buf);
}

static const VarDef* find(unsigned vr) {
  for (size_t i = 0; i < N_VARS; i++) if (VARS[i].vr == vr) return &VARS[i];
  return NULL;
}

static const char* mode_name(int mode) {
  static const char* n[] = {"Instantiated", "Initialization Mode", "Event Mode", "Continuous-Time Mode", "Step Mode", "Terminated"};
  return n[mode];
}

static fmi3Status check_set(Inst* s, const VarDef* v) {
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
      logf_(s, fmi3Error, "variable %s can only be set in initialization mode or event mode (the FMU is in %s)",
            v->name, mode_name(s->mode));
    else
      logf_(s, fmi3Error, "variable %s cannot be set in %s", v->name, mode_name(s->mode));
    return fmi3Error;
  }
  return fmi3OK;
}

static size_t type_size(VType t) {
  switch (t) {
    case F64: case I64: case U64: return 8; case F32: case I32: case U32: return 4;
    case I16: case U16: return 2; case BOOL: return sizeof(int); case STR: return sizeof(StrVal);
    case BIN: return sizeof(BinVal); default: return 1;
  }
}

/* generic get/set: `ext` holds values of the FMI type (fmi3Boolean for BOOL, fmi3String for STR) */
static fmi3Status get_any(fmi3Instance inst, VType type, const fmi3ValueReference vr[], size_t nvr, void* ext, size_t* sizes) {
  Inst* s = (Inst*)inst;
  m_update(&s->m, s->time);
  size_t k = 0;
  for (size_t i = 0; i < nvr; i++) {
    const VarDef* v = find(vr[i]);
    if (!v || v->type != type) { logf_(s, fmi3Error, "value reference %u is not a variable of the requested type", vr[i]); return fmi3Error; }
    for (size_t j = 0; j < v->n; j++, k++) {
      char* src = (char*)&s->m + v->offset + j * type_size(type);
      if (type == BOOL) ((fmi3Boolean*)ext)[k] = *(int*)src != 0;
      else if (type == STR) ((fmi3String*)ext)[k] = (const char*)src;
      else if (type == BIN) { ((fmi3Binary*)ext)[k] = ((BinVal*)src)->d; sizes[k] = ((BinVal*)src)->n; }
      else memcpy((char*)ext + k * type_size(type), src, type_size(type));
    }
  }
  return fmi3OK;
}

static fmi3Status set_any(fmi3Instance inst, VType type, const fmi3ValueReference vr[], size_t nvr, const void* ext, const size_t* sizes) {
  Inst* s = (Inst*)inst;
  size_t k = 0;
  for (size_t i = 0; i < nvr; i++) {
    const VarDef* v = find(vr[i]);
    if (!v || v->type != type) { logf_(s, fmi3Error, "value reference %u is not a variable of the requested type", vr[i]); return fmi3Error; }
    if (check_set(s, v) != fmi3OK) return fmi3Error;
    for (size_t j = 0; j < v->n; j++, k++) {
      char* dst = (char*)&s->m + v->offset + j * type_size(type);
      if (type == BOOL) *(int*)dst = ((const fmi3Boolean*)ext)[k] ? 1 : 0;
      else if (type == STR) { strncpy(dst, ((const fmi3String*)ext)[k], sizeof(StrVal) - 1); dst[sizeof(StrVal) - 1] = 0; }
      else if (type == BIN) {
        BinVal* b = (BinVal*)dst; size_t n = sizes[k] < sizeof b->d ? sizes[k] : sizeof b->d;
        memcpy(b->d, ((const fmi3Binary*)ext)[k], n); b->n = n;
      } else memcpy(dst, (const char*)ext + k * type_size(type), type_size(type));
    }
  }
  return fmi3OK;
}

#define GETSET(Name, T, CT) \
  fmi3Status fmi3Get##Name(fmi3Instance i, const fmi3ValueReference vr[], size_t n, CT v[], size_t nv) { return get_any(i, T, vr, n, v, NULL); } \
  fmi3Status fmi3Set##Name(fmi3Instance i, const fmi3ValueReference vr[], size_t n, const CT v[], size_t nv) { return set_any(i, T, vr, n, v, NULL); }
GETSET(Float64, F64, fmi3Float64) GETSET(Float32, F32, fmi3Float32) GETSET(Int8, I8, fmi3Int8) GETSET(UInt8, U8, fmi3UInt8)
GETSET(Int16, I16, fmi3Int16) GETSET(UInt16, U16, fmi3UInt16) GETSET(Int32, I32, fmi3Int32) GETSET(UInt32, U32, fmi3UInt32)
GETSET(Int64, I64, fmi3Int64) GETSET(UInt64, U64, fmi3UInt64) GETSET(Boolean, BOOL, fmi3Boolean) GETSET(String, STR, fmi3String)
fmi3Status fmi3GetBinary(fmi3Instance i, const fmi3ValueReference vr[], size_t n, size_t sizes[], fmi3Binary v[], size_t nv) { return get_any(i, BIN, vr, n, v, sizes); }
fmi3Status fmi3SetBinary(fmi3Instance i, const fmi3ValueReference vr[], size_t n, const size_t sizes[], const fmi3Binary v[], size_t nv) { return set_any(i, BIN, vr, n, v, sizes); }
fmi3Status fmi3GetClock(fmi3Instance i, const fmi3ValueReference vr[], size_t n, fmi3Clock v[]) { return fmi3Error; }
fmi3Status fmi3SetClock(fmi3Instance i, const fmi3ValueReference vr[], size_t n, const fmi3Clock v[]) { return fmi3Error; }

const char* fmi3GetVersion(void) { return fmi3Version; }
fmi3Status fmi3SetDebugLogging(fmi3Instance i, fmi3Boolean on, size_t n, const fmi3String c[]) { return fmi3OK; }

static Inst* make(fmi3String name, fmi3InstanceEnvironment env, fmi3LogMessageCallback log, int cs) {
  Inst* s = (Inst*)calloc(1, sizeof(Inst));
  if (!s) return NULL;
  strncpy(s->name, name ? name : "", sizeof s->name - 1);
  s->env = env; s->log = log; s->cs = cs; s->mode = M_INSTANTIATED;
  m_start(&s->m);
  return s;
}
fmi3Instance fmi3InstantiateModelExchange(fmi3String name, fmi3String token, fmi3String res, fmi3Boolean vis, fmi3Boolean logging,
                                          fmi3InstanceEnvironment env, fmi3LogMessageCallback log) {
#ifdef NO_ME
  if (log) log(env, fmi3Error, "logStatusError", "this FMU has no Model Exchange interface");
  return NULL;
#else
  return make(name, env, log, 0);
#endif
}
fmi3Instance fmi3InstantiateCoSimulation(fmi3String name, fmi3String token, fmi3String res, fmi3Boolean vis, fmi3Boolean logging,
                                         fmi3Boolean eventModeUsed, fmi3Boolean early, const fmi3ValueReference req[], size_t nreq,
                                         fmi3InstanceEnvironment env, fmi3LogMessageCallback log, fmi3IntermediateUpdateCallback cb) {
#ifdef NO_CS
  return NULL;
#else
  return make(name, env, log, 1);
#endif
}
fmi3Instance fmi3InstantiateScheduledExecution(fmi3String name, fmi3String token, fmi3String res, fmi3Boolean vis, fmi3Boolean logging,
                                               fmi3InstanceEnvironment env, fmi3LogMessageCallback log, fmi3ClockUpdateCallback c,
                                               fmi3LockPreemptionCallback l, fmi3UnlockPreemptionCallback u) { return NULL; }
void fmi3FreeInstance(fmi3Instance i) { free(i); }

fmi3Status fmi3EnterInitializationMode(fmi3Instance i, fmi3Boolean tolDef, fmi3Float64 tol, fmi3Float64 t0, fmi3Boolean stopDef, fmi3Float64 t1) {
  Inst* s = (Inst*)i; s->time = t0; s->mode = M_INIT; return fmi3OK;
}
fmi3Status fmi3ExitInitializationMode(fmi3Instance i) {
  Inst* s = (Inst*)i;
  if (m_check(&s->m)) { logf_(s, fmi3Error, "%s", m_message); return fmi3Error; }
  m_init(&s->m, s->time, &s->next_def, &s->next_t);
  s->mode = s->cs ? M_STEP : M_EVENT;
  return fmi3OK;
}
fmi3Status fmi3EnterEventMode(fmi3Instance i) { ((Inst*)i)->mode = M_EVENT; return fmi3OK; }
fmi3Status fmi3Terminate(fmi3Instance i) { ((Inst*)i)->mode = M_TERMINATED; return fmi3OK; }
fmi3Status fmi3Reset(fmi3Instance i) { Inst* s = (Inst*)i; m_start(&s->m); s->mode = M_INSTANTIATED; s->time = 0; return fmi3OK; }

fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance i, fmi3ValueReference vr, size_t* n) { return fmi3Error; }
fmi3Status fmi3GetVariableDependencies(fmi3Instance i, fmi3ValueReference d, size_t a[], fmi3ValueReference b[], size_t c[], fmi3DependencyKind k[], size_t n) { return fmi3Error; }

fmi3Status fmi3GetFMUState(fmi3Instance i, fmi3FMUState* st) {
  Inst* copy = (Inst*)malloc(sizeof(Inst));
  if (!copy) return fmi3Error;
  memcpy(copy, i, sizeof(Inst));
  if (*st) free(*st);
  *st = copy;
  return fmi3OK;
}
fmi3Status fmi3SetFMUState(fmi3Instance i, fmi3FMUState st) { memcpy(i, st, sizeof(Inst)); return fmi3OK; }
fmi3Status fmi3FreeFMUState(fmi3Instance i, fmi3FMUState* st) { free(*st); *st = NULL; return fmi3OK; }
fmi3Status fmi3SerializedFMUStateSize(fmi3Instance i, fmi3FMUState st, size_t* n) { return fmi3Error; }
fmi3Status fmi3SerializeFMUState(fmi3Instance i, fmi3FMUState st, fmi3Byte b[], size_t n) { return fmi3Error; }
fmi3Status fmi3DeserializeFMUState(fmi3Instance i, const fmi3Byte b[], size_t n, fmi3FMUState* st) { return fmi3Error; }
fmi3Status fmi3GetDirectionalDerivative(fmi3Instance i, const fmi3ValueReference u[], size_t nu, const fmi3ValueReference k[], size_t nk,
                                        const fmi3Float64 s[], size_t ns, fmi3Float64 o[], size_t no) { return fmi3Error; }
fmi3Status fmi3GetAdjointDerivative(fmi3Instance i, const fmi3ValueReference u[], size_t nu, const fmi3ValueReference k[], size_t nk,
                                    const fmi3Float64 s[], size_t ns, fmi3Float64 o[], size_t no) { return fmi3Error; }
fmi3Status fmi3EnterConfigurationMode(fmi3Instance i) { return fmi3Error; }
fmi3Status fmi3ExitConfigurationMode(fmi3Instance i) { return fmi3Error; }
fmi3Status fmi3GetIntervalDecimal(fmi3Instance i, const fmi3ValueReference v[], size_t n, fmi3Float64 x[], fmi3IntervalQualifier q[]) { return fmi3Error; }
fmi3Status fmi3GetIntervalFraction(fmi3Instance i, const fmi3ValueReference v[], size_t n, fmi3UInt64 c[], fmi3UInt64 r[], fmi3IntervalQualifier q[]) { return fmi3Error; }
fmi3Status fmi3GetShiftDecimal(fmi3Instance i, const fmi3ValueReference v[], size_t n, fmi3Float64 x[]) { return fmi3Error; }
fmi3Status fmi3GetShiftFraction(fmi3Instance i, const fmi3ValueReference v[], size_t n, fmi3UInt64 c[], fmi3UInt64 r[]) { return fmi3Error; }
fmi3Status fmi3SetIntervalDecimal(fmi3Instance i, const fmi3ValueReference v[], size_t n, const fmi3Float64 x[]) { return fmi3Error; }
fmi3Status fmi3SetIntervalFraction(fmi3Instance i, const fmi3ValueReference v[], size_t n, const fmi3UInt64 c[], const fmi3UInt64 r[]) { return fmi3Error; }
fmi3Status fmi3SetShiftDecimal(fmi3Instance i, const fmi3ValueReference v[], size_t n, const fmi3Float64 x[]) { return fmi3Error; }
fmi3Status fmi3SetShiftFraction(fmi3Instance i, const fmi3ValueReference v[], size_t n, const fmi3UInt64 c[], const fmi3UInt64 r[]) { return fmi3Error; }
fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance i) { return fmi3OK; }

fmi3Status fmi3UpdateDiscreteStates(fmi3Instance i, fmi3Boolean* need, fmi3Boolean* term, fmi3Boolean* nom, fmi3Boolean* values,
                                    fmi3Boolean* next_def, fmi3Float64* next_t) {
  Inst* s = (Inst*)i;
  if (s->mode != M_EVENT && s->mode != M_INIT) { logf_(s, fmi3Error, "fmi3UpdateDiscreteStates outside event mode"); return fmi3Error; }
  *values = m_event(&s->m, s->time, &s->next_def, &s->next_t) ? fmi3True : fmi3False;
  *need = fmi3False; *term = m_terminate(&s->m) ? fmi3True : fmi3False; *nom = fmi3False;
  *next_def = s->next_def ? fmi3True : fmi3False; *next_t = s->next_t;
  return fmi3OK;
}

fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance i) { ((Inst*)i)->mode = M_CONT; return fmi3OK; }
fmi3Status fmi3CompletedIntegratorStep(fmi3Instance i, fmi3Boolean noSet, fmi3Boolean* enter, fmi3Boolean* term) {
  *enter = fmi3False; *term = fmi3False; return fmi3OK;
}
fmi3Status fmi3SetTime(fmi3Instance i, fmi3Float64 t) { ((Inst*)i)->time = t; return fmi3OK; }
fmi3Status fmi3SetContinuousStates(fmi3Instance i, const fmi3Float64 x[], size_t n) {
  if (n != N_STATES) return fmi3Error; m_set_x(&((Inst*)i)->m, x); return fmi3OK;
}
fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance i, fmi3Float64 dx[], size_t n) {
  Inst* s = (Inst*)i; if (n != N_STATES) return fmi3Error;
  m_update(&s->m, s->time); m_der(&s->m, s->time, dx); return fmi3OK;
}
fmi3Status fmi3GetEventIndicators(fmi3Instance i, fmi3Float64 z[], size_t n) {
  Inst* s = (Inst*)i;
  if (n != N_INDICATORS) return fmi3Error;
  m_update(&s->m, s->time); m_ind(&s->m, s->time, z); return fmi3OK;
}
fmi3Status fmi3GetContinuousStates(fmi3Instance i, fmi3Float64 x[], size_t n) {
  if (n != N_STATES) return fmi3Error; m_get_x(&((Inst*)i)->m, x); return fmi3OK;
}
fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance i, fmi3Float64 x[], size_t n) {
  for (size_t k = 0; k < n; k++) x[k] = 1.0; return fmi3OK;
}
fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance i, size_t* n) { *n = N_INDICATORS; return fmi3OK; }
fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance i, size_t* n) { *n = N_STATES; return fmi3OK; }

fmi3Status fmi3EnterStepMode(fmi3Instance i) { ((Inst*)i)->mode = M_STEP; return fmi3OK; }
fmi3Status fmi3GetOutputDerivatives(fmi3Instance i, const fmi3ValueReference vr[], size_t n, const fmi3Int32 o[], fmi3Float64 v[], size_t nv) { return fmi3Error; }

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

fmi3Status fmi3DoStep(fmi3Instance i, fmi3Float64 t, fmi3Float64 h, fmi3Boolean noSet, fmi3Boolean* event, fmi3Boolean* term,
                      fmi3Boolean* early, fmi3Float64* last) {
  Inst* s = (Inst*)i;
  double t_end = t + h, eps = 1e-12 * (1 + fabs(t_end));
  *event = fmi3False; *term = fmi3False; *early = fmi3False;
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
    if (m_terminate(&s->m)) break;  /* the model is done: stop at the event that ended it */
  }
  if (!m_terminate(&s->m)) s->time = t_end;
  *last = s->time;
  *term = m_terminate(&s->m) ? fmi3True : fmi3False;
  return fmi3OK;
}
fmi3Status fmi3ActivateModelPartition(fmi3Instance i, fmi3ValueReference c, fmi3Float64 t) { return fmi3Error; }
