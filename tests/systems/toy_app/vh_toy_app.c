/* vh_toy_app.c - the toy application, see vh_toy_app.h. */
#include <string.h>

#include "vh_toy_app.h"

void vh_toy_app_config_default(vh_toy_app_config_t *cfg) { cfg->gain = 3u; }

int vh_toy_app_config_host(vh_toy_app_config_t *cfg)
{
    (void)cfg;
    return VH_OK;
}

int vh_toy_app_check(const vh_toy_app_config_t *cfg) { return cfg->gain > 0u ? VH_OK : VH_EINVAL; }

void vh_toy_app_init(vh_toy_app_t *a, const vh_toy_app_config_t *cfg)
{
    a->cfg = *cfg;
    vh_toy_app_reset(a);
}

void vh_toy_app_reset(vh_toy_app_t *a)
{
    const vh_toy_app_config_t cfg = a->cfg;
    memset(a, 0, sizeof *a);
    a->cfg = cfg;
}

void vh_toy_app_rx(vh_toy_app_t *a, vh_app_ctx_t *ctx, const vh_frame_t *f)
{
    (void)ctx;
    ++a->frames;
    a->last = f->len > 0u ? f->data[0] : 0u;
    a->fresh = 1u;
}

void vh_toy_app_cal_gather(const vh_toy_app_t *a, vh_toy_app_cal_t *c) { c->gain = a->cfg.gain; }

void vh_toy_app_cal_apply(vh_toy_app_t *a, const vh_toy_app_cal_t *c) { a->cfg.gain = c->gain; }

unsigned vh_toy_app_safety(vh_toy_app_t *a, int hold)
{
    (void)a;
    (void)hold;
    return 0u;
}

void vh_toy_app_step(vh_toy_app_t *a, vh_app_ctx_t *ctx)
{
    (void)ctx;
    ++a->runs;
    if (a->fresh) {
        a->sum += (uint32_t)a->cfg.gain * a->last;
        a->fresh = 0u;
    }
}

int vh_toy_app_fill(vh_toy_app_t *a, vh_app_ctx_t *ctx, uint8_t *data)
{
    (void)ctx;
    memcpy(data, &a->sum, sizeof a->sum);
    return a->frames > 0u;
}
