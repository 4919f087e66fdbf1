/* Shared declarations of the featherstar FMI 3.0 shell.
 *
 * CasADi's generated <id>_wrap.c is compiled with FMI3_FUNCTION_PREFIX=casadi_, so its entry
 * points become casadi_fmi3...; the shell (fmi3_shell.c and the other fmi3_*.c beside it)
 * defines the real fmi3... symbols around them. The generated code knows its own memory layout
 * and variable tables but hides them in one translation unit, so fmu_src/export.py appends
 * fs_model_info() to the wrap source: the only bridge between the two, described by fs_model.
 */
#ifndef FEATHERSTAR_FMI3_SHELL_H
#define FEATHERSTAR_FMI3_SHELL_H

#include <stddef.h>
#include "fmi3FunctionTypes.h"

/* The valid values of one parameter (fmu_src.model.Parameter): [min, max], the lower bound
 * strict when exclusive_min; when n_choices > 0 only the listed values are valid. */
typedef struct {
  double min, max;
  int exclusive_min;
  size_t n_choices;
  const double* choices;
  const char* unit;
} fs_limit;

typedef struct {
  const char* instantiation_token; /* as in modelDescription.xml */
  size_t memory_size; /* sizeof(casadi_fmi_memory): what an FMU state snapshot copies */
  size_t n_var;       /* value references 1 .. n_var-1 index CasADi's variable table */
  size_t n_x, n_u, n_p, n_zero;
  const size_t* var_offset; /* n_var + 1 entries: element range of each variable */
  const fmi3ValueReference* x_vr;
  const fmi3ValueReference* u_vr;
  const fmi3ValueReference* p_vr;
  size_t n_y;
  const fmi3ValueReference* y_vr; /* the outputs */
  const fs_limit* limit;          /* n_var entries, by value reference; set for parameters */
  const char* const* var_name;    /* n_var entries, by value reference (for log messages) */
  /* xdot = f(t, x, u, p) with u, p as currently set; nonzero when the generated code fails */
  int (*rhs)(void* memory, double t, const double* x, double* xdot);
  void (*get_states)(const void* memory, double* x);
  /* writes t and (if x is not NULL) the states; outputs are re-evaluated on the next get */
  void (*set_states)(void* memory, double t, const double* x);
  /* the current value of every variable, by value reference, without evaluating the model */
  const double* (*values)(const void* memory);
  /* evaluates outputs and derivatives at the current t, x, u, p; nonzero when the code fails */
  int (*evaluate)(void* memory);
} fs_model;

const fs_model* fs_model_info(void);

/* Modes are bits so that each entry point states the set of modes it accepts as one mask. */
typedef enum {
  FS_INSTANTIATED = 1 << 0,
  FS_INITIALIZATION = 1 << 1,
  FS_EVENT = 1 << 2,
  FS_CONTINUOUS_TIME = 1 << 3,
  FS_STEP = 1 << 4,
  FS_TERMINATED = 1 << 5,
  /* fmi3DoStep returned fmi3Error: the instance may only be inspected, rolled back or reset */
  FS_FAILED = 1 << 6
} fs_mode;

#define FS_ANY_MODE 0x7F

typedef enum { FS_MODEL_EXCHANGE = 1, FS_CO_SIMULATION = 2 } fs_kind;
#define FS_ANY_KIND (FS_MODEL_EXCHANGE | FS_CO_SIMULATION)

typedef enum { FS_VR_UNKNOWN, FS_VR_STATE, FS_VR_INPUT, FS_VR_PARAMETER, FS_VR_CALCULATED } fs_vr_kind;

#define FS_TIME_VR ((fmi3ValueReference)4294967295u)

/* What an FMU state snapshot restores besides CasADi's memory and the first-stage derivative. */
typedef struct {
  fs_mode mode;
  double time;
  double rtol, atol;
  double h;         /* Dormand-Prince step carried between doStep calls; 0 = not chosen yet */
  double err_old;   /* PI step controller memory */
  int fsal_valid;   /* work[0 .. n_x) holds f(time, x, u, p) for the current x, u, p */
} fs_dynamic;

