/* vh_tc.c - see vh_tc.h. */
#include "vh_tc.h"

#define CF_EQ9(r) ((-1.695 * (r) * (r) + 0.3 * (r) + 1.874) * 1e-3) /* eq. 9: C_f(r) */
#define DCF_EQ9(r) ((-3.39 * (r) + 0.3) * 1e-3)                     /* dC_f/dr */
#define BLEND_S0 (1.0 - VH_TC_RC)
/* c(s) = a s + b s^2 with s = 1 - r: c(S0) = C_f(RC) and -c'(S0) = C_f'(RC) */
#define BLEND_B (-(CF_EQ9(VH_TC_RC) + DCF_EQ9(VH_TC_RC) * BLEND_S0) / (BLEND_S0 * BLEND_S0))
#define BLEND_A (-DCF_EQ9(VH_TC_RC) - 2.0 * BLEND_B * BLEND_S0)

void vh_tc_torques(double we, double wt, double *tp, double *ti)
{
    const double wec = we > 1e-3 ? we : 1e-3; /* keeps r finite; the torques ~we^2 vanish there */
    double r = wt / wec;
    if (!(r > 0.0)) {
        r = 0.0; /* turbine at rest or (shaft wind-up) slightly backwards: stall */
    }
    if (r <= VH_TC_RC) {
        const double rt = r < 0.85 ? -1.4 * r + 2.2 : 0.99; /* eq. 9: R_t(r) */
        *tp = CF_EQ9(r) * wec * wec;                        /* eq. 9: T_p = C_f w_e^2 */
        *ti = rt * *tp;                                     /* eq. 9: T_i = R_t T_p */
    } else if (r <= 1.0) {
        const double s = 1.0 - r;
        *tp = (BLEND_A * s + BLEND_B * s * s) * wec * wec;
        *ti = 0.99 * *tp; /* eq. 9's coupling-range torque ratio */
    } else {
        *tp = BLEND_A * (1.0 - r) * wec * wec; /* overrun: -a (w_t - w_e) w_e */
        *ti = *tp;
    }
}

double vh_tc_max_slope(void)
{
    return BLEND_A;
}
