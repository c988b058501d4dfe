/* Drives the 14-DOF plant, its tyre and the chassis sensor node hard under ASan + UBSan
 * (tests/test_veh14.py builds it): hostile inputs, standstill, lift-off, locked wheels, relaxation. */
#include <math.h>
#include <stdio.h>

#include "vh_chsnode.h"
#include "vh_mftire.h"
#include "vh_rng.h"
#include "vh_veh14.h"

static int finite_truth(const vh_v14_truth_t *t)
{
    int i;
    if (!isfinite(t->vx) || !isfinite(t->vy) || !isfinite(t->r) || !isfinite(t->phi) || !isfinite(t->ay)) {
        return 0;
    }
    for (i = 0; i < VH_V14_NW; ++i) {
        if (!isfinite(t->fx[i]) || !isfinite(t->fy[i]) || !isfinite(t->fz[i]) || !isfinite(t->omega[i])) {
            return 0;
        }
    }
    return 1;
}

int main(void)
{
    static vh_v14_t p;
    vh_v14_params_t prm;
    vh_v14_input_t in, ins[10];
    vh_chs_t node;
    vh_chs_config_t cfg;
    vh_frame_t fr[2];
    vh_rng_t rng;
    vh_mft_coef_t coef;
    double fx, fy;
    int k, i, relax;

    vh_mft_coef_default(&coef);
    for (k = 0; k < 2000; ++k) {
        const double kap = -1.5 + 3.0 * (double)k / 2000.0;
        vh_mft_eval(&coef, 4000.0, 1.0, kap, tan(0.1 * kap), &fx, &fy);
        vh_mft_eval(&coef, 0.0, 1.0, kap, 0.3, &fx, &fy);
        vh_mft_eval(&coef, 4000.0, 0.0, kap, 0.3, &fx, &fy);
        vh_mft_eval(&coef, 4000.0, 1.0, 0.0, 0.0, &fx, &fy);
        vh_mft_eval(&coef, 1e6, 3.0, kap, -1e3, &fx, &fy);
    }
    vh_rng_seed(&rng, 7u);
    vh_chs_config_default(&cfg);
    cfg.accel_gravity = 1;
    if (vh_chs_init(&node, &cfg) != VH_OK) {
        return 1;
    }
    for (relax = 0; relax < 2; ++relax) {
        vh_v14_params_default(&prm);
        prm.relax_x = relax ? 0.15 : 0.0;
        prm.relax_y = relax ? 0.4 : 0.0;
        if (vh_v14_init(&p, &prm) != VH_OK || vh_v14_set_rolling(&p, 30.0) != VH_OK) {
            return 1;
        }
        for (k = 0; k < 40000; ++k) {
            vh_v14_input_init(&in, 1.0);
            in.steer = 0.5 * sin(0.002 * k);
            for (i = 0; i < VH_V14_NW; ++i) {
                in.drive[i] = (k % 9000 < 3000) ? 800.0 * vh_rng_uniform(&rng) : 0.0;
                in.brake[i] = (k % 9000 > 5000) ? 4000.0 * vh_rng_uniform(&rng) : 0.0;
                in.mu[i] = 3.5 * vh_rng_uniform(&rng) - 0.2;
            }
            if (k % 997 == 0) {
                in.steer = NAN;
                in.drive[1] = INFINITY;
                in.brake[2] = -5.0;
                in.mu[3] = NAN;
            }
            if (k == 20000) {
                p.x[VH_V14_X_ZU] = 0.2; /* a kerb: the wheel leaves the road */
                p.x[VH_V14_X_VZU + 1] = 3.0;
            }
            vh_v14_step(&p, &in);
            if (!finite_truth(&p.truth)) {
                printf("non-finite truth at step %d\n", k);
                return 1;
            }
            (void)vh_chs_step(&node, &p.truth, fr, 2);
            (void)vh_v14_energy(&p);
        }
    }
    p.truth.ax = NAN;
    p.truth.omega[0] = -1e9;
    (void)vh_chs_step(&node, &p.truth, fr, 2);
    (void)vh_chs_step(&node, NULL, fr, 2);
    (void)vh_chs_step(&node, &p.truth, fr, 0);
    for (i = 0; i < 10; ++i) {
        vh_v14_input_init(&ins[i], 0.8);
    }
    (void)vh_v14_run(&p, 10, ins, NULL);
    printf("sanitize_veh14: ok (%u bad inputs, %u frames)\n", (unsigned)p.bad_inputs, (unsigned)node.frames);
    return 0;
}
