/* featherstar FMI 3.0 shell: getting and setting values, and their derivatives.
 *
 * Every value reference is checked against the model's table before CasADi's code sees it.
 * Values are checked too: a parameter must lie in its physical range (from the Model), inputs
 * and states must be finite, and a NaN result is never handed out with fmi3OK. Start values of
 * states, inputs and parameters can be read before initialization, as FMI 3.0 allows.
 */
#include <math.h>

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

/* Number of values the references address, or (size_t)-1 after logging the first bad one. */
size_t fs_count_values(const fs_instance* s, const char* function,
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

int fs_check_array_args(const fs_instance* s, const char* function, const void* vr,
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
  n = fs_count_values(s, "fmi3GetFloat64", valueReferences, nValueReferences, 1);
  if (!fs_check_array_args(s, "fmi3GetFloat64", valueReferences, nValueReferences, values, nValues, n))
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
  n = fs_count_values(s, "fmi3SetFloat64", valueReferences, nValueReferences, 0);
  if (!fs_check_array_args(s, "fmi3SetFloat64", valueReferences, nValueReferences, values, nValues, n))
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
  n_out = fs_count_values(s, function, unknowns, n_unknowns, 0);
  n_in = fs_count_values(s, function, knowns, n_knowns, 0);
  if (n_out == (size_t)-1 || n_in == (size_t)-1) return 0;
  /* Forward mode seeds the knowns; adjoint mode seeds the unknowns. */
  return fs_check_array_args(s, function, knowns, n_knowns, seed, n_seed, adjoint ? n_out : n_in) &&
         fs_check_array_args(s, function, unknowns, n_unknowns, sensitivity, n_sensitivity,
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
