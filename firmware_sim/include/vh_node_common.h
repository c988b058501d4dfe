/* vh_node_common.h - the scaffolding the simulated CAN sensor nodes (DLS, CHS, ROLL) share: the
 * check of their per-channel noise and bias, one noisy sample of every channel, the validity
 * qualifier of a channel and the next frame slot of a tick. Encoding, packing and E2E stay in each
 * node: the generated codec is per message.
 *
 * The noise of every channel is drawn every sample, in channel order, whatever its level (0
 * included) or fault state, so changing or failing one channel never shifts another channel's
 * noise sequence; golden logs depend on this draw order.
 */
#ifndef VH_NODE_COMMON_H
#define VH_NODE_COMMON_H

#include <stddef.h>
#include <stdint.h>

#include "vh_rng.h"
#include "vh_types.h"

/* VH_OK, or VH_EINVAL for a negative or non-finite noise level or a non-finite bias (bias NULL:
 * the node has none). */
int vh_node_check(const double *noise_std, const double *bias, int nch);
/* The random stream restarted from seed and v[0..nch) zeroed (a node's reset). */
void vh_node_restart(vh_rng_t *rng, uint64_t seed, double *v, int nch);
/* out[i] = phys[i] + bias[i] + noise_std[i] * N(0, 1) for i = 0..nch-1 in order (bias NULL: none);
 * out may be phys. */
void vh_node_sample(vh_rng_t *rng, const double *phys, const double *bias, const double *noise_std, int nch,
                    double *out);
/* ok[i] = 1 when v[i] is finite and bit i of fail_mask is clear: a sensor that reads garbage
 * reports it rather than sending a clamped number. */
void vh_node_qualify(const double *v, uint32_t fail_mask, int nch, uint8_t *ok);
/* f as an empty FD|BRS frame of id and len (payload zeroed), to be packed and E2E protected. */
void vh_node_frame_init(vh_frame_t *f, uint32_t id, size_t len);
/* A node that sends several frames a tick: out[*k] through vh_node_frame_init, *k advanced; NULL
 * when *k >= cap. */
vh_frame_t *vh_node_slot(vh_frame_t *out, size_t *k, size_t cap, uint32_t id, size_t len);
/* One more frame sent: *frames + 1, saturating. */
void vh_node_count(uint32_t *frames);

#endif /* VH_NODE_COMMON_H */
