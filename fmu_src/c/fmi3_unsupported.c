/* featherstar FMI 3.0 shell: entry points the exported models have no use for.
 *
 * The models only declare Float64 variables, no clocks and no structural parameters, and
 * CasADi answers all of these with fmi3Fatal, which tells an importer the whole process is
 * corrupt. Here they fail politely instead: an empty request succeeds, anything else is an
 * fmi3Error naming the function, so one misdirected call does not take a co-simulation down.
 */
#include "fmi3Functions.h"
#include "fmi3_shell.h"

static fmi3Status no_such_variables(fmi3Instance instance, const char* function, size_t n) {
  fs_instance* s = fs_check(instance, function, FS_ANY_MODE, FS_ANY_KIND);
  if (!s) return fmi3Error;
  if (n == 0) return fmi3OK;
  fs_error(s, "%s: the model has no variables of this type", function);
  return fmi3Error;
}

static fmi3Status not_supported(fmi3Instance instance, const char* function, const char* why) {
  fs_instance* s = fs_check(instance, function, FS_ANY_MODE, FS_ANY_KIND);
  if (s) fs_error(s, "%s: not supported (%s)", function, why);
  return fmi3Error;
}

#define TYPED_ACCESSORS(T)                                                                    \
  FMI3_Export fmi3Status fmi3Get##T(fmi3Instance instance, const fmi3ValueReference vr[],    \
                                    size_t nvr, fmi3##T values[], size_t nValues) {          \
    (void)vr, (void)values, (void)nValues;                                                   \
    return no_such_variables(instance, "fmi3Get" #T, nvr);                                   \
  }                                                                                           \
  FMI3_Export fmi3Status fmi3Set##T(fmi3Instance instance, const fmi3ValueReference vr[],    \
                                    size_t nvr, const fmi3##T values[], size_t nValues) {    \
    (void)vr, (void)values, (void)nValues;                                                   \
    return no_such_variables(instance, "fmi3Set" #T, nvr);                                   \
  }

TYPED_ACCESSORS(Float32)
TYPED_ACCESSORS(Int8)
TYPED_ACCESSORS(UInt8)
TYPED_ACCESSORS(Int16)
TYPED_ACCESSORS(UInt16)
TYPED_ACCESSORS(Int32)
TYPED_ACCESSORS(UInt32)
TYPED_ACCESSORS(Int64)
TYPED_ACCESSORS(UInt64)
TYPED_ACCESSORS(Boolean)
TYPED_ACCESSORS(String)

FMI3_Export fmi3Status fmi3GetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                     size_t valueSizes[], fmi3Binary values[], size_t nValues) {
  (void)vr, (void)valueSizes, (void)values, (void)nValues;
  return no_such_variables(instance, "fmi3GetBinary", nvr);
}

FMI3_Export fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                     const size_t valueSizes[], const fmi3Binary values[],
                                     size_t nValues) {
  (void)vr, (void)valueSizes, (void)values, (void)nValues;
  return no_such_variables(instance, "fmi3SetBinary", nvr);
}

FMI3_Export fmi3Status fmi3GetClock(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                    fmi3Clock values[]) {
  (void)vr, (void)values;
  return no_such_variables(instance, "fmi3GetClock", nvr);
}

FMI3_Export fmi3Status fmi3SetClock(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                    const fmi3Clock values[]) {
  (void)vr, (void)values;
  return no_such_variables(instance, "fmi3SetClock", nvr);
}

#define NO_CLOCKS(name, ...)                                                   \
  FMI3_Export fmi3Status name(fmi3Instance instance, __VA_ARGS__) {            \
    return not_supported(instance, #name, "the model has no clocks");          \
  }

NO_CLOCKS(fmi3GetIntervalDecimal, const fmi3ValueReference vr[], size_t nvr, fmi3Float64 i[],
          fmi3IntervalQualifier q[])
NO_CLOCKS(fmi3GetIntervalFraction, const fmi3ValueReference vr[], size_t nvr, fmi3UInt64 c[],
          fmi3UInt64 r[], fmi3IntervalQualifier q[])
NO_CLOCKS(fmi3GetShiftDecimal, const fmi3ValueReference vr[], size_t nvr, fmi3Float64 sh[])
NO_CLOCKS(fmi3GetShiftFraction, const fmi3ValueReference vr[], size_t nvr, fmi3UInt64 c[],
          fmi3UInt64 r[])
NO_CLOCKS(fmi3SetIntervalDecimal, const fmi3ValueReference vr[], size_t nvr, const fmi3Float64 i[])
NO_CLOCKS(fmi3SetIntervalFraction, const fmi3ValueReference vr[], size_t nvr, const fmi3UInt64 c[],
          const fmi3UInt64 r[])
NO_CLOCKS(fmi3SetShiftDecimal, const fmi3ValueReference vr[], size_t nvr, const fmi3Float64 sh[])
NO_CLOCKS(fmi3SetShiftFraction, const fmi3ValueReference vr[], size_t nvr, const fmi3UInt64 c[],
          const fmi3UInt64 r[])
NO_CLOCKS(fmi3ActivateModelPartition, fmi3ValueReference clockReference, fmi3Float64 activationTime)

FMI3_Export fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance instance) {
  return not_supported(instance, "fmi3EvaluateDiscreteStates", "the model has no clocks");
}

