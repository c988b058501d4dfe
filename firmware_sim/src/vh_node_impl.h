/* vh_node_impl.h - private to firmware_sim/src: what the sensor nodes' sources write alike, written
 * once as macros (the types and the generated codec's names differ per node and message).
 * Not in firmware_sim/include: the public headers are also the cffi declarations, which take no
 * multi-line macro. */
#ifndef VH_NODE_IMPL_H
#define VH_NODE_IMPL_H

#include "vh_node_common.h"

/* Init and reset of a one-frame sensor node with one random stream (vh_dlsnode.c). The node type vh_<node>_t
 * has cfg, rng, meas[NCH], counter and frames; its config vh_<node>_config_t has noise_std[NCH] and
 * seed. BIAS is the config's bias array as an expression of cfg, or NULL for a node without bias.
 * init: VH_EINVAL (nothing changed) for NULL or a configuration vh_node_check refuses, else the
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

/* One channel of a sensor frame: signal `sig` of message `msg` on bus `bus` (the generated codec's
 * lower- and upper-case names) written through its generated encoder from v, or its SNA value when
 * ok is 0, and its qualifier qf_<sig> set to ok. m is the message struct's name. */
#define VH_NODE_CHANNEL(m, bus, BUS, msg, MSG, sig, SIG, ok, v)                                        \
    m.sig = (ok) ? vh_##bus##_##msg##_##sig##_encode_round(v) : VH_##BUS##_##MSG##_##SIG##_SNA_CHOICE; \
    m.qf_##sig = (ok)

/* The four corners of one quantity, signals <sig>_fl, _fr, _rl, _rr on channels ch0 .. ch0 + 3 (the
 * wheel order FL, FR, RL, RR of every node), each through the node's CHAN(sig, SIG, ch). */
#define VH_NODE_CORNERS(CHAN, sig, SIG, ch0) \
    CHAN(sig##_fl, SIG##_FL, (ch0) + 0);     \
    CHAN(sig##_fr, SIG##_FR, (ch0) + 1);     \
    CHAN(sig##_rl, SIG##_RL, (ch0) + 2);     \
    CHAN(sig##_rr, SIG##_RR, (ch0) + 3)

#endif /* VH_NODE_IMPL_H */
