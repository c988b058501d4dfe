/* Drives the roll UKF and SMC (both precisions) hard under ASan + UBSan: random states,
 * measurements, masks, NaN/Inf inputs, an indefinite and a NaN covariance. */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "vh_roll.h"

static uint64_t rng_s = 0x9E3779B97F4A7C15u;
static double urand(void)
{
    rng_s ^= rng_s << 13;
    rng_s ^= rng_s >> 7;
    rng_s ^= rng_s << 17;
    return (double)(rng_s >> 11) / 9007199254740992.0;
}

#define DRIVE(SFX, REAL)                                                                              \
    static int drive_##SFX(void)                                                                      \
    {                                                                                                 \
        vh_roll_params_t prm;                                                                         \
        vh_roll_smc_params_t sp;                                                                      \
        vh_roll_ukf_##SFX f;                                                                          \
        vh_roll_smc_##SFX c;                                                                          \
        REAL u[VH_ROLL_NU], z[VH_ROLL_NZ];                                                            \
        int k, i;                                                                                     \
        vh_roll_params_default(&prm);                                                                 \
        vh_roll_smc_params_default(&sp, &prm);                                                        \
        if (vh_roll_ukf_init_##SFX(&f, &prm) != 0 || vh_roll_smc_init_##SFX(&c, &sp) != 0) {          \
            return 1;                                                                                 \
        }                                                                                             \
        if (vh_roll_ukf_init_##SFX(NULL, &prm) != -1 || vh_roll_smc_init_##SFX(&c, NULL) != -1) {     \
            return 1;                                                                                 \
        }                                                                                             \
        for (k = 0; k < 4000; ++k) {                                                                  \
            uint32_t mask = (uint32_t)(urand() * 16384.0);                                            \
            u[0] = (REAL)(0.1 * (urand() - 0.5));                                                     \
            u[1] = (REAL)(40.0 * urand());                                                            \
            u[2] = (REAL)(8000.0 * (urand() - 0.5));                                                  \
            u[3] = (REAL)(8000.0 * (urand() - 0.5));                                                  \
            for (i = 0; i < VH_ROLL_NZ; ++i) {                                                        \
                z[i] = (REAL)(0.01 * (urand() - 0.5));                                                \
            }                                                                                         \
            if (k % 97 == 0) {                                                                        \
                z[k % VH_ROLL_NZ] = (REAL)NAN;                                                        \
            }                                                                                         \
            if (k % 211 == 0) {                                                                       \
                u[k % VH_ROLL_NU] = (REAL)INFINITY;                                                   \
            }                                                                                         \
            if (k % 500 == 250) {                                                                     \
                for (i = 0; i < VH_ROLL_NX * VH_ROLL_NX; ++i) {                                       \
                    f.P[i] = (REAL)(-1.0);                                                            \
                }                                                                                     \
            }                                                                                         \
            if (k % 733 == 400) {                                                                     \
                f.P[5] = (REAL)NAN;                                                                   \
            }                                                                                         \
            (void)vh_roll_ukf_step_##SFX(&f, u, z, k % 5 == 0 ? 0x3FFFu : mask);                    \
            (void)vh_roll_smc_step_##SFX(&c, f.x[VH_ROLL_X_PHI], f.x[VH_ROLL_X_P], f.ay_post, f.x[VH_ROLL_X_D], \
                                         f.health, k % 300 < 250);                                    \
            if (!(fabs((double)c.m_f) <= sp.m_max_f + 1e-3) || !(fabs((double)c.m_r) <= sp.m_max_r + 1e-3)) { \
                return 2;                                                                             \
            }                                                                                         \
            for (i = 0; i < VH_ROLL_NX; ++i) {                                                        \
                if (!isfinite((double)f.x[i])) {                                                      \
                    return 3;                                                                         \
                }                                                                                     \
            }                                                                                         \
        }                                                                                             \
        printf(#SFX ": resets %u regularised %u\n", (unsigned)f.resets, (unsigned)f.regularised);    \
        return f.resets > 0 ? 0 : 4;                                                                  \
    }

DRIVE(f32, float)
DRIVE(f64, double)

int main(void)
{
    int rc = drive_f32();
    if (rc == 0) {
        rc = drive_f64();
    }
    if (rc == 0) {
        printf("sanitize roll: ok\n");
    } else {
        printf("sanitize roll: failed %d\n", rc);
    }
    return rc;
}
