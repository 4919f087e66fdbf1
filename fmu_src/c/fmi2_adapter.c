/* featherstar FMI 2.0 adapter: the fmi2 entry points of an FMI 2.0 FMU, each translated to the
 * FMI 3.0 shell beside it (fmi3_shell.c and the other fmi3_*.c).
 *
 * One shell serves both standards so that every check (state machine, arguments, NaN and
 * parameter ranges), the Co-Simulation integrator and the FMU state snapshots are the same code
 * in an FMI 2.0 and an FMI 3.0 FMU of a model: their results agree to the last bit. In an
 * FMI 2.0 build the shell's fmi3 functions are compiled with FMI3_Export empty, so they stay
 * hidden and only the fmi2 functions below are exported. The FMI 2.0 modelDescription.xml lists
 * the same value references as the FMI 3.0 one (without `time`), so value references pass
 * through unchanged; Real is Float64 and the status codes share their values.
 */
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
#include "fmi3Functions.h"

typedef struct {
  fmi3Instance inner;
  fmi2Type type;
  char* name;
  fmi2CallbackFunctions callbacks;
  /* fmi2SetupExperiment's arguments, passed on by fmi2EnterInitializationMode */
  fmi3Boolean tolerance_defined, stop_time_defined;
  fmi3Float64 tolerance, start_time, stop_time;
} fs2_instance;

/* FMI 2.0's logger takes a printf format: a message goes through with every '%' doubled. */
static void forward_log(fmi3InstanceEnvironment environment, fmi3Status status, fmi3String category,
                        fmi3String message) {
  const fs2_instance* s = (const fs2_instance*)environment;
  char escaped[1024];
  size_t i = 0;
  if (!s->callbacks.logger) return;
  for (; message && *message && i + 2 < sizeof escaped; ++message) {
    if (*message == '%') escaped[i++] = '%';
    escaped[i++] = *message;
  }
  escaped[i] = '\0';
  s->callbacks.logger(s->callbacks.componentEnvironment, s->name, (fmi2Status)status, category, escaped);
}

static fs2_instance* self(fmi2Component c) { return (fs2_instance*)c; }
static fmi3Instance inner(fmi2Component c) { return c ? self(c)->inner : NULL; }

static fmi2Status refuse(fmi2Component c, const char* message) {
  if (c) forward_log(self(c), fmi3Error, "logStatusError", message);
  return fmi2Error;
}

FMI2_Export const char* fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
FMI2_Export const char* fmi2GetVersion(void) { return fmi2Version; }

FMI2_Export fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                                          fmi2String fmuResourceLocation,
                                          const fmi2CallbackFunctions* functions, fmi2Boolean visible,
                                          fmi2Boolean loggingOn) {
  fs2_instance* s;
  if (fmuType != fmi2ModelExchange && fmuType != fmi2CoSimulation) return NULL;
  s = calloc(1, sizeof(fs2_instance));
  if (!s) return NULL;
  s->type = fmuType;
  s->name = strdup(instanceName ? instanceName : "");
  if (functions) s->callbacks = *functions;
  if (s->name) {
    s->inner = fmuType == fmi2ModelExchange
                   ? fmi3InstantiateModelExchange(instanceName, fmuGUID, fmuResourceLocation, visible,
                                                  loggingOn, s, forward_log)
                   : fmi3InstantiateCoSimulation(instanceName, fmuGUID, fmuResourceLocation, visible,
                                                 loggingOn, fmi3False, fmi3False, NULL, 0, s,
                                                 forward_log, NULL);
  }
  if (!s->inner) {
    free(s->name);
    free(s);
    return NULL;
  }
  return s;
}

FMI2_Export void fmi2FreeInstance(fmi2Component c) {
  if (!c) return;
  fmi3FreeInstance(self(c)->inner);
  free(self(c)->name);
  free(c);
}

FMI2_Export fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                                           const fmi2String categories[]) {
  return (fmi2Status)fmi3SetDebugLogging(inner(c), loggingOn, nCategories, categories);
}

FMI2_Export fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined,
                                           fmi2Real tolerance, fmi2Real startTime,
                                           fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
  fs2_instance* s = self(c);
  if (!s) return fmi2Error;
  s->tolerance_defined = toleranceDefined;
  s->tolerance = tolerance;
  s->start_time = startTime;
  s->stop_time_defined = stopTimeDefined;
  s->stop_time = stopTime;
  return fmi2OK;
}

