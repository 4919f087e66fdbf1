/* featherstar FMI 3.0 shell: Model Exchange entry points.
 *
 * CasADi's versions write nContinuousStates values without checking the count, return
 * fmi3Fatal from fmi3GetEventIndicators when the model has no event indicators (fmpy's solvers
 * call it unconditionally) and leave fmi3CompletedIntegratorStep's outputs unwritten. These
 * wrappers check mode, sizes and pointers and fill those gaps before delegating. Non-finite
 * states are refused (fmi3Error); non-finite derivatives are never returned with fmi3OK.
 */
#include <math.h>

#include "fmi3Functions.h"
#include "fmi3_shell.h"

#define ME_EVAL_MODES (FS_INITIALIZATION | FS_EVENT | FS_CONTINUOUS_TIME | FS_TERMINATED)

static int check_states_array(const fs_instance* s, const char* function, const void* array,
                              size_t n, size_t expected) {
  if (n != expected) {
    fs_error(s, "%s: got %zu elements, the model has %zu", function, n, expected);
    return 0;
  }
  if (n && !array) {
    fs_error(s, "%s: NULL array", function);
    return 0;
  }
  return 1;
}

FMI3_Export fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance instance) {
  fs_instance* s = fs_check(instance, "fmi3EnterContinuousTimeMode", FS_EVENT, FS_MODEL_EXCHANGE);
  if (!s) return fmi3Error;
  if (casadi_fmi3EnterContinuousTimeMode(s->memory) != fmi3OK) return fmi3Error;
  s->dyn.mode = FS_CONTINUOUS_TIME;
  return fmi3OK;
}

FMI3_Export fmi3Status fmi3CompletedIntegratorStep(fmi3Instance instance,
                                                   fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                                   fmi3Boolean* enterEventMode,
                                                   fmi3Boolean* terminateSimulation) {
  fs_instance* s = fs_check(instance, "fmi3CompletedIntegratorStep", FS_CONTINUOUS_TIME, FS_MODEL_EXCHANGE);
  if (!s) return fmi3Error;
  if (!enterEventMode || !terminateSimulation) {
    fs_error(s, "fmi3CompletedIntegratorStep: NULL argument");
    return fmi3Error;
  }
  *enterEventMode = fmi3False;
  *terminateSimulation = fmi3False;
  return casadi_fmi3CompletedIntegratorStep(s->memory, noSetFMUStatePriorToCurrentPoint,
                                            enterEventMode, terminateSimulation);
}

FMI3_Export fmi3Status fmi3SetTime(fmi3Instance instance, fmi3Float64 time) {
  fs_instance* s = fs_check(instance, "fmi3SetTime", FS_EVENT | FS_CONTINUOUS_TIME, FS_MODEL_EXCHANGE);
  if (!s) return fmi3Error;
  if (!isfinite(time)) {
    fs_error(s, "fmi3SetTime: time is not finite");
    return fmi3Error;
  }
  s->dyn.time = time;
  /* CasADi's fmi3SetTime keeps its cached outputs; a time-dependent model needs them redone. */
  s->model->set_states(s->memory, time, NULL);
  return fmi3OK;
}

FMI3_Export fmi3Status fmi3SetContinuousStates(fmi3Instance instance, const fmi3Float64 continuousStates[],
                                               size_t nContinuousStates) {
  const char* fn = "fmi3SetContinuousStates";
  fs_instance* s = fs_check(instance, fn, FS_CONTINUOUS_TIME, FS_MODEL_EXCHANGE);
  long bad;
  if (!s || !check_states_array(s, fn, continuousStates, nContinuousStates, s->model->n_x))
    return fmi3Error;
  bad = fs_first_non_finite(continuousStates, nContinuousStates);
  if (bad >= 0) {
    fs_error(s, "%s: state '%s' = %g refused: not finite", fn, s->model->var_name[s->model->x_vr[bad]],
             continuousStates[bad]);
    return fmi3Error;
  }
  return casadi_fmi3SetContinuousStates(s->memory, continuousStates, nContinuousStates);
}

FMI3_Export fmi3Status fmi3GetContinuousStates(fmi3Instance instance, fmi3Float64 continuousStates[],
                                               size_t nContinuousStates) {
  const char* fn = "fmi3GetContinuousStates";
  fs_instance* s = fs_check(instance, fn, ME_EVAL_MODES, FS_MODEL_EXCHANGE);
  if (!s || !check_states_array(s, fn, continuousStates, nContinuousStates, s->model->n_x))
    return fmi3Error;
  s->model->get_states(s->memory, continuousStates);
  return fmi3OK;
}

FMI3_Export fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance instance, fmi3Float64 derivatives[],
                                                         size_t nContinuousStates) {
  const char* fn = "fmi3GetContinuousStateDerivatives";
  fs_instance* s = fs_check(instance, fn, ME_EVAL_MODES, FS_MODEL_EXCHANGE);
  if (!s || !check_states_array(s, fn, derivatives, nContinuousStates, s->model->n_x))
    return fmi3Error;
  long bad;
  if (casadi_fmi3GetContinuousStateDerivatives(s->memory, derivatives, nContinuousStates) != fmi3OK) {
    fs_error(s, "%s: model evaluation failed at t=%g", fn, s->dyn.time);
    return fmi3Error;
  }
  /* Discard, as FMI 3.0 asks of a model outside its domain: the integrator may retry shorter. */
  bad = fs_first_non_finite(derivatives, nContinuousStates);
  if (bad >= 0) {
    fs_discard(s, "%s: der(%s) is not finite (%g) at t=%.10g", fn,
               s->model->var_name[s->model->x_vr[bad]], derivatives[bad], s->dyn.time);
    return fmi3Discard;
  }
  return fmi3OK;
}

FMI3_Export fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance instance, fmi3Float64 nominals[],
                                                         size_t nContinuousStates) {
  const char* fn = "fmi3GetNominalsOfContinuousStates";
  fs_instance* s = fs_check(instance, fn, ME_EVAL_MODES | FS_INSTANTIATED, FS_MODEL_EXCHANGE);
  if (!s || !check_states_array(s, fn, nominals, nContinuousStates, s->model->n_x))
    return fmi3Error;
  return casadi_fmi3GetNominalsOfContinuousStates(s->memory, nominals, nContinuousStates);
}

FMI3_Export fmi3Status fmi3GetEventIndicators(fmi3Instance instance, fmi3Float64 eventIndicators[],
                                              size_t nEventIndicators) {
  const char* fn = "fmi3GetEventIndicators";
  fs_instance* s = fs_check(instance, fn, ME_EVAL_MODES, FS_MODEL_EXCHANGE);
  if (!s || !check_states_array(s, fn, eventIndicators, nEventIndicators, s->model->n_zero))
    return fmi3Error;
  if (nEventIndicators == 0) return fmi3OK;
  return casadi_fmi3GetEventIndicators(s->memory, eventIndicators, nEventIndicators);
}

FMI3_Export fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance instance, size_t* nContinuousStates) {
  fs_instance* s = fs_check(instance, "fmi3GetNumberOfContinuousStates", FS_ANY_MODE, FS_ANY_KIND);
  if (!s || !nContinuousStates) return fmi3Error;
  *nContinuousStates = s->model->n_x;
  return fmi3OK;
}

FMI3_Export fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance instance, size_t* nEventIndicators) {
  fs_instance* s = fs_check(instance, "fmi3GetNumberOfEventIndicators", FS_ANY_MODE, FS_ANY_KIND);
  if (!s || !nEventIndicators) return fmi3Error;
  *nEventIndicators = s->model->n_zero;
  return fmi3OK;
}