FMI3_Export fmi3Status fmi3EnterConfigurationMode(fmi3Instance instance) {
  return not_supported(instance, "fmi3EnterConfigurationMode", "the model has no structural parameters");
}

FMI3_Export fmi3Status fmi3ExitConfigurationMode(fmi3Instance instance) {
  return not_supported(instance, "fmi3ExitConfigurationMode", "the model has no structural parameters");
}

FMI3_Export fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance instance,
                                                           fmi3ValueReference valueReference,
                                                           size_t* nDependencies) {
  (void)valueReference, (void)nDependencies;
  return not_supported(instance, "fmi3GetNumberOfVariableDependencies",
                       "read ModelStructure in modelDescription.xml");
}

FMI3_Export fmi3Status fmi3GetVariableDependencies(
    fmi3Instance instance, fmi3ValueReference dependent, size_t elementIndicesOfDependent[],
    fmi3ValueReference independents[], size_t elementIndicesOfIndependents[],
    fmi3DependencyKind dependencyKinds[], size_t nDependencies) {
  (void)dependent, (void)elementIndicesOfDependent, (void)independents;
  (void)elementIndicesOfIndependents, (void)dependencyKinds, (void)nDependencies;
  return not_supported(instance, "fmi3GetVariableDependencies",
                       "read ModelStructure in modelDescription.xml");
}

FMI3_Export fmi3Status fmi3GetOutputDerivatives(fmi3Instance instance,
                                                const fmi3ValueReference valueReferences[],
                                                size_t nValueReferences, const fmi3Int32 orders[],
                                                fmi3Float64 values[], size_t nValues) {
  (void)valueReferences, (void)nValueReferences, (void)orders, (void)values, (void)nValues;
  return not_supported(instance, "fmi3GetOutputDerivatives", "maxOutputDerivativeOrder is 0");
}

/* A snapshot holds CasADi's memory verbatim, pointers included: it cannot leave the process. */
FMI3_Export fmi3Status fmi3SerializedFMUStateSize(fmi3Instance instance, fmi3FMUState FMUState,
                                                  size_t* size) {
  (void)FMUState, (void)size;
  return not_supported(instance, "fmi3SerializedFMUStateSize", "canSerializeFMUState is false");
}

FMI3_Export fmi3Status fmi3SerializeFMUState(fmi3Instance instance, fmi3FMUState FMUState,
                                             fmi3Byte serializedState[], size_t size) {
  (void)FMUState, (void)serializedState, (void)size;
  return not_supported(instance, "fmi3SerializeFMUState", "canSerializeFMUState is false");
}

FMI3_Export fmi3Status fmi3DeserializeFMUState(fmi3Instance instance, const fmi3Byte serializedState[],
                                               size_t size, fmi3FMUState* FMUState) {
  (void)serializedState, (void)size, (void)FMUState;
  return not_supported(instance, "fmi3DeserializeFMUState", "canSerializeFMUState is false");
}

FMI3_Export fmi3Instance fmi3InstantiateScheduledExecution(
    fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath,
    fmi3Boolean visible, fmi3Boolean loggingOn, fmi3InstanceEnvironment instanceEnvironment,
    fmi3LogMessageCallback logMessage, fmi3ClockUpdateCallback clockUpdate,
    fmi3LockPreemptionCallback lockPreemption, fmi3UnlockPreemptionCallback unlockPreemption) {
  (void)instanceName, (void)instantiationToken, (void)resourcePath, (void)visible;
  (void)loggingOn, (void)clockUpdate, (void)lockPreemption, (void)unlockPreemption;
  if (logMessage)
    logMessage(instanceEnvironment, fmi3Error, "logStatusError",
               "fmi3InstantiateScheduledExecution: not supported (Model Exchange and Co-Simulation only)");
  return NULL;
}
