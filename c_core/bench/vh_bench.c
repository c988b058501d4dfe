/* vh_bench.c - C-loop benchmarks of the firmware, run by `vehest-can bench`.
 *
 * Prints one line "name n median_ns p99_ns" per benchmark: each sample is one call timed with
 * CLOCK_MONOTONIC (its own cost, ~20 ns, is measured and subtracted as "clock").
 */
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "vh_dkf.h"
#include "vh_dlsim.h"
#include "vh_ecu.h"

#define N_SAMPLES 40000

static double now_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec * 1e9 + (double)ts.tv_nsec;
}

static int cmp(const void *a, const void *b)
{
    const double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static void report(const char *name, double *s, int n, double clock_ns)
{
    qsort(s, (size_t)n, sizeof *s, cmp);
    printf("%s %d %.1f %.1f\n", name, n, s[n / 2] - clock_ns, s[(n * 99) / 100] - clock_ns);
}

static double samples[N_SAMPLES];

int main(void)
{
    static vh_dlsim_t sim;
    static vh_ecu_t ecu;
    static vh_frame_t frames[N_SAMPLES];
    vh_dlp_params_t prm;
    vh_dls_config_t node;
    vh_ecu_config_t ecfg;
    vh_dkf_config_t kcfg;
    vh_dkf_t kf;
    vh_frame_t tx[VH_ECU_MAX_TX];
    double z[3], clock_ns, t0;
    int i;
    volatile size_t sink = 0u;

    for (i = 0; i < N_SAMPLES; ++i) {
        t0 = now_ns();
        samples[i] = now_ns() - t0;
    }
    qsort(samples, N_SAMPLES, sizeof samples[0], cmp);
    clock_ns = samples[N_SAMPLES / 2];
    printf("clock %d %.1f 0\n", N_SAMPLES, clock_ns);

    /* the car's frames of a launch, made once */
    vh_dlp_params_default(&prm);
    vh_dls_config_default(&node);
    if (vh_dlsim_init(&sim, &prm, 1u, &node) != VH_OK) {
        return 1;
    }
    for (i = 0; i < N_SAMPLES; ++i) {
        (void)vh_dlsim_tick(&sim, i < 2000 ? 0.0 : 0.6, 2, &frames[i], 1u);
    }

    vh_ecu_config_default(&ecfg);
    if (vh_ecu_init(&ecu, &ecfg) != VH_OK) {
        return 1;
    }
    for (i = 0; i < N_SAMPLES; ++i) { /* full tick: unpack + checks + 2 filters + pack */
        t0 = now_ns();
        vh_ecu_rx(&ecu, &frames[i]);
        sink += vh_ecu_step(&ecu, tx, VH_ECU_MAX_TX);
        samples[i] = now_ns() - t0;
    }
    report("ecu_tick", samples, N_SAMPLES, clock_ns);

    vh_dkf_config_default(&kcfg, VH_DKF_SPEEDS_TORQUE);
    if (vh_dkf_init(&kf, &kcfg) != VH_OK) {
        return 1;
    }
    for (i = 0; i < N_SAMPLES; ++i) {
        z[0] = 200.0 + (double)(i % 7);
        z[1] = 51.0 + (double)(i % 5) * 0.1;
        z[2] = 1500.0 + (double)(i % 11);
        t0 = now_ns();
        sink += (size_t)vh_dkf_step(&kf, 170.0, z, VH_DKF_ALL_VALID);
        samples[i] = now_ns() - t0;
    }
    report("dkf_step", samples, N_SAMPLES, clock_ns);

    vh_dlsim_reset(&sim);
    for (i = 0; i < N_SAMPLES; ++i) { /* plant + sensor node */
        t0 = now_ns();
        sink += vh_dlsim_tick(&sim, 0.6, 2, tx, 1u);
        samples[i] = now_ns() - t0;
    }
    report("car_tick", samples, N_SAMPLES, clock_ns);
    return sink == 0u ? 0 : 0;
}
