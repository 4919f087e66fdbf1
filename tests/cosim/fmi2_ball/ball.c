/* A hand-written FMI 2.0 Model Exchange FMU with a state event: a bouncing ball.
 * h' = v, v' = -g; event indicator z = h; at h = 0 falling: v := -e v (time event-free).
 * Value references: 0 g, 1 e (parameters), 2 h, 3 der(h) (= v), 4 v, 5 der(v), 6 bounces (output, Real). */
#include <stdlib.h>
#include <string.h>
#include "fmi2Functions.h"

typedef struct { double g, e, h, v, bounces, time; } Ball;

const char* fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char* fmi2GetVersion(void) { return fmi2Version; }
fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String cat[]) { return fmi2OK; }
fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String res,
                              const fmi2CallbackFunctions* f, fmi2Boolean visible, fmi2Boolean logging) {
  if (type != fmi2ModelExchange) return NULL;
  Ball* b = (Ball*)calloc(1, sizeof(Ball));
  b->g = 9.81; b->e = 0.7; b->h = 1.0; b->v = 0.0;
  return b;
}
void fmi2FreeInstance(fmi2Component c) { free(c); }
fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean a, fmi2Real tol, fmi2Real t0, fmi2Boolean b, fmi2Real t1) { return fmi2OK; }
fmi2Status fmi2EnterInitializationMode(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2ExitInitializationMode(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2Terminate(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2Reset(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real v[]) {
  Ball* b = (Ball*)c;
  for (size_t i = 0; i < n; i++) {
    switch (vr[i]) {
      case 0: v[i] = b->g; break; case 1: v[i] = b->e; break; case 2: v[i] = b->h; break;
      case 3: v[i] = b->v; break; case 4: v[i] = b->v; break; case 5: v[i] = -b->g; break;
      case 6: v[i] = b->bounces; break; default: return fmi2Error;
    }
  }
  return fmi2OK;
}
fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real v[]) {
  Ball* b = (Ball*)c;
  for (size_t i = 0; i < n; i++) {
    switch (vr[i]) {
      case 0: b->g = v[i]; break; case 1: b->e = v[i]; break; case 2: b->h = v[i]; break;
      case 4: b->v = v[i]; break; default: return fmi2Error;
    }
  }
  return fmi2OK;
}
fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Integer v[]) { return n ? fmi2Error : fmi2OK; }
fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Boolean v[]) { return n ? fmi2Error : fmi2OK; }
fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2String v[]) { return n ? fmi2Error : fmi2OK; }
fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer v[]) { return n ? fmi2Error : fmi2OK; }
fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Boolean v[]) { return n ? fmi2Error : fmi2OK; }
fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2String v[]) { return n ? fmi2Error : fmi2OK; }
fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate* s) { return fmi2Error; }
fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate s) { return fmi2Error; }
fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate* s) { return fmi2Error; }
fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate s, size_t* n) { return fmi2Error; }
fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate s, fmi2Byte b[], size_t n) { return fmi2Error; }
fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte b[], size_t n, fmi2FMUstate* s) { return fmi2Error; }
fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference a[], size_t na,
                                        const fmi2ValueReference b[], size_t nb, const fmi2Real dv[], fmi2Real out[]) { return fmi2Error; }
fmi2Status fmi2EnterEventMode(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo* info) {
  Ball* b = (Ball*)c;
  memset(info, 0, sizeof(*info));
  if (b->h <= 0 && b->v < 0) {  /* the bounce */
    b->h = 0.0;
    b->v = -b->e * b->v;
    b->bounces += 1;
    info->valuesOfContinuousStatesChanged = fmi2True;
  }
  return fmi2OK;
}
fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2CompletedIntegratorStep(fmi2Component c, fmi2Boolean n, fmi2Boolean* e, fmi2Boolean* t) { *e = fmi2False; *t = fmi2False; return fmi2OK; }
fmi2Status fmi2SetTime(fmi2Component c, fmi2Real t) { ((Ball*)c)->time = t; return fmi2OK; }
fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t n) { Ball* b = (Ball*)c; b->h = x[0]; b->v = x[1]; return fmi2OK; }
fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real dx[], size_t n) { Ball* b = (Ball*)c; dx[0] = b->v; dx[1] = -b->g; return fmi2OK; }
fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real z[], size_t n) { z[0] = ((Ball*)c)->h; return fmi2OK; }
fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t n) { Ball* b = (Ball*)c; x[0] = b->h; x[1] = b->v; return fmi2OK; }
fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real x[], size_t n) { x[0] = 1; x[1] = 1; return fmi2OK; }
