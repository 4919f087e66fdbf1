/* featherstar FMI 3.0 shell: the real fmi3 entry points around CasADi's generated FMU code.
 *
 * CasADi's generated functions trust their caller completely: an unknown value reference, the
 * `time` reference, a call out of sequence or a NULL pointer reads or writes out of bounds.
 * Importers do all of these (fmpy records every declared variable, `time` included), so every
 * entry point here first checks the instance, its mode and its arguments, logs what was wrong
 * through logMessage and returns fmi3Error; only then does it delegate to casadi_fmi3....
 * The mode checks follow the FMI 3.0 state machine. This file holds the life cycle; getting and
 * setting values is in fmi3_variables.c; Co-Simulation (fmi3_cosim.c) and the FMU state
 * snapshots (fmi3_state.c) are the shell's own, since CasADi only provides Model Exchange.
 */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"
#include "fmi3_shell.h"

const char* fs_mode_name(fs_mode mode) {
  switch (mode) {
    case FS_INSTANTIATED: return "Instantiated";
    case FS_INITIALIZATION: return "InitializationMode";
    case FS_EVENT: return "EventMode";
    case FS_CONTINUOUS_TIME: return "ContinuousTimeMode";
    case FS_STEP: return "StepMode";
    case FS_TERMINATED: return "Terminated";
    case FS_FAILED: return "failed (after an fmi3Error)";
  }
  return "unknown";
}

static void log_status(const fs_instance* s, fmi3Status status, const char* fmt, va_list args) {
  char message[512];
  /* Errors are reported whatever the logging setting: an importer still needs the cause. */
  if (!s->log) return;
  vsnprintf(message, sizeof message, fmt, args);
  s->log(s->environment, status, status == fmi3Discard ? "logStatusDiscard" : "logStatusError", message);
}

void fs_error(const fs_instance* s, const char* fmt, ...) {
  va_list args;
  va_start(args, fmt);
  log_status(s, fmi3Error, fmt, args);
  va_end(args);
}

void fs_discard(const fs_instance* s, const char* fmt, ...) {
  va_list args;
  va_start(args, fmt);
  log_status(s, fmi3Discard, fmt, args);
  va_end(args);
}

fs_instance* fs_check(fmi3Instance instance, const char* function, unsigned modes, unsigned kinds) {
  fs_instance* s = (fs_instance*)instance;
  if (!s) return NULL;
  if (!(s->kind & kinds)) {
    fs_error(s, "%s: not available in %s", function,
             s->kind == FS_CO_SIMULATION ? "Co-Simulation" : "Model Exchange");
    return NULL;
  }
  if (!(s->dyn.mode & modes)) {
    fs_error(s, "%s: not allowed in state %s", function, fs_mode_name(s->dyn.mode));
    return NULL;
  }
  return s;
}

size_t fs_work_size(size_t n_x) { return 10 * n_x; }

long fs_first_non_finite(const double* values, size_t n) {
  size_t i;
  for (i = 0; i < n; ++i)
    if (!isfinite(values[i])) return (long)i;
  return -1;
}

/* Why the outputs at the current point cannot be passed on, or NULL: a step that ends with a
 * NaN output is a failed step, not an OK one the importer would only notice later. Evaluating
 * here costs nothing extra: the importer's next fmi3GetFloat64 reuses the result. */
const char* fs_outputs_problem(fs_instance* s, char* why, size_t size) {
  const fs_model* m = s->model;
  const double* v;
  size_t i;
  if (m->evaluate(s->memory)) return "model evaluation failed";
  v = m->values(s->memory);
  for (i = 0; i < m->n_y; ++i) {
    if (!isfinite(v[m->y_vr[i]])) {
      snprintf(why, size, "output '%s' is not finite (%g)", m->var_name[m->y_vr[i]], v[m->y_vr[i]]);
      return why;
    }
  }
  return NULL;
}

static void reset_dynamic(fs_instance* s) {
  s->dyn.mode = FS_INSTANTIATED;
  s->dyn.time = 0.0;
  s->dyn.rtol = FS_DEFAULT_RTOL;
  s->dyn.atol = 1e-2 * FS_DEFAULT_RTOL;
  s->dyn.h = 0.0;
  s->dyn.err_old = 1e-4;
  s->dyn.fsal_valid = 0;
}

