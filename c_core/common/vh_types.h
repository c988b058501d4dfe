/* vh_types.h - types shared by the ECU firmware and the simulated nodes.
 *
 * Only <stdint.h>/<stddef.h>: the firmware has no clock, no I/O and no heap.
 */
#ifndef VH_TYPES_H
#define VH_TYPES_H

#include <stddef.h>
#include <stdint.h>

/* Status codes returned by *_init and friends. */
enum {
    VH_OK = 0,
    VH_EINVAL = -1, /* a configuration value out of its documented range */
    VH_ENOSPC = -2  /* caller's buffer too small */
};

/* Frame flags (same meaning as python-can's Message fields). */
enum {
    VH_FRAME_EXT = 1u, /* 29-bit identifier */
    VH_FRAME_FD = 2u,  /* CAN FD frame */
    VH_FRAME_BRS = 4u  /* CAN FD bit-rate switch */
};

#define VH_FRAME_MAX_LEN 64

/* One CAN (FD) frame as it crosses the firmware boundary. */
typedef struct {
    uint32_t id;                    /* 11- or 29-bit identifier */
    uint8_t len;                    /* payload length in bytes, 0..64 */
    uint8_t flags;                  /* VH_FRAME_* */
    uint8_t data[VH_FRAME_MAX_LEN]; /* payload; bytes past len are zero */
} vh_frame_t;

/* Fixed ECU tick: 500 us (2 kHz), the rate of the torque transducer in seed 001. */
#define VH_TICK_US 500u

/* a + b, stopping at UINT32_MAX: every counter of the firmware counts through this, because a
 * wrapped count reads as "few faults" (uint32 at 2 kHz takes 24 days of one count per tick). */
static inline uint32_t vh_sat_add_u32(uint32_t a, uint32_t b)
{
    return (a > UINT32_MAX - b) ? UINT32_MAX : a + b;
}

/* A counter put in a bus field whose largest value is `max` (0xFFFF for 16 bits): the count, or
 * `max` when it is that large or larger, and then *saturated = 1 (the field reads "max or more"). */
static inline uint32_t vh_sat_field_u32(uint32_t count, uint32_t max, uint8_t *saturated)
{
    if (count >= max) {
        *saturated = 1u;
        return max;
    }
    return count;
}

#endif /* VH_TYPES_H */
