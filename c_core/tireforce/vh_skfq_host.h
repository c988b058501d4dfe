/* vh_skfq_host.h - host-side (off-line) helpers of the fixed-point SKFMEC: its integer constants
 * from a double configuration, and double inputs quantised to its formats. Not flashed.
 */
#ifndef VH_SKFQ_HOST_H
#define VH_SKFQ_HOST_H

#include <stddef.h>
#include <stdint.h>

#include "vh_skf.h"
#include "vh_skfq.h"

/* The fixed-point filter's integer constants (vh_skfq.h) from a configuration with scaled = 1:
 * VH_OK, or VH_EINVAL if the configuration is invalid, not scaled, or a constant does not fit. */
int vh_skfq_params_from_config(const vh_skf_config_t *cfg, vh_skfq_params_t *prm);
/* The calibration's two roundings of a constant (vh_tfa_host.c uses them too): v = m 2^-e with
 * |m| in [2^30, 2^31), rounded half up, 0 staying 0 (vh_fix_kmul's vh_fix_k_t); and
 * round_half_up(v 2^frac) as int32. A non-finite v, or one out of the format: *ok = 0. */
vh_fix_k_t vh_skfq_kconst(double v, int *ok);
int32_t vh_skfq_qconst(double v, int frac, int *ok);
/* Inputs to the fixed-point formats (round half up, saturating): u[n*13] doubles as
 * vh_skf_input_t rows -> q[n*13] int32 as vh_skfq_input_t rows. */
void vh_skfq_quantise_inputs(size_t n, const double *u, int32_t *q);

#endif /* VH_SKFQ_HOST_H */
