/* featherstar FMI 3.0 shell: the real fmi3 entry points around CasADi's generated FMU code.
 *
 * CasADi's generated functions trust their caller completely: an unknown value reference, the
 * `time` reference, a call out of sequence or a NULL pointer reads or writes out of bounds.
 * Importers do all of these (fmpy records every declared variable, `time` included), so every
 * entry point here first checks the instance, its mode and its arguments, logs what was wrong
 * through logMessage and returns fmi3Error; only then does it delegate to casadi_fmi3....
 * The mode checks follow the FMI 3.0 state machine; Co-Simulation (fmi3_cosim.c) and the FMU
 * state snapshots are the shell's own, since CasADi only provides Model Exchange.
 */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"
#include "fmi3_shell.h"

#define GET_MODES (FS_INSTANTIATED | FS_INITIALIZATION | FS_EVENT | FS_CONTINUOUS_TIME | FS_STEP | FS_TERMINATED | FS_FAILED)
#define SET_MODES (FS_INSTANTIATED | FS_INITIALIZATION | FS_EVENT | FS_CONTINUOUS_TIME | FS_STEP)
#define DERIVATIVE_MODES (FS_INITIALIZATION | FS_EVENT | FS_CONTINUOUS_TIME | FS_STEP | FS_TERMINATED)

/* Modes in which fmi3SetFloat64 may change each kind of variable (FMI 3.0, section 3.2). */
static const unsigned settable_in[] = {
    [FS_VR_UNKNOWN] = 0,
    [FS_VR_STATE] = FS_INSTANTIATED | FS_INITIALIZATION,
    [FS_VR_INPUT] = SET_MODES,
    [FS_VR_PARAMETER] = FS_INSTANTIATED | FS_INITIALIZATION | FS_EVENT | FS_STEP,
    [FS_VR_CALCULATED] = 0,
};

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

/* Number of values the references address, or (size_t)-1 after logging the first bad one. */
static size_t count_values(const fs_instance* s, const char* function,
                           const fmi3ValueReference vr[], size_t n_vr, int allow_time) {
  size_t i, n = 0;
  for (i = 0; i < n_vr; ++i) {
    if (vr[i] == FS_TIME_VR && allow_time) {
      n += 1;
    } else if (vr[i] < s->model->n_var && s->vr_kind[vr[i]] != FS_VR_UNKNOWN) {
      n += s->model->var_offset[vr[i] + 1] - s->model->var_offset[vr[i]];
    } else {
      fs_error(s, "%s: unknown value reference %u", function, (unsigned)vr[i]);
      return (size_t)-1;
    }
  }
  return n;
}

static int check_array_args(const fs_instance* s, const char* function, const void* vr,
                            size_t n_vr, const void* values, size_t n_values, size_t expected) {
  if (n_vr && (!vr || !values)) {
    fs_error(s, "%s: NULL array", function);
    return 0;
  }
  if (expected == (size_t)-1) return 0;
  if (expected != n_values) {
    fs_error(s, "%s: nValues = %zu but the value references address %zu values",
             function, n_values, expected);
    return 0;
  }
  return 1;
}

static const char* var_name(const fs_instance* s, fmi3ValueReference vr) {
  return vr == FS_TIME_VR ? "time" : s->model->var_name[vr];
}

/* In Instantiated only start values exist: those of states, inputs and parameters (and time). */
static fmi3Status get_start_values(fs_instance* s, const fmi3ValueReference vr[], size_t n_vr,
                                   fmi3Float64 values[]) {
  const double* v = s->model->values(s->memory);
  size_t i;
  for (i = 0; i < n_vr; ++i) {
    if (vr[i] != FS_TIME_VR && s->vr_kind[vr[i]] == FS_VR_CALCULATED) {
      fs_error(s, "fmi3GetFloat64: '%s' (value reference %u) is calculated: it has no value before "
               "fmi3EnterInitializationMode", var_name(s, vr[i]), (unsigned)vr[i]);
      return fmi3Error;
    }
    values[i] = vr[i] == FS_TIME_VR ? s->dyn.time : v[vr[i]];
  }
  return fmi3OK;
}

