/* vh_roll_f64_host.c - the roll UKF and SMC in double precision (the reference build of the same
 * source, vh_roll_impl.inc). */
#include <math.h>
#include <stddef.h>
#include <stdint.h>

#include "vh_roll.h"

#define VH_ROLL_REAL double
#define VH_ROLL_NAME(n) n##_f64
#define VH_SQRT sqrt
#define VH_SIN sin
#define VH_COS cos
#define VH_ATAN atan
#define VH_FABS fabs
#include "vh_roll_impl.inc"
