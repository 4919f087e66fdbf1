/* Every scalar type in and out: T_output = T_input + T_parameter (Boolean: xor, String and
 * Binary: parameter followed by input; Enumeration: the larger); FMI 3.0 also an array port. */
#include "vars.h"
#define N_INDICATORS 0
#define N_STATES 0
#define CS_SUBSTEP_S 1.0

static int m_check(Model* m) { return 0; }
static void m_init(Model* m, double t, int* next_def, double* next_t) { *next_def = 0; }
static void m_update(Model* m, double t) {
  m->Float64_output = m->Float64_input + m->Float64_parameter;
  m->Int32_output = m->Int32_input + m->Int32_parameter;
  m->Boolean_output = m->Boolean_input ^ m->Boolean_parameter;
  m->Enumeration_output = m->Enumeration_input > m->Enumeration_parameter ? m->Enumeration_input : m->Enumeration_parameter;
  snprintf(m->String_output, sizeof(StrVal), "%s%s", m->String_parameter, m->String_input);
#if FMI_MAJOR == 3
  m->Float32_output = m->Float32_input + m->Float32_parameter;
  m->Int8_output = m->Int8_input + m->Int8_parameter;
  m->UInt8_output = m->UInt8_input + m->UInt8_parameter;
  m->Int16_output = m->Int16_input + m->Int16_parameter;
  m->UInt16_output = m->UInt16_input + m->UInt16_parameter;
  m->UInt32_output = m->UInt32_input + m->UInt32_parameter;
  m->Int64_output = m->Int64_input + m->Int64_parameter;
  m->UInt64_output = m->UInt64_input + m->UInt64_parameter;
  size_t np_ = m->Binary_parameter.n, ni = m->Binary_input.n;
  if (np_ + ni > sizeof m->Binary_output.d) ni = sizeof m->Binary_output.d - np_;
  memcpy(m->Binary_output.d, m->Binary_parameter.d, np_);
  memcpy(m->Binary_output.d + np_, m->Binary_input.d, ni);
  m->Binary_output.n = np_ + ni;
  for (int i = 0; i < 3; i++) m->Float64_vector_output[i] = 2 * m->Float64_vector_input[i];
#endif
}
static void m_der(Model* m, double t, double dx[]) {}
static void m_get_x(Model* m, double x[]) {}
static void m_set_x(Model* m, const double x[]) {}
static int m_event(Model* m, double t, int* next_def, double* next_t) { *next_def = 0; return 0; }
static int m_terminate(Model* m) { return 0; }
static void m_ind(Model* m, double t, double z[]) {}
