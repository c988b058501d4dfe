/* vh_bench_skf.c - C-loop benchmark of the tire-force estimators' step (seed 000).
 *
 * Prints "name n median_ns p99_ns" per estimator (the format of vh_bench.c): one step of SKFMEC
 * in double, of the plain EKF, of SKFMEC in fixed point and of SKFMEC-A in fixed point (vh_tfa.c), timed call by call with
 * CLOCK_MONOTONIC (the clock's own cost is measured and subtracted: vh_bench_common.h).
 * Inputs: a 0.5 Hz sine steer at 70 km/h with a consistent yaw rate and lateral acceleration, small deterministic noise.
 * Build: cc -O3 -Ic_core/include c_core/bench/vh_bench_skf.c c_core/src/vh_skf.c
 *        c_core/src/vh_skfq.c c_core/src/vh_fix.c -lm  (vehest_can.tireforce.bench_c_loop does it).
 */
#define _POSIX_C_SOURCE 199309L
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>

#include "vh_bench_common.h"

#include "vh_skf.h"
#include "vh_skfq.h"
#include "vh_skfq_host.h"
#include "vh_tfa_host.h"

#define N_SAMPLES 40000 /* 20 s of driving at 2 kHz */

static double samples[N_SAMPLES];
static vh_skf_input_t inputs[N_SAMPLES];
static int32_t qinputs[N_SAMPLES * VH_SKFQ_NU];
/* the springs' static deflections of the model car in Q.VH_TFA_FH [m]: 0.163 m front, 0.130 m rear */
static const int32_t ride[4] = {(int32_t)(0.163 * (1 << VH_TFA_FH)), (int32_t)(0.163 * (1 << VH_TFA_FH)),
                                (int32_t)(0.130 * (1 << VH_TFA_FH)), (int32_t)(0.130 * (1 << VH_TFA_FH))};

/* FNV-1a over the bytes (little-endian) of n arrays of int32 */
static uint32_t fnv1a(const int32_t *const *parts, const int *len, int n)
{
    uint32_t h = 2166136261u;
    int a, b, byte;
    for (a = 0; a < n; ++a) {
        for (b = 0; b < len[a]; ++b) {
            const uint32_t v = (uint32_t)parts[a][b];
            for (byte = 0; byte < 4; ++byte) {
                h = (h ^ ((v >> (8 * byte)) & 0xffu)) * 16777619u;
            }
        }
    }
    return h;
}

int main(int argc, char **argv)
{
    static vh_skf_t kf;
    static vh_skfq_t kq, kq2;
    static vh_tfa_t ka;
    vh_tfa_config_t acfg;
    vh_tfa_params_t aprm;
    vh_skf_config_t cfg;
    vh_skfq_params_t prm;
    double clock_ns, t0;
    int i, v;
    unsigned lcg = 12345u;
    volatile int sink = 0;
    /* optional sample count (the test suite runs a short one) */
    const int n = argc > 1 && atoi(argv[1]) > 100 && atoi(argv[1]) <= N_SAMPLES ? atoi(argv[1]) : N_SAMPLES;

    clock_ns = vh_bench_clock(samples, n);

    for (i = 0; i < n; ++i) {
        const double t = i * 5e-4, vx = 19.44;
        const double delta = 0.035 * sin(2.0 * 3.14159265358979 * 0.5 * t);
        double noise;
        int w;
        lcg = lcg * 1103515245u + 12345u;
        noise = ((double)(lcg >> 16) / 65536.0 - 0.5) * 0.02;
        inputs[i].delta = delta;
        inputs[i].r = vx * delta / 2.693 + noise;
        inputs[i].ay = vx * inputs[i].r + noise;
        inputs[i].ax = noise;
        inputs[i].p = 0.01 * cos(2.0 * 3.14159265358979 * 0.5 * t) + noise;
        for (w = 0; w < 4; ++w) {
            inputs[i].omega[w] = vx / 0.305 + noise;
            inputs[i].torque[w] = 10.0;
        }
    }
    vh_skfq_quantise_inputs((size_t)n, &inputs[0].ax, qinputs);

    for (v = 0; v < 2; ++v) { /* double: SKFMEC, EKF */
        vh_skf_config_default(&cfg, v == 0 ? VH_SKF_SKFMEC : VH_SKF_EKF);
        if (vh_skf_init(&kf, &cfg) != VH_OK) {
            return 1;
        }
        for (i = 0; i < n; ++i) {
            t0 = vh_bench_now_ns();
            sink += vh_skf_step(&kf, &inputs[i], VH_SKF_ALL_VALID);
            samples[i] = vh_bench_now_ns() - t0;
        }
        vh_bench_report(v == 0 ? "skfmec_double_step" : "ekf_double_step", samples, n, clock_ns);
    }

    vh_skf_config_default(&cfg, VH_SKF_SKFMEC);
    if (vh_skfq_params_from_config(&cfg, &prm) != VH_OK || vh_skfq_init(&kq, &prm) != VH_OK) {
        return 1;
    }
    for (i = 0; i < n; ++i) {
        const vh_skfq_input_t *in = vh_skfq_input_row(qinputs, (size_t)i);
        t0 = vh_bench_now_ns();
        sink += vh_skfq_step(&kq, in, VH_SKF_ALL_VALID);
        samples[i] = vh_bench_now_ns() - t0;
    }
    vh_bench_report("skfmec_fixed_step", samples, n, clock_ns);
    /* SKFMEC-A: the same SKFMEC step and vh_tfa_step after it, timed together, with ride heights */
    vh_tfa_config_default(&acfg);
    if (vh_skfq_init(&kq2, &prm) != VH_OK || vh_tfa_params_from_config(&cfg, &acfg, &aprm) != VH_OK ||
        vh_tfa_init(&ka, &aprm) != VH_OK) {
        return 1;
    }
    for (i = 0; i < n; ++i) {
        const vh_skfq_input_t *in = vh_skfq_input_row(qinputs, (size_t)i);
        t0 = vh_bench_now_ns();
        sink += vh_skfq_step(&kq2, in, VH_SKF_ALL_VALID);
        vh_tfa_step(&ka, &kq2, in, VH_SKF_ALL_VALID, ride);
        samples[i] = vh_bench_now_ns() - t0;
    }
    vh_bench_report("skfmec_a_fixed_step", samples, n, clock_ns);
    printf("skfmec_a_fixed_saturations %u 0 0\n", (unsigned)ka.sat);
    printf("skfmec_fixed_saturations %u 0 0\n", (unsigned)kq.sat);
    { /* FNV-1a of the final integer states: equal for every build of the same sources */
        const int32_t *skf[4] = {kq.x, kq.p, kq.fy, kq.fz};
        const int skf_len[4] = {VH_SKFQ_NX, VH_SKFQ_NX * VH_SKFQ_NX, 4, 4};
        /* SKFMEC-A: mass, loads, forces, the frictions (the road's updates from step 2000 on) */
        const int32_t scalars[4] = {ka.k, ka.p, ka.mu_road, ka.p_road};
        const int32_t *tfa[5] = {ka.fy, ka.fz, ka.mu, scalars, &ka.z_lp};
        const int tfa_len[5] = {4, 4, 2, 4, 1};
        printf("skfmec_fixed_checksum %u 0 0\n", (unsigned)fnv1a(skf, skf_len, 4));
        printf("skfmec_a_fixed_checksum %u 0 0\n", (unsigned)fnv1a(tfa, tfa_len, 5));
    }
    return sink == 0 ? 0 : 2;
}
