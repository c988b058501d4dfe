/* vh_roll_f32.c - the roll UKF and SMC in single precision (the ECU's build: a Cortex-M4F/M33
 * FPU does float32 in hardware). The code is vh_roll_impl.inc. */
#include <math.h>
#include <stddef.h>
#include <stdint.h>

/* single precision only, whichever build compiles this file (the extension, a target, the tests) */
#pragma GCC diagnostic error "-Wdouble-promotion"

#include "vh_mathf.h"
#include "vh_roll.h"

#define VH_ROLL_REAL float
#define VH_ROLL_NAME(n) n##_f32
#define VH_SQRT sqrtf
/* the project's own (c_core/common/vh_mathf.c): libm's sinf/atanf round differently on the ECU
 * (newlib) and the host (glibc); sqrtf and fabsf are exact on both */
#define VH_SIN vh_sinf
#define VH_COS vh_cosf
#define VH_ATAN vh_atanf
#define VH_FABS fabsf
#include "vh_roll_impl.inc"
