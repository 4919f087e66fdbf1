/* A minimal hand-written FMI 2.0 FMU (Model Exchange + Co-Simulation) for featherstar's tests:
 * a first-order lag x' = (u - x) / tau with outputs y = x and z = k * u (direct feedthrough).
 * Co-Simulation steps with classic RK4 substeps (inputs held over the communication step).
 * Supports fmi2Get/Set/FreeFMUstate (rollback). Value references:
 *   0 tau (parameter)  1 k (parameter)  2 u (input)  3 x (state, output y)  4 der(x)  5 z (output)
 */
#include <stdlib.h>
#include <string.h>
#include <math.h>
#include "fmi2Functions.h"

typedef struct {
  double tau, k, u, x, time;
  int cs;
  fmi2CallbackFunctions cb;
} Lag;

static double der(const Lag* m, double x) { return (m->u - x) / m->tau; }

const char* fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char* fmi2GetVersion(void) { return fmi2Version; }
fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String cat[]) { return fmi2OK; }

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String res,
                              const fmi2CallbackFunctions* functions, fmi2Boolean visible, fmi2Boolean logging) {
  Lag* m = (Lag*)calloc(1, sizeof(Lag));
  if (!m) return NULL;
  m->tau = 0.1; m->k = 2.0; m->u = 0.0; m->x = 0.0; m->time = 0.0;
  m->cs = (type == fmi2CoSimulation);
  if (functions) m->cb = *functions;
  return m;
}
void fmi2FreeInstance(fmi2Component c) { free(c); }
fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean tolDef, fmi2Real tol, fmi2Real start,
                               fmi2Boolean stopDef, fmi2Real stop) { ((Lag*)c)->time = start; return fmi2OK; }
fmi2Status fmi2EnterInitializationMode(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2ExitInitializationMode(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2Terminate(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2Reset(fmi2Component c) { Lag* m = (Lag*)c; m->x = 0; m->u = 0; m->time = 0; return fmi2OK; }

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[]) {
  Lag* m = (Lag*)c;
  for (size_t i = 0; i < nvr; i++) {
    switch (vr[i]) {
      case 0: value[i] = m->tau; break;
      case 1: value[i] = m->k; break;
      case 2: value[i] = m->u; break;
      case 3: value[i] = m->x; break;
      case 4: value[i] = der(m, m->x); break;
      case 5: value[i] = m->k * m->u; break;
      default: return fmi2Error;
    }
  }
  return fmi2OK;
}
fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[]) {
  Lag* m = (Lag*)c;
  for (size_t i = 0; i < nvr; i++) {
    switch (vr[i]) {
      case 0: if (!(value[i] > 0)) return fmi2Error; m->tau = value[i]; break;
      case 1: m->k = value[i]; break;
      case 2: m->u = value[i]; break;
      case 3: m->x = value[i]; break;
      default: return fmi2Error;
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

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate* state) {
  Lag* copy = (Lag*)malloc(sizeof(Lag));
  if (!copy) return fmi2Error;
  memcpy(copy, c, sizeof(Lag));
  if (*state) free(*state);
  *state = copy;
  return fmi2OK;
}
fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate state) { memcpy(c, state, sizeof(Lag)); return fmi2OK; }
fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate* state) { free(*state); *state = NULL; return fmi2OK; }
fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate s, size_t* n) { return fmi2Error; }
fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate s, fmi2Byte b[], size_t n) { return fmi2Error; }
fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte b[], size_t n, fmi2FMUstate* s) { return fmi2Error; }
fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference a[], size_t na,
                                        const fmi2ValueReference b[], size_t nb, const fmi2Real dv[], fmi2Real out[]) { return fmi2Error; }

/* Model Exchange */
fmi2Status fmi2EnterEventMode(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo* info) {
  info->newDiscreteStatesNeeded = fmi2False; info->terminateSimulation = fmi2False;
  info->nominalsOfContinuousStatesChanged = fmi2False; info->valuesOfContinuousStatesChanged = fmi2False;
  info->nextEventTimeDefined = fmi2False; info->nextEventTime = 0;
  return fmi2OK;
}
fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2CompletedIntegratorStep(fmi2Component c, fmi2Boolean noSet, fmi2Boolean* enter, fmi2Boolean* term) {
  *enter = fmi2False; *term = fmi2False; return fmi2OK;
}
fmi2Status fmi2SetTime(fmi2Component c, fmi2Real t) { ((Lag*)c)->time = t; return fmi2OK; }
fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t nx) {
  if (nx != 1) return fmi2Error; ((Lag*)c)->x = x[0]; return fmi2OK;
}
fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real dx[], size_t nx) {
  if (nx != 1) return fmi2Error; dx[0] = der((Lag*)c, ((Lag*)c)->x); return fmi2OK;
}
fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real z[], size_t nz) { return nz ? fmi2Error : fmi2OK; }
fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t nx) {
  if (nx != 1) return fmi2Error; x[0] = ((Lag*)c)->x; return fmi2OK;
}
fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real n[], size_t nx) {
  if (nx != 1) return fmi2Error; n[0] = 1.0; return fmi2OK;
}

/* Co-Simulation */
fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                       const fmi2Integer order[], const fmi2Real v[]) { return fmi2Error; }
fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                        const fmi2Integer order[], fmi2Real v[]) { return fmi2Error; }
fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean noSetPrior) {
  Lag* m = (Lag*)c;
  int n = (int)ceil(h / 1e-4);
  if (n < 1) n = 1;
  double dt = h / n;
  for (int i = 0; i < n; i++) {
    double x = m->x;
    double k1 = der(m, x), k2 = der(m, x + 0.5 * dt * k1), k3 = der(m, x + 0.5 * dt * k2), k4 = der(m, x + dt * k3);
    m->x = x + dt / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4);
  }
  if (!isfinite(m->x)) return fmi2Error;
  m->time = t + h;
  return fmi2OK;
}
fmi2Status fmi2CancelStep(fmi2Component c) { return fmi2Error; }
fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status* v) { return fmi2Error; }
fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real* v) { return fmi2Error; }
fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer* v) { return fmi2Error; }
fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean* v) { return fmi2Error; }
fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String* v) { return fmi2Error; }
