/* vh_roll_f32.c - the roll UKF and SMC in single precision (the ECU's build: a Cortex-M4F/M33
 * FPU does float32 in hardware). The code is vh_roll_impl.inc. */
#include <math.h>
#include <stddef.h>
#include <stdint.h>

/* single precision only, whichever build compiles this file (the extension, a target, the tests) */
#pragma GCC diagnostic error "-Wdouble-promotion"

#include "vh_roll.h"

#define VH_ROLL_REAL float
#define VH_ROLL_NAME(n) n##_f32
#define VH_SQRT sqrtf
#define VH_SIN sinf
#define VH_COS cosf
#define VH_ATAN atanf
#define VH_FABS fabsf
#include "vh_roll_impl.inc"
