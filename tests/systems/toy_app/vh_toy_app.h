/* vh_toy_app.h - a toy fifth application for tests/systems/test_toy_app.py: registered with the ECU
 * by its descriptor alone (vh_toy_app.def), no edit to a shared file. It counts the frames of one
 * RX ID, sums their first byte times its gain in a runnable every 10 ticks and sends the sum. */
#ifndef VH_TOY_APP_H
#define VH_TOY_APP_H

#include "vh_app.h"

#define VH_TOY_IN_FRAME_ID 0x555u /* in neither DBC */
#define VH_TOY_OUT_FRAME_ID 0x556u
#define VH_TOY_OUT_LENGTH 8u
#define VH_TOY_OUT_IS_FD 0u

typedef struct {
    uint8_t gain;
} vh_toy_app_config_t;

typedef struct {
    uint8_t gain;
} vh_toy_app_cal_t;

typedef struct {
    vh_toy_app_config_t cfg;
    uint32_t frames; /* frames received since reset */
    uint32_t runs;   /* runnable calls since reset */
    uint32_t sum;    /* gain x first byte, summed by the runnable */
    uint8_t last;    /* first byte of the last frame */
    uint8_t fresh;
} vh_toy_app_t;

void vh_toy_app_config_default(vh_toy_app_config_t *cfg);
int vh_toy_app_config_host(vh_toy_app_config_t *cfg);
int vh_toy_app_check(const vh_toy_app_config_t *cfg);
void vh_toy_app_init(vh_toy_app_t *a, const vh_toy_app_config_t *cfg);
void vh_toy_app_reset(vh_toy_app_t *a);
void vh_toy_app_rx(vh_toy_app_t *a, vh_app_ctx_t *ctx, const vh_frame_t *f);
void vh_toy_app_cal_gather(const vh_toy_app_t *a, vh_toy_app_cal_t *c);
void vh_toy_app_cal_apply(vh_toy_app_t *a, const vh_toy_app_cal_t *c);
unsigned vh_toy_app_safety(vh_toy_app_t *a, int hold);
void vh_toy_app_step(vh_toy_app_t *a, vh_app_ctx_t *ctx);
int vh_toy_app_fill(vh_toy_app_t *a, vh_app_ctx_t *ctx, uint8_t *data);

#endif /* VH_TOY_APP_H */
