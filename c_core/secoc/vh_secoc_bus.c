/* vh_secoc_bus.c - the SecOC RX/TX hook of a node, see vh_secoc_bus.h. */
#include <string.h>

#include "vh_secoc_bus.h"
#include "vh_secoc_table.h" /* generated from the DBCs: VH_SECOC_MSGS, VH_SECOC_NODE_* */

typedef char vh_secoc_nodes_fit[(VH_SECOC_N_NODES <= VH_SECOC_MAX_NODES) ? 1 : -1];

static void count(uint32_t *c)
{
    *c = vh_sat_add_u32(*c, 1u);
}

static const vh_secoc_msg_t *find(uint32_t id)
{
    size_t i;
    for (i = 0; i < sizeof VH_SECOC_MSGS / sizeof VH_SECOC_MSGS[0]; ++i) {
        if (VH_SECOC_MSGS[i].id == id) {
            return &VH_SECOC_MSGS[i];
        }
    }
    return NULL;
}

void vh_secoc_bus_init(vh_secoc_bus_t *s, unsigned self)
{
    memset(s, 0, sizeof *s);
    s->self = (uint8_t)(self < VH_SECOC_N_NODES ? self : 0u);
}

int vh_secoc_bus_set_key(vh_secoc_bus_t *s, unsigned node, const uint8_t key[VH_AES_BLOCK])
{
    if (node >= VH_SECOC_N_NODES || vh_cmac_init(&s->key[node], key) != 0) {
        return VH_EINVAL;
    }
    s->have_key[node] = 1u;
    return VH_OK;
}

int vh_secoc_bus_restore_rx(vh_secoc_bus_t *s, unsigned node, uint64_t latest)
{
    if (node >= VH_SECOC_N_NODES) {
        return VH_EINVAL;
    }
    vh_secoc_rx_init(&s->rx[node], latest, latest != 0u);
    return VH_OK;
}

int vh_secoc_bus_start(vh_secoc_bus_t *s, uint64_t fv_start, uint64_t reserved_until)
{
    if (!s->have_key[s->self] || fv_start == 0u) {
        return VH_EINVAL;
    }
    vh_secoc_tx_init(&s->tx, fv_start, reserved_until);
    s->tick = 0u;
    s->on = 1u;
    return VH_OK;
}

void vh_secoc_bus_resync(vh_secoc_bus_t *s) { s->tick = 0u; }

void vh_secoc_bus_wipe(vh_secoc_bus_t *s)
{
    unsigned i;
    for (i = 0; i < VH_SECOC_MAX_NODES; ++i) {
        vh_cmac_wipe(&s->key[i]);
        s->have_key[i] = 0u;
    }
    s->on = 0u;
}

int vh_secoc_bus_node(const char *name)
{
    int i;
    for (i = 0; i < VH_SECOC_N_NODES; ++i) {
        if (strcmp(VH_SECOC_NODE_NAMES[i], name) == 0) {
            return i;
        }
    }
    return -1;
}

static vh_secoc_bus_result_t reject(vh_secoc_bus_t *s, uint32_t *why)
{
    count(why);
    count(&s->cnt.rejected);
    return VH_SECOC_BUS_REJECTED;
}

vh_secoc_bus_result_t vh_secoc_bus_rx(vh_secoc_bus_t *s, const vh_frame_t *in, vh_frame_t *out)
{
    const vh_secoc_msg_t *m = (in->flags & VH_FRAME_EXT) ? NULL : find(in->id);
    vh_secoc_rx_t *rx;
    vh_secoc_result_t r;
    if (m == NULL || !s->on || m->node == s->self) {
        /* not secured; or SecOC off (tails unchecked); or our own frame echoed back, which no
         * application here uses: sync frames are never an application's */
        return (m != NULL && m->sync) ? VH_SECOC_BUS_CONSUMED : VH_SECOC_BUS_PASS;
    }
    if (!s->have_key[m->node]) {
        return reject(s, &s->cnt.no_key);
    }
    if (in->len != m->authentic + VH_SECOC_TAIL_BYTES) {
        return reject(s, &s->cnt.malformed);
    }
    rx = &s->rx[m->node];
    if (m->sync) {
        r = vh_secoc_sync_accept(rx, &s->key[m->node], m->data_id, in->data);
        if (r == VH_SECOC_OK) {
            count(&s->cnt.syncs);
            return VH_SECOC_BUS_CONSUMED;
        }
    } else {
        r = vh_secoc_verify(rx, &s->key[m->node], m->data_id, in->data, m->authentic, NULL);
        if (r == VH_SECOC_OK) {
            *out = *in;
            memset(out->data + m->authentic, 0, VH_SECOC_TAIL_BYTES); /* as its application packed it */
            count(&s->cnt.accepted);
            return VH_SECOC_BUS_OK;
        }
    }
    return reject(s, r == VH_SECOC_E_REPLAY ? &s->cnt.replayed
                     : r == VH_SECOC_E_UNSYNCED ? &s->cnt.unsynced : &s->cnt.bad_mac);
}

#define MAX_SYNC 2 /* sync frames per node and tick: one per bus */

size_t vh_secoc_bus_tx(vh_secoc_bus_t *s, vh_frame_t *tx, size_t n, size_t cap)
{
    vh_frame_t sync[MAX_SYNC];
    size_t i, k = 0u, ns = 0u;
    if (!s->on) {
        return n;
    }
    /* sync frames first, with the lowest FVs of the tick: a receiver resyncs on them, then
     * accepts the rest */
    for (i = 0; s->tick % VH_SECOC_SYNC_PERIOD_TICKS == 0u && i < sizeof VH_SECOC_MSGS / sizeof VH_SECOC_MSGS[0]; ++i) {
        const vh_secoc_msg_t *m = &VH_SECOC_MSGS[i];
        if (!m->sync || m->node != s->self || ns >= MAX_SYNC) {
            continue;
        }
        memset(&sync[ns], 0, sizeof sync[ns]);
        sync[ns].id = m->id;
        sync[ns].len = (uint8_t)(VH_SECOC_SYNC_AUTHENTIC + VH_SECOC_TAIL_BYTES);
        sync[ns].flags = (uint8_t)(VH_FRAME_FD | VH_FRAME_BRS);
        if (vh_secoc_sync_build(&s->tx, &s->key[s->self], m->data_id, sync[ns].data) == VH_SECOC_OK) {
            ++ns;
        } else {
            count(&s->cnt.tx_dropped);
        }
    }
    ++s->tick;
    for (i = 0; i < n; ++i) { /* secure in place; a frame that cannot be secured is not sent */
        const vh_secoc_msg_t *m = (tx[i].flags & VH_FRAME_EXT) ? NULL : find(tx[i].id);
        if (m != NULL && m->node == s->self && !m->sync && tx[i].len == m->authentic + VH_SECOC_TAIL_BYTES) {
            if (vh_secoc_protect(&s->tx, &s->key[s->self], m->data_id, tx[i].data, m->authentic) != VH_SECOC_OK) {
                count(&s->cnt.tx_dropped);
                continue;
            }
            count(&s->cnt.secured);
        }
        if (k != i) {
            tx[k] = tx[i];
        }
        ++k;
    }
    while (ns > 0u && k + ns > cap) { /* no room: a lost sync frame only leaves a gap in the FVs */
        --ns;
        count(&s->cnt.tx_dropped);
    }
    memmove(tx + ns, tx, k * sizeof *tx);
    memcpy(tx, sync, ns * sizeof *tx);
    s->cnt.sync_sent = vh_sat_add_u32(s->cnt.sync_sent, (uint32_t)ns);
    return k + ns;
}