static fs_instance* instantiate(fmi3String name, fmi3String token, fmi3String resources,
                                fmi3Boolean visible, fmi3Boolean logging_on,
                                fmi3InstanceEnvironment environment, fmi3LogMessageCallback log,
                                fs_kind kind) {
  const fs_model* model = fs_model_info();
  size_t i, n_work = fs_work_size(model->n_x);
  fs_instance* s;
  if (!token || strcmp(token, model->instantiation_token) != 0) {
    if (log)
      log(environment, fmi3Error, "logStatusError",
          "fmi3Instantiate: instantiationToken does not match modelDescription.xml");
    return NULL;
  }
  s = calloc(1, sizeof(fs_instance));
  if (!s) return NULL;
  s->model = model;
  s->kind = kind;
  s->environment = environment;
  s->log = log;
  s->name = strdup(name ? name : "");
  s->vr_kind = calloc(model->n_var, 1);
  s->work = calloc(n_work ? n_work : 1, sizeof(double));
  if (s->name && s->vr_kind && s->work)
    s->memory = casadi_fmi3InstantiateModelExchange(s->name, token, resources, visible, logging_on,
                                                    environment, log);
  if (!s->memory) {
    if (log) log(environment, fmi3Error, "logStatusError", "fmi3Instantiate: out of memory");
    free(s->name);
    free(s->vr_kind);
    free(s->work);
    free(s);
    return NULL;
  }
  for (i = 1; i < model->n_var; ++i) s->vr_kind[i] = FS_VR_CALCULATED;
  for (i = 0; i < model->n_x; ++i) s->vr_kind[model->x_vr[i]] = FS_VR_STATE;
  for (i = 0; i < model->n_u; ++i) s->vr_kind[model->u_vr[i]] = FS_VR_INPUT;
  for (i = 0; i < model->n_p; ++i) s->vr_kind[model->p_vr[i]] = FS_VR_PARAMETER;
  reset_dynamic(s);
  return s;
}

FMI3_Export fmi3Instance fmi3InstantiateModelExchange(
    fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath,
    fmi3Boolean visible, fmi3Boolean loggingOn, fmi3InstanceEnvironment instanceEnvironment,
    fmi3LogMessageCallback logMessage) {
  return instantiate(instanceName, instantiationToken, resourcePath, visible, loggingOn,
                     instanceEnvironment, logMessage, FS_MODEL_EXCHANGE);
}

FMI3_Export fmi3Instance fmi3InstantiateCoSimulation(
    fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath,
    fmi3Boolean visible, fmi3Boolean loggingOn, fmi3Boolean eventModeUsed,
    fmi3Boolean earlyReturnAllowed, const fmi3ValueReference requiredIntermediateVariables[],
    size_t nRequiredIntermediateVariables, fmi3InstanceEnvironment instanceEnvironment,
    fmi3LogMessageCallback logMessage, fmi3IntermediateUpdateCallback intermediateUpdate) {
  fs_instance* s;
  /* Steps never return early and there are no intermediate updates: these requests are moot. */
  (void)earlyReturnAllowed;
  (void)requiredIntermediateVariables;
  (void)nRequiredIntermediateVariables;
  (void)intermediateUpdate;
  s = instantiate(instanceName, instantiationToken, resourcePath, visible, loggingOn,
                  instanceEnvironment, logMessage, FS_CO_SIMULATION);
  if (s) s->event_mode_used = eventModeUsed;
  return s;
}

FMI3_Export void fmi3FreeInstance(fmi3Instance instance) {
  fs_instance* s = (fs_instance*)instance;
  if (!s) return;
  casadi_fmi3FreeInstance(s->memory);
  free(s->name);
  free(s->vr_kind);
  free(s->work);
  free(s);
}

FMI3_Export const char* fmi3GetVersion(void) { return fmi3Version; }

FMI3_Export fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn,
                                           size_t nCategories, const fmi3String categories[]) {
  /* The shell only ever logs errors, and those are always reported. */
  (void)loggingOn;
  (void)nCategories;
  (void)categories;
  return fs_check(instance, "fmi3SetDebugLogging", FS_ANY_MODE, FS_ANY_KIND) ? fmi3OK : fmi3Error;
}

FMI3_Export fmi3Status fmi3EnterInitializationMode(fmi3Instance instance,
                                                   fmi3Boolean toleranceDefined,
                                                   fmi3Float64 tolerance, fmi3Float64 startTime,
                                                   fmi3Boolean stopTimeDefined,
                                                   fmi3Float64 stopTime) {
  fs_instance* s = fs_check(instance, "fmi3EnterInitializationMode", FS_INSTANTIATED, FS_ANY_KIND);
  if (!s) return fmi3Error;
  if (!isfinite(startTime)) {
    fs_error(s, "fmi3EnterInitializationMode: startTime is not finite");
    return fmi3Error;
  }
  /* Below ~1e-13 the Dormand-Prince error estimate is mostly rounding noise. */
  if (toleranceDefined && tolerance > 0) s->dyn.rtol = tolerance < 1e-13 ? 1e-13 : tolerance;
  s->dyn.atol = 1e-2 * s->dyn.rtol;
  s->dyn.time = startTime;
  s->dyn.fsal_valid = 0;
  if (casadi_fmi3EnterInitializationMode(s->memory, toleranceDefined, tolerance, startTime,
                                         stopTimeDefined, stopTime) != fmi3OK)
    return fmi3Error;
  s->model->set_states(s->memory, startTime, NULL);
  s->dyn.mode = FS_INITIALIZATION;
  return fmi3OK;
}

