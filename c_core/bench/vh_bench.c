/* vh_bench.c - C-loop benchmarks of the firmware, run by `vehest-can bench`.
 *
 * Prints one line "name n median_ns p99_ns" per benchmark: each sample is one call timed with
 * CLOCK_MONOTONIC (its own cost, ~20 ns, is measured and subtracted as "clock"; harness:
 * vh_bench_common.h). Benchmarks:
 *   ecu_tick          full ECU tick, powertrain bus only: one DLS_Sensors frame in, 2 driveline KF
 *   ecu_tick_chassis  the same tick with the chassis estimator active: a DLS_Sensors and a
 *                     CHS_Sensors frame in every tick, the fixed-point SKFMEC steps once per tick
 *   dkf_step          one driveline KF step
 *   car_tick          driveline plant + sensor node
 * plus a check line "ecu_chassis_skf ticks skf_steps skf_resets" (the chassis side did run).
 * The CHS_Sensors frames come from the chassis sensor node's firmware (vh_chs_step: the generated
 * codec and E2E P01, noise on) sampling a 0.5 Hz sine steer at 70 km/h, the drive of vh_bench_skf.c.
 */
#define _POSIX_C_SOURCE 199309L
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "vh_bench_common.h"

#include "vh_chsnode.h"
#include "vh_dkf.h"
#include "vh_dlsim.h"
#include "vh_ecu.h"

#define N_SAMPLES 40000

static double samples[N_SAMPLES];

/* CHS_Sensors frames of a sine-steer drive, one per tick. */
static int make_chs_frames(vh_frame_t *out, int n)
{
    static vh_v14_truth_t truth;
    vh_chs_config_t ccfg;
    vh_chs_t node;
    int i, w;

    vh_chs_config_default(&ccfg);
    if (vh_chs_init(&node, &ccfg) != VH_OK) {
        return 0;
    }
    memset(&truth, 0, sizeof truth);
    truth.vx = 19.44;
    for (i = 0; i < n; ++i) {
        const double t = i * 5e-4;
        truth.t = t;
        truth.steer = 0.035 * sin(2.0 * 3.14159265358979 * 0.5 * t);
        truth.r = truth.vx * truth.steer / 2.693;
        truth.ay = truth.vx * truth.r;
        truth.ax = 0.0;
        truth.p = 0.01 * cos(2.0 * 3.14159265358979 * 0.5 * t);
        for (w = 0; w < 4; ++w) {
            truth.omega[w] = truth.vx / 0.305;
            truth.torque[w] = 10.0;
        }
        if (vh_chs_step(&node, &truth, &out[i], 1u) != 1u) {
            return 0;
        }
    }
    return 1;
}

int main(void)
{
    static vh_dlsim_t sim;
    static vh_ecu_t ecu;
    static vh_frame_t frames[N_SAMPLES], chs[N_SAMPLES];
    vh_dlp_params_t prm;
    vh_dls_config_t node;
    vh_ecu_config_t ecfg;
    vh_dkf_config_t kcfg;
    vh_dkf_t kf;
    vh_frame_t tx[VH_ECU_MAX_TX];
    double z[3], clock_ns, t0;
    int i;
    volatile size_t sink = 0u;

    clock_ns = vh_bench_clock(samples, N_SAMPLES);

    /* the car's frames of a launch, made once */
    vh_dlp_params_default(&prm);
    vh_dls_config_default(&node);
    if (vh_dlsim_init(&sim, &prm, 1u, &node) != VH_OK) {
        return 1;
    }
    for (i = 0; i < N_SAMPLES; ++i) {
        (void)vh_dlsim_tick(&sim, i < 2000 ? 0.0 : 0.6, 2, &frames[i], 1u);
    }
    if (!make_chs_frames(chs, N_SAMPLES)) {
        return 1;
    }

    vh_ecu_config_default(&ecfg);
    if (vh_ecu_init(&ecu, &ecfg) != VH_OK) {
        return 1;
    }
    for (i = 0; i < N_SAMPLES; ++i) { /* full tick: unpack + checks + 2 filters + pack */
        t0 = vh_bench_now_ns();
        vh_ecu_rx(&ecu, &frames[i]);
        sink += vh_ecu_step(&ecu, tx, VH_ECU_MAX_TX);
        samples[i] = vh_bench_now_ns() - t0;
    }
    vh_bench_report("ecu_tick", samples, N_SAMPLES, clock_ns);

    if (vh_ecu_init(&ecu, &ecfg) != VH_OK) {
        return 1;
    }
    for (i = 0; i < N_SAMPLES; ++i) { /* the same, chassis bus too: + CHS checks + fixed SKFMEC + pack */
        t0 = vh_bench_now_ns();
        vh_ecu_rx(&ecu, &frames[i]);
        vh_ecu_rx(&ecu, &chs[i]);
        sink += vh_ecu_step(&ecu, tx, VH_ECU_MAX_TX);
        samples[i] = vh_bench_now_ns() - t0;
    }
    vh_bench_report("ecu_tick_chassis", samples, N_SAMPLES, clock_ns);
    printf("ecu_chassis_skf %d %u %u\n", N_SAMPLES, (unsigned)ecu.chs.skf.steps, (unsigned)ecu.chs.skf.resets);

    vh_dkf_config_default(&kcfg, VH_DKF_SPEEDS_TORQUE);
    if (vh_dkf_init(&kf, &kcfg) != VH_OK) {
        return 1;
    }
    for (i = 0; i < N_SAMPLES; ++i) {
        z[0] = 200.0 + (double)(i % 7);
        z[1] = 51.0 + (double)(i % 5) * 0.1;
        z[2] = 1500.0 + (double)(i % 11);
        t0 = vh_bench_now_ns();
        sink += (size_t)vh_dkf_step(&kf, 170.0, z, VH_DKF_ALL_VALID);
        samples[i] = vh_bench_now_ns() - t0;
    }
    vh_bench_report("dkf_step", samples, N_SAMPLES, clock_ns);

    vh_dlsim_reset(&sim);
    for (i = 0; i < N_SAMPLES; ++i) { /* plant + sensor node */
        t0 = vh_bench_now_ns();
        sink += vh_dlsim_tick(&sim, 0.6, 2, tx, 1u);
        samples[i] = vh_bench_now_ns() - t0;
    }
    vh_bench_report("car_tick", samples, N_SAMPLES, clock_ns);
    return sink == 0u ? 0 : 0;
}