typedef struct {
  const fs_model* model;
  fmi3Instance memory; /* CasADi's instance */
  fs_kind kind;
  int event_mode_used;
  char* name;
  fmi3InstanceEnvironment environment;
  fmi3LogMessageCallback log;
  unsigned char* vr_kind; /* fs_vr_kind per value reference below n_var */
  double* work;           /* Dormand-Prince stages, fs_work_size(n_x) doubles; k1 first */
  fs_dynamic dyn;
} fs_instance;

#define FS_DEFAULT_RTOL 1e-6

size_t fs_work_size(size_t n_x);
/* Logs an fmi3Error message through the importer's logMessage callback, if any. */
void fs_error(const fs_instance* s, const char* fmt, ...) __attribute__((format(printf, 2, 3)));
/* Logs an fmi3Discard message: a result was not finite, the importer may retry (shorter step). */
void fs_discard(const fs_instance* s, const char* fmt, ...) __attribute__((format(printf, 2, 3)));
/* The instance if it exists, is of an allowed kind and in an allowed mode; else logs and NULL. */
fs_instance* fs_check(fmi3Instance instance, const char* function, unsigned modes, unsigned kinds);
const char* fs_mode_name(fs_mode mode);
/* Evaluates the model at the current point; why an output is not finite there, or NULL. */
const char* fs_outputs_problem(fs_instance* s, char* why, size_t size);
/* Number of values the references address, or (size_t)-1 after logging the first bad one. */
size_t fs_count_values(const fs_instance* s, const char* function, const fmi3ValueReference vr[],
                       size_t n_vr, int allow_time);
/* Whether an array argument holds `expected` values; logs why not. */
int fs_check_array_args(const fs_instance* s, const char* function, const void* vr, size_t n_vr,
                        const void* values, size_t n_values, size_t expected);
/* Index of the first non-finite value, or -1 when all n are finite. */
long fs_first_non_finite(const double* values, size_t n);

/* CasADi's entry points, renamed by FMI3_FUNCTION_PREFIX=casadi_ in the wrap source. */
fmi3InstantiateModelExchangeTYPE casadi_fmi3InstantiateModelExchange;
fmi3FreeInstanceTYPE casadi_fmi3FreeInstance;
fmi3EnterInitializationModeTYPE casadi_fmi3EnterInitializationMode;
fmi3ExitInitializationModeTYPE casadi_fmi3ExitInitializationMode;
fmi3EnterEventModeTYPE casadi_fmi3EnterEventMode;
fmi3TerminateTYPE casadi_fmi3Terminate;
fmi3ResetTYPE casadi_fmi3Reset;
fmi3GetFloat64TYPE casadi_fmi3GetFloat64;
fmi3SetFloat64TYPE casadi_fmi3SetFloat64;
fmi3GetDirectionalDerivativeTYPE casadi_fmi3GetDirectionalDerivative;
fmi3GetAdjointDerivativeTYPE casadi_fmi3GetAdjointDerivative;
fmi3UpdateDiscreteStatesTYPE casadi_fmi3UpdateDiscreteStates;
fmi3EnterContinuousTimeModeTYPE casadi_fmi3EnterContinuousTimeMode;
fmi3CompletedIntegratorStepTYPE casadi_fmi3CompletedIntegratorStep;
fmi3SetTimeTYPE casadi_fmi3SetTime;
fmi3SetContinuousStatesTYPE casadi_fmi3SetContinuousStates;
fmi3GetContinuousStateDerivativesTYPE casadi_fmi3GetContinuousStateDerivatives;
fmi3GetEventIndicatorsTYPE casadi_fmi3GetEventIndicators;
fmi3GetContinuousStatesTYPE casadi_fmi3GetContinuousStates;
fmi3GetNominalsOfContinuousStatesTYPE casadi_fmi3GetNominalsOfContinuousStates;

#endif