FMI3_Export fmi3Status fmi3ExitInitializationMode(fmi3Instance instance) {
  fs_instance* s = fs_check(instance, "fmi3ExitInitializationMode", FS_INITIALIZATION, FS_ANY_KIND);
  char why[256];
  const char* problem;
  if (!s) return fmi3Error;
  /* Each parameter is checked against its own range when set; a combination the model cannot
   * work with (a four-bar that does not close) shows here, before the first step. */
  problem = fs_outputs_problem(s, why, sizeof why);
  if (problem) {
    fs_error(s, "fmi3ExitInitializationMode: %s at t=%g with the values set (parameters outside "
             "the range they are valid in together?)", problem, s->dyn.time);
    return fmi3Error;
  }
  if (casadi_fmi3ExitInitializationMode(s->memory) != fmi3OK) return fmi3Error;
  s->dyn.mode = (s->kind == FS_CO_SIMULATION && !s->event_mode_used) ? FS_STEP : FS_EVENT;
  return fmi3OK;
}

FMI3_Export fmi3Status fmi3EnterEventMode(fmi3Instance instance) {
  fs_instance* s = fs_check(instance, "fmi3EnterEventMode", FS_CONTINUOUS_TIME | FS_STEP, FS_ANY_KIND);
  if (!s) return fmi3Error;
  if (s->kind == FS_CO_SIMULATION && !s->event_mode_used) {
    fs_error(s, "fmi3EnterEventMode: instantiated with eventModeUsed = false");
    return fmi3Error;
  }
  if (casadi_fmi3EnterEventMode(s->memory) != fmi3OK) return fmi3Error;
  s->dyn.fsal_valid = 0;
  s->dyn.mode = FS_EVENT;
  return fmi3OK;
}

FMI3_Export fmi3Status fmi3Terminate(fmi3Instance instance) {
  fs_instance* s = fs_check(instance, "fmi3Terminate",
                            FS_EVENT | FS_CONTINUOUS_TIME | FS_STEP | FS_FAILED, FS_ANY_KIND);
  if (!s) return fmi3Error;
  if (casadi_fmi3Terminate(s->memory) != fmi3OK) return fmi3Error;
  s->dyn.mode = FS_TERMINATED;
  return fmi3OK;
}

FMI3_Export fmi3Status fmi3Reset(fmi3Instance instance) {
  fs_instance* s = fs_check(instance, "fmi3Reset", FS_ANY_MODE, FS_ANY_KIND);
  if (!s) return fmi3Error;
  if (casadi_fmi3Reset(s->memory) != fmi3OK) return fmi3Error;
  reset_dynamic(s);
  return fmi3OK;
}

FMI3_Export fmi3Status fmi3UpdateDiscreteStates(
    fmi3Instance instance, fmi3Boolean* discreteStatesNeedUpdate, fmi3Boolean* terminateSimulation,
    fmi3Boolean* nominalsOfContinuousStatesChanged, fmi3Boolean* valuesOfContinuousStatesChanged,
    fmi3Boolean* nextEventTimeDefined, fmi3Float64* nextEventTime) {
  fs_instance* s = fs_check(instance, "fmi3UpdateDiscreteStates", FS_EVENT, FS_ANY_KIND);
  if (!s) return fmi3Error;
  if (!discreteStatesNeedUpdate || !terminateSimulation || !nominalsOfContinuousStatesChanged ||
      !valuesOfContinuousStatesChanged || !nextEventTimeDefined || !nextEventTime) {
    fs_error(s, "fmi3UpdateDiscreteStates: NULL argument");
    return fmi3Error;
  }
  *nextEventTime = 0.0;
  s->dyn.fsal_valid = 0;
  return casadi_fmi3UpdateDiscreteStates(s->memory, discreteStatesNeedUpdate, terminateSimulation,
                                         nominalsOfContinuousStatesChanged,
                                         valuesOfContinuousStatesChanged, nextEventTimeDefined,
                                         nextEventTime);
}