FMI2_Export fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
  fs2_instance* s = self(c);
  if (!s) return fmi2Error;
  return (fmi2Status)fmi3EnterInitializationMode(s->inner, s->tolerance_defined, s->tolerance,
                                                 s->start_time, s->stop_time_defined, s->stop_time);
}

FMI2_Export fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
  return (fmi2Status)fmi3ExitInitializationMode(inner(c));
}

FMI2_Export fmi2Status fmi2Terminate(fmi2Component c) { return (fmi2Status)fmi3Terminate(inner(c)); }

FMI2_Export fmi2Status fmi2Reset(fmi2Component c) {
  fs2_instance* s = self(c);
  if (!s) return fmi2Error;
  s->tolerance_defined = s->stop_time_defined = fmi3False;
  s->start_time = 0.0;
  return (fmi2Status)fmi3Reset(s->inner);
}

FMI2_Export fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                   fmi2Real value[]) {
  return (fmi2Status)fmi3GetFloat64(inner(c), vr, nvr, value, nvr);
}

FMI2_Export fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                   const fmi2Real value[]) {
  return (fmi2Status)fmi3SetFloat64(inner(c), vr, nvr, value, nvr);
}

/* The models have Real variables only: an empty request succeeds, anything else is refused. */
#define NO_VARIABLES(function, T)                                                            \
  FMI2_Export fmi2Status function(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, \
                                  T value[]) {                                               \
    (void)vr, (void)value;                                                                   \
    if (!c) return fmi2Error;                                                                \
    return nvr ? refuse(c, #function ": the model has no variables of this type") : fmi2OK;  \
  }

NO_VARIABLES(fmi2GetInteger, fmi2Integer)
NO_VARIABLES(fmi2GetBoolean, fmi2Boolean)
NO_VARIABLES(fmi2GetString, fmi2String)
NO_VARIABLES(fmi2SetInteger, const fmi2Integer)
NO_VARIABLES(fmi2SetBoolean, const fmi2Boolean)
NO_VARIABLES(fmi2SetString, const fmi2String)

FMI2_Export fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate* FMUstate) {
  return (fmi2Status)fmi3GetFMUState(inner(c), FMUstate);
}

FMI2_Export fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate) {
  return (fmi2Status)fmi3SetFMUState(inner(c), FMUstate);
}

FMI2_Export fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate* FMUstate) {
  return (fmi2Status)fmi3FreeFMUState(inner(c), FMUstate);
}

/* A snapshot holds CasADi's memory verbatim, pointers included: it cannot leave the process. */
FMI2_Export fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate, size_t* size) {
  (void)FMUstate, (void)size;
  return refuse(c, "fmi2SerializedFMUstateSize: not supported (canSerializeFMUstate is false)");
}

FMI2_Export fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate, fmi2Byte bytes[],
                                             size_t size) {
  (void)FMUstate, (void)bytes, (void)size;
  return refuse(c, "fmi2SerializeFMUstate: not supported (canSerializeFMUstate is false)");
}

FMI2_Export fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte bytes[], size_t size,
                                               fmi2FMUstate* FMUstate) {
  (void)bytes, (void)size, (void)FMUstate;
  return refuse(c, "fmi2DeSerializeFMUstate: not supported (canSerializeFMUstate is false)");
}

FMI2_Export fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[],
                                                    size_t nUnknown, const fmi2ValueReference vKnown_ref[],
                                                    size_t nKnown, const fmi2Real dvKnown[],
                                                    fmi2Real dvUnknown[]) {
  return (fmi2Status)fmi3GetDirectionalDerivative(inner(c), vUnknown_ref, nUnknown, vKnown_ref, nKnown,
                                                  dvKnown, nKnown, dvUnknown, nUnknown);
}

/* --- Model Exchange ------------------------------------------------------------------------ */

FMI2_Export fmi2Status fmi2EnterEventMode(fmi2Component c) { return (fmi2Status)fmi3EnterEventMode(inner(c)); }

FMI2_Export fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo* eventInfo) {
  fmi3Boolean need = fmi3False, terminate = fmi3False, nominals = fmi3False, values = fmi3False;
  fmi3Boolean defined = fmi3False;
  fmi3Float64 next = 0.0;
  fmi3Status status;
  if (c && !eventInfo) return refuse(c, "fmi2NewDiscreteStates: NULL eventInfo");
  status = fmi3UpdateDiscreteStates(inner(c), &need, &terminate, &nominals, &values, &defined, &next);
  if (status <= fmi3Warning) {
    eventInfo->newDiscreteStatesNeeded = need;
    eventInfo->terminateSimulation = terminate;
    eventInfo->nominalsOfContinuousStatesChanged = nominals;
    eventInfo->valuesOfContinuousStatesChanged = values;
    eventInfo->nextEventTimeDefined = defined;
    eventInfo->nextEventTime = next;
  }
  return (fmi2Status)status;
}

