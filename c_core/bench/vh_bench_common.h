/* vh_bench_common.h - the timing harness shared by the C-loop benchmarks (every benchmark in c_core/bench).
 *
 * Each sample is one call timed with CLOCK_MONOTONIC; the clock's own cost is measured first
 * (vh_bench_clock) and subtracted. Output: one line "name n median_ns p99_ns" per benchmark.
 * Header-only: include it once, from the benchmark's single translation unit, after defining
 * _POSIX_C_SOURCE 199309L.
 */
#ifndef VH_BENCH_COMMON_H
#define VH_BENCH_COMMON_H

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

static double vh_bench_now_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec * 1e9 + (double)ts.tv_nsec;
}

static int vh_bench_cmp(const void *a, const void *b)
{
    const double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* Sorts s[0..n) and prints its median and p99 less the clock's cost. */
static void vh_bench_report(const char *name, double *s, int n, double clock_ns)
{
    qsort(s, (size_t)n, sizeof *s, vh_bench_cmp);
    printf("%s %d %.1f %.1f\n", name, n, s[n / 2] - clock_ns, s[(n * 99) / 100] - clock_ns);
}

/* Median cost of one clock reading, from n back-to-back pairs (s is scratch); prints the "clock" line. */
static double vh_bench_clock(double *s, int n)
{
    double t0, clock_ns;
    int i;
    for (i = 0; i < n; ++i) {
        t0 = vh_bench_now_ns();
        s[i] = vh_bench_now_ns() - t0;
    }
    qsort(s, (size_t)n, sizeof *s, vh_bench_cmp);
    clock_ns = s[n / 2];
    printf("clock %d %.1f 0\n", n, clock_ns);
    return clock_ns;
}

/* v into p[0..4), least significant byte first: the 32-bit fields of the XCP benches' commands
 * (seed & key, addresses), Intel byte order as the slaves are configured. */
static inline void vh_bench_le32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
    p[2] = (uint8_t)(v >> 16);
    p[3] = (uint8_t)(v >> 24);
}

#endif /* VH_BENCH_COMMON_H */
