/* vh_node_lifecycle.h - private to firmware_sim/src: init and reset of a one-frame sensor node
 * (vh_dlsnode.c, vh_chsnode.c), written once. The node type vh_<node>_t has cfg, rng, meas[NCH],
 * counter and frames; its config vh_<node>_config_t has noise_std[NCH] and seed. BIAS is the
 * config's bias array as an expression of cfg, or NULL for a node without bias.
 * (Not in firmware_sim/include: the public headers are also the cffi declarations, which take no
 * multi-line macro.) */
#ifndef VH_NODE_LIFECYCLE_H
#define VH_NODE_LIFECYCLE_H

#include "vh_node_common.h"

/* init: VH_EINVAL (nothing changed) for NULL or a configuration vh_node_check refuses, else the
 * configuration copied and the node reset. reset: counter and frames to 0, samples to 0, random
 * stream restarted from cfg.seed. */
#define VH_NODE_LIFECYCLE(node, NCH, BIAS)                                                      \
    int vh_##node##_init(vh_##node##_t *n, const vh_##node##_config_t *cfg)                    \
    {                                                                                           \
        if (n == NULL || cfg == NULL || vh_node_check(cfg->noise_std, (BIAS), (NCH)) != VH_OK) { \
            return VH_EINVAL;                                                                   \
        }                                                                                       \
        n->cfg = *cfg;                                                                          \
        vh_##node##_reset(n);                                                                   \
        return VH_OK;                                                                           \
    }                                                                                           \
                                                                                                \
    void vh_##node##_reset(vh_##node##_t *n)                                                    \
    {                                                                                           \
        vh_node_restart(&n->rng, n->cfg.seed, n->meas, (NCH));                                  \
        n->counter = 0u;                                                                        \
        n->frames = 0u;                                                                         \
    }

#endif /* VH_NODE_LIFECYCLE_H */