FMI2_Export fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c) {
  return (fmi2Status)fmi3EnterContinuousTimeMode(inner(c));
}

FMI2_Export fmi2Status fmi2CompletedIntegratorStep(fmi2Component c, fmi2Boolean noSetFMUStatePriorToCurrentPoint,
                                                   fmi2Boolean* enterEventMode, fmi2Boolean* terminateSimulation) {
  fmi3Boolean event = fmi3False, terminate = fmi3False;
  fmi3Status status;
  if (c && (!enterEventMode || !terminateSimulation))
    return refuse(c, "fmi2CompletedIntegratorStep: NULL argument");
  status = fmi3CompletedIntegratorStep(inner(c), noSetFMUStatePriorToCurrentPoint, &event, &terminate);
  if (status <= fmi3Warning) {
    *enterEventMode = event;
    *terminateSimulation = terminate;
  }
  return (fmi2Status)status;
}

FMI2_Export fmi2Status fmi2SetTime(fmi2Component c, fmi2Real time) { return (fmi2Status)fmi3SetTime(inner(c), time); }

FMI2_Export fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t nx) {
  return (fmi2Status)fmi3SetContinuousStates(inner(c), x, nx);
}

FMI2_Export fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real derivatives[], size_t nx) {
  return (fmi2Status)fmi3GetContinuousStateDerivatives(inner(c), derivatives, nx);
}

FMI2_Export fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real eventIndicators[], size_t ni) {
  return (fmi2Status)fmi3GetEventIndicators(inner(c), eventIndicators, ni);
}

FMI2_Export fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t nx) {
  return (fmi2Status)fmi3GetContinuousStates(inner(c), x, nx);
}

FMI2_Export fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real x_nominal[], size_t nx) {
  return (fmi2Status)fmi3GetNominalsOfContinuousStates(inner(c), x_nominal, nx);
}

/* --- Co-Simulation ------------------------------------------------------------------------- */

FMI2_Export fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint,
                                  fmi2Real communicationStepSize, fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
  fmi3Boolean event = fmi3False, terminate = fmi3False, early = fmi3False;
  fmi3Float64 last = 0.0;
  return (fmi2Status)fmi3DoStep(inner(c), currentCommunicationPoint, communicationStepSize,
                                noSetFMUStatePriorToCurrentPoint, &event, &terminate, &early, &last);
}

FMI2_Export fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                                   const fmi2Integer order[], const fmi2Real value[]) {
  (void)vr, (void)order, (void)value;
  if (!c) return fmi2Error;
  return nvr ? refuse(c, "fmi2SetRealInputDerivatives: not supported (canInterpolateInputs is false)") : fmi2OK;
}

FMI2_Export fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                                    const fmi2Integer order[], fmi2Real value[]) {
  (void)vr, (void)order, (void)value;
  if (!c) return fmi2Error;
  return nvr ? refuse(c, "fmi2GetRealOutputDerivatives: not supported (maxOutputDerivativeOrder is 0)") : fmi2OK;
}

/* Steps always complete before fmi2DoStep returns: there is never a pending step to ask about. */
FMI2_Export fmi2Status fmi2CancelStep(fmi2Component c) {
  return refuse(c, "fmi2CancelStep: not supported (fmi2DoStep never returns fmi2Pending)");
}

#define NO_STATUS(function, T)                                                                 \
  FMI2_Export fmi2Status function(fmi2Component c, const fmi2StatusKind s, T* value) {         \
    (void)s, (void)value;                                                                      \
    return refuse(c, #function ": not supported (fmi2DoStep never returns fmi2Pending)");      \
  }

NO_STATUS(fmi2GetStatus, fmi2Status)
NO_STATUS(fmi2GetRealStatus, fmi2Real)
NO_STATUS(fmi2GetIntegerStatus, fmi2Integer)
NO_STATUS(fmi2GetStringStatus, fmi2String)

/* After fmi2Discard an importer asks whether the slave ended for good: these models never ask to
 * terminate (a discarded step is a step to retry shorter), so the answer is always no. */
FMI2_Export fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean* value) {
  if (!c || !value) return refuse(c, "fmi2GetBooleanStatus: NULL argument");
  if (s != fmi2Terminated) return refuse(c, "fmi2GetBooleanStatus: only fmi2Terminated is supported");
  *value = fmi2False;
  return fmi2OK;
}
