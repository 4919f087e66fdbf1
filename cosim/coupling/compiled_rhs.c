/* The strong coupling's right-hand side as a program of C calls (featherstar.cosim.compiled_rhs).
 *
 * CVODE calls fs_rhs(t, y, ydot, program) directly: set the time and the states of every unit,
 * walk the schedule (copy driving outputs into inputs, set inputs, get outputs, evaluate compiled
 * CasADi functions of time), get the derivatives. Everything the schedule holds as data runs
 * here without entering Python; a step that cannot (a Python block, an algebraic loop, ports of
 * other types) is a callback into Python, op FS_PYTHON.
 *
 * Statuses follow FMI (0 OK, 1 Warning, 2 Discard, 3 Error, 4 Fatal): Discard makes the right-hand
 * side fail recoverably (CVODE retries with a smaller step, as the FMI standard asks of an
 * importer), anything worse unrecoverably. The failing op, its status and the time are kept in
 * the program so that Python can name the block and the function.
 */
#include <stddef.h>

typedef double* (*fs_array_fn)(void* nvector);
typedef int (*fs_set_time_fn)(void* instance, double t);
typedef int (*fs_states_fn)(void* instance, double* x, size_t n);
typedef int (*fs_float64_fn)(void* instance, const unsigned* vr, size_t n_vr, double* values, size_t n_values);
typedef int (*fs_real2_fn)(void* instance, const unsigned* vr, size_t n_vr, double* values);
typedef int (*fs_casadi_fn)(const double** arg, double** res, long long* iw, double* w, int mem);
typedef int (*fs_python_fn)(double t);

enum {
  FS_SET_TIME = 1,
  FS_SET_STATES = 2,
  FS_GET_DERIVATIVES = 3,
  FS_COPY = 4,
  FS_SET_FLOAT64 = 5, /* fmi3SetFloat64 */
  FS_GET_FLOAT64 = 6, /* fmi3GetFloat64 */
  FS_SET_REAL = 7,    /* fmi2SetReal */
  FS_GET_REAL = 8,    /* fmi2GetReal */
  FS_CASADI = 9,      /* outputs = f(t, parameters), CasADi's generated C */
  FS_PYTHON = 10
};

typedef struct {
  int kind;
  void* fn;
  void* instance;
  const unsigned* vr; /* value references */
  size_t n;           /* values, or states */
  double* values;     /* contiguous inputs to set / outputs to get */
  size_t offset;      /* first state in y / ydot */
  const double* src;  /* FS_COPY: *dst = *src */
  double* dst;
  const double** arg; /* FS_CASADI: arg[0] points at t_cell */
  double** res;
  long long* iw;
  double* w;
  double* t_cell;
} fs_op;

typedef struct {
  fs_op* ops;
  int n_ops;
  fs_array_fn array; /* N_VGetArrayPointer_Serial */
  int failed_op;     /* -1: none */
  int failed_status;
  double failed_t;
  long long calls;
} fs_program;

static int run(fs_program* p, double t, double* y, double* ydot, int derivatives) {
  for (int i = 0; i < p->n_ops; ++i) {
    fs_op* op = &p->ops[i];
    int status;
    switch (op->kind) {
      case FS_SET_TIME:
        status = ((fs_set_time_fn)op->fn)(op->instance, t);
        break;
      case FS_SET_STATES:
        status = ((fs_states_fn)op->fn)(op->instance, y + op->offset, op->n);
        break;
      case FS_GET_DERIVATIVES:
        if (!derivatives) continue;
        status = ((fs_states_fn)op->fn)(op->instance, ydot + op->offset, op->n);
        break;
      case FS_COPY:
        *op->dst = *op->src;
        continue;
      case FS_SET_FLOAT64:
      case FS_GET_FLOAT64:
        status = ((fs_float64_fn)op->fn)(op->instance, op->vr, op->n, op->values, op->n);
        break;
      case FS_SET_REAL:
      case FS_GET_REAL:
        status = ((fs_real2_fn)op->fn)(op->instance, op->vr, op->n, op->values);
        break;
      case FS_CASADI:
        *op->t_cell = t;
        status = ((fs_casadi_fn)op->fn)(op->arg, op->res, op->iw, op->w, 0) ? 3 : 0;
        break;
      case FS_PYTHON:
        status = ((fs_python_fn)op->fn)(t);
        break;
      default:
        status = 4;
    }
    if (status > 1) {
      p->failed_op = i;
      p->failed_status = status;
      p->failed_t = t;
      return status == 2 ? 1 : -1;
    }
  }
  return 0;
}

/* CVRhsFn */
int fs_rhs(double t, void* y, void* ydot, void* user_data) {
  fs_program* p = (fs_program*)user_data;
  p->calls++;
  return run(p, t, p->array(y), p->array(ydot), 1);
}

/* Every unit at (t, y) with the program's inputs set and outputs evaluated, no derivatives: the
 * master's output points. Returns 0, or the status of the op that failed. */
int fs_point(fs_program* p, double t, double* y) {
  int flag = run(p, t, y, NULL, 0);
  return flag == 0 ? 0 : p->failed_status;
}
