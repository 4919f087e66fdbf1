/* Shared declarations of featherstar's hand-written test FMUs (tests/cosim/fmu_c).
 * A model file defines `Model`, includes the generated variable table (vars.h, written by
 * tests/cosim/c_fmus.py from the same spec as modelDescription.xml) and the m_* functions;
 * fmi2_shell.c / fmi3_shell.c implement the FMI API around it (variable access by type with the
 * standard's mode rules, event mode, Model Exchange, and Co-Simulation by RK4 substeps that
 * stop at every time event). */
#ifndef SHELL_H
#define SHELL_H
#include <stddef.h>
#include <stdint.h>
#include <string.h>
#include <math.h>
#include <stdio.h>

typedef enum { F64, F32, I8, U8, I16, U16, I32, U32, I64, U64, BOOL, STR, BIN } VType;
typedef enum { PAR_FIXED, PAR_TUNABLE, INPUT, OUTPUT, LOCAL } VCaus;
typedef struct { unsigned vr; const char* name; VType type; VCaus caus; int discrete; size_t n; size_t offset; } VarDef;
typedef struct { size_t n; unsigned char d[32]; } BinVal;
typedef char StrVal[64];

/* a model reports a problem through this (the shell forwards it to the FMU's logger) */
static char m_message[256];
#endif
