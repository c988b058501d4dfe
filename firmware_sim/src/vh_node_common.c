/* vh_node_common.c - see vh_node_common.h. */
#include "vh_node_common.h"

#include <math.h>

int vh_node_check(const double *noise_std, const double *bias, int nch)
{
    int i;
    for (i = 0; i < nch; ++i) {
        if (!(noise_std[i] >= 0.0) || !isfinite(noise_std[i]) || (bias != NULL && !isfinite(bias[i]))) {
            return VH_EINVAL;
        }
    }
    return VH_OK;
}

void vh_node_restart(vh_rng_t *rng, uint64_t seed, double *v, int nch)
{
    int i;
    vh_rng_seed(rng, seed);
    for (i = 0; i < nch; ++i) {
        v[i] = 0.0;
    }
}

void vh_node_sample(vh_rng_t *rng, const double *phys, const double *bias, const double *noise_std, int nch,
                    double *out)
{
    int i;
    for (i = 0; i < nch; ++i) {
        /* bias added before the noise, as (phys + bias) + noise: the nodes' historical rounding */
        const double x = bias != NULL ? phys[i] + bias[i] : phys[i];
        out[i] = x + noise_std[i] * vh_rng_gauss(rng);
    }
}

void vh_node_qualify(const double *v, uint32_t fail_mask, int nch, uint8_t *ok)
{
    int i;
    for (i = 0; i < nch; ++i) {
        ok[i] = (uint8_t)(isfinite(v[i]) && !(fail_mask & (1u << i)));
    }
}

void vh_node_frame_init(vh_frame_t *f, uint32_t id, size_t len)
{
    int i;
    for (i = 0; i < VH_FRAME_MAX_LEN; ++i) {
        f->data[i] = 0u;
    }
    f->id = id;
    f->len = (uint8_t)len;
    f->flags = (uint8_t)(VH_FRAME_FD | VH_FRAME_BRS);
}

vh_frame_t *vh_node_slot(vh_frame_t *out, size_t *k, size_t cap, uint32_t id, size_t len)
{
    vh_frame_t *f;
    if (*k >= cap) {
        return NULL;
    }
    f = &out[(*k)++];
    vh_node_frame_init(f, id, len);
    return f;
}

void vh_node_count(uint32_t *frames)
{
    if (*frames < UINT32_MAX) {
        ++*frames;
    }
}