FMI3_Export fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                      size_t nValueReferences, fmi3Float64 values[], size_t nValues) {
  fs_instance* s = fs_check(instance, "fmi3GetFloat64", GET_MODES, FS_ANY_KIND);
  size_t i, k, n;
  long bad;
  int has_time = 0;
  if (!s) return fmi3Error;
  if (nValueReferences && !valueReferences) {
    fs_error(s, "fmi3GetFloat64: NULL array");
    return fmi3Error;
  }
  n = count_values(s, "fmi3GetFloat64", valueReferences, nValueReferences, 1);
  if (!check_array_args(s, "fmi3GetFloat64", valueReferences, nValueReferences, values, nValues, n))
    return fmi3Error;
  if (s->dyn.mode == FS_INSTANTIATED)
    return get_start_values(s, valueReferences, nValueReferences, values);
  for (i = 0; i < nValueReferences; ++i) has_time |= valueReferences[i] == FS_TIME_VR;
  if (!has_time) {
    if (casadi_fmi3GetFloat64(s->memory, valueReferences, nValueReferences, values, nValues) != fmi3OK) {
      fs_error(s, "fmi3GetFloat64: model evaluation failed at t=%g", s->dyn.time);
      return fmi3Error;
    }
    /* Variables are scalars: value i belongs to valueReferences[i]. A NaN is never passed on
     * as a valid result: the importer would only find out much later, and not where. Discard
     * (not Error) because an ME importer may retry with a shorter step (FMI 3.0, 2.2.3). */
    bad = fs_first_non_finite(values, nValues);
    if (bad >= 0) {
      fs_discard(s, "fmi3GetFloat64: '%s' is not finite (%g) at t=%.10g", var_name(s, valueReferences[bad]),
                 values[bad], s->dyn.time);
      return fmi3Discard;
    }
    return fmi3OK;
  }
  /* `time` lives in the shell, so a mixed request is answered one reference at a time. */
  for (i = 0, k = 0; i < nValueReferences; ++i) {
    if (valueReferences[i] == FS_TIME_VR) {
      values[k++] = s->dyn.time;
      continue;
    }
    n = s->model->var_offset[valueReferences[i] + 1] - s->model->var_offset[valueReferences[i]];
    fmi3Status status = fmi3GetFloat64(s, &valueReferences[i], 1, &values[k], n);
    if (status != fmi3OK) return status;
    k += n;
  }
  return fmi3OK;
}

/* Whether `value` may be given to variable `vr`; logs why not. Parameters must lie in their
 * physical range, inputs and states must be finite: the model code would compute with anything. */
static int valid_value(const fs_instance* s, fmi3ValueReference vr, double value) {
  const fs_limit* limit = &s->model->limit[vr];
  size_t i;
  int ok;
  if (s->vr_kind[vr] != FS_VR_PARAMETER) {
    if (isfinite(value)) return 1;
    fs_error(s, "fmi3SetFloat64: %s '%s' = %g refused: not finite",
             s->vr_kind[vr] == FS_VR_INPUT ? "input" : "state", var_name(s, vr), value);
    return 0;
  }
  if (limit->n_choices) {
    for (i = 0; i < limit->n_choices; ++i)
      if (value == limit->choices[i]) return 1;
    fs_error(s, "fmi3SetFloat64: parameter '%s' = %g refused: it must be one of the %zu values its "
             "description lists", var_name(s, vr), value, limit->n_choices);
    return 0;
  }
  ok = isfinite(value) && (limit->exclusive_min ? value > limit->min : value >= limit->min) &&
       value <= limit->max;
  if (!ok)
    fs_error(s, "fmi3SetFloat64: parameter '%s' = %g %s refused: outside its valid range %c%g, %g] %s",
             var_name(s, vr), value, limit->unit, limit->exclusive_min ? '(' : '[', limit->min,
             limit->max, limit->unit);
  return ok;
}

