/* vh_skfmec_bench.c - the SKFMEC step on the emulated Cortex-M4F twice over the same inputs: the ECU's
 * fixed-point filter (vh_skfq.c, as flashed) and the double source (vh_skf.c, vh_mat.c) built here in
 * float32. A measurement of the change docs/firmware.md names ("The cost of a tick"), never in the
 * ECU's image: `vehest-can study firmware.cost --skfmec-float32` builds it (vehest_can/tools/pil_bench.py).
 *
 * vh_skfmec_bench_data.h (generated per run) gives BENCH_N steps of inputs, float (bench_u, laid out as
 * vh_skf_input_t) and quantised (bench_q, as vh_skfq_input_t), their masks, the double configuration
 * (bench_config) and the fixed-point constants made from it on the host (bench_skfq_params, the bytes of
 * vh_skfq_params_t: int32 fields only, so the same layout on both). Per step the UART carries the SysTick
 * counts of the fixed and the float32 step (u32 each) and their tyre forces (int32 in Q.FN, float32). */
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "vh_skfq.h"
#include "vh_target.h"

/* The double source in float32: every double a float, the math functions their float forms, unsuffixed
 * constants single precision (-fsingle-precision-constant); -Wdouble-promotion keeps it honest. */
#define double float
#define sin sinf
#define cos cosf
#define fabs fabsf
#define sqrt sqrtf
#include "vh_mat.c"
#include "vh_skf.c"
#undef double
#undef sin
#undef cos
#undef fabs
#undef sqrt

#include "vh_skfmec_bench_data.h"

typedef char input_check[(sizeof(vh_skf_input_t) == 13 * sizeof(float)) ? 1 : -1];
typedef char params_check[(sizeof(vh_skfq_params_t) == sizeof bench_skfq_params) ? 1 : -1];

int main(void)
{
    static vh_skf_t f;
    static vh_skfq_t q;
    static vh_skfq_params_t prm;
    vh_skf_config_t cfg;
    uint32_t n;
    vh_uart_init();
    vh_systick_start();
    bench_config(&cfg);
    memcpy(&prm, bench_skfq_params, sizeof prm);
    if (vh_skf_init(&f, &cfg) != VH_OK || vh_skfq_init(&q, &prm) != VH_OK) {
        vh_uart_put('E');
        for (;;) {
        }
    }
    vh_uart_put('S');
    for (n = 0; n < BENCH_N; ++n) {
        vh_skf_input_t in;
        vh_skfq_input_t iq;
        uint32_t t0, c[2];
        memcpy(&in, bench_u[n], sizeof in);
        memcpy(&iq, bench_q[n], sizeof iq);
        t0 = vh_systick_now();
        (void)vh_skfq_step(&q, &iq, bench_mask[n]);
        c[0] = vh_systick_since(t0);
        t0 = vh_systick_now();
        (void)vh_skf_step(&f, &in, bench_mask[n]);
        c[1] = vh_systick_since(t0);
        vh_uart_write(c, sizeof c);
        vh_uart_write(q.fy, sizeof q.fy);
        vh_uart_write(f.fy, sizeof f.fy);
    }
    vh_uart_put('D');
    for (;;) {
    }
}