FMI3_Export fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                      size_t nValueReferences, const fmi3Float64 values[], size_t nValues) {
  fs_instance* s = fs_check(instance, "fmi3SetFloat64", SET_MODES, FS_ANY_KIND);
  size_t i, n;
  if (!s) return fmi3Error;
  if (nValueReferences && !valueReferences) {
    fs_error(s, "fmi3SetFloat64: NULL array");
    return fmi3Error;
  }
  n = count_values(s, "fmi3SetFloat64", valueReferences, nValueReferences, 0);
  if (!check_array_args(s, "fmi3SetFloat64", valueReferences, nValueReferences, values, nValues, n))
    return fmi3Error;
  for (i = 0; i < nValueReferences; ++i) {
    fs_vr_kind kind = (fs_vr_kind)s->vr_kind[valueReferences[i]];
    if (!(settable_in[kind] & s->dyn.mode)) {
      fs_error(s, "fmi3SetFloat64: value reference %u cannot be set in state %s%s",
               (unsigned)valueReferences[i], fs_mode_name(s->dyn.mode),
               kind == FS_VR_CALCULATED ? " (it is calculated)" : "");
      return fmi3Error;
    }
    /* All or nothing: a refused value leaves every variable as it was. */
    if (!valid_value(s, valueReferences[i], values[i])) return fmi3Error;
  }
  s->dyn.fsal_valid = 0;
  return casadi_fmi3SetFloat64(s->memory, valueReferences, nValueReferences, values, nValues);
}

static int check_derivative_args(const fs_instance* s, const char* function,
                                 const fmi3ValueReference unknowns[], size_t n_unknowns,
                                 const fmi3ValueReference knowns[], size_t n_knowns,
                                 const void* seed, size_t n_seed, const void* sensitivity,
                                 size_t n_sensitivity, int adjoint) {
  size_t n_out, n_in;
  if ((n_unknowns && !unknowns) || (n_knowns && !knowns)) {
    fs_error(s, "%s: NULL array", function);
    return 0;
  }
  n_out = count_values(s, function, unknowns, n_unknowns, 0);
  n_in = count_values(s, function, knowns, n_knowns, 0);
  if (n_out == (size_t)-1 || n_in == (size_t)-1) return 0;
  /* Forward mode seeds the knowns; adjoint mode seeds the unknowns. */
  return check_array_args(s, function, knowns, n_knowns, seed, n_seed, adjoint ? n_out : n_in) &&
         check_array_args(s, function, unknowns, n_unknowns, sensitivity, n_sensitivity,
                          adjoint ? n_in : n_out);
}

FMI3_Export fmi3Status fmi3GetDirectionalDerivative(
    fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,
    const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[], size_t nSeed,
    fmi3Float64 sensitivity[], size_t nSensitivity) {
  const char* fn = "fmi3GetDirectionalDerivative";
  fs_instance* s = fs_check(instance, fn, DERIVATIVE_MODES, FS_ANY_KIND);
  if (!s || !check_derivative_args(s, fn, unknowns, nUnknowns, knowns, nKnowns, seed, nSeed,
                                   sensitivity, nSensitivity, 0))
    return fmi3Error;
  return casadi_fmi3GetDirectionalDerivative(s->memory, unknowns, nUnknowns, knowns, nKnowns,
                                             seed, nSeed, sensitivity, nSensitivity);
}

FMI3_Export fmi3Status fmi3GetAdjointDerivative(
    fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,
    const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[], size_t nSeed,
    fmi3Float64 sensitivity[], size_t nSensitivity) {
  const char* fn = "fmi3GetAdjointDerivative";
  fs_instance* s = fs_check(instance, fn, DERIVATIVE_MODES, FS_ANY_KIND);
  if (!s || !check_derivative_args(s, fn, unknowns, nUnknowns, knowns, nKnowns, seed, nSeed,
                                   sensitivity, nSensitivity, 1))
    return fmi3Error;
  return casadi_fmi3GetAdjointDerivative(s->memory, unknowns, nUnknowns, knowns, nKnowns, seed,
                                         nSeed, sensitivity, nSensitivity);
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
