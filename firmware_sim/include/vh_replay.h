/* vh_replay.h - a recorded log through the ECU at native speed (host only: `vehest-can replay`).
 *
 * vh_candump_parse reads candump -L text (can-utils' log format, with python-can's optional R/T
 * direction) into frames; vh_replay_run hands a batch of events to the ECU: per event, first its
 * ticks, then its frame or reset. Python (vehest_can.service.replay) turns a log into events
 * (sync frames or timestamps), so both follow the same rules as the message-by-message replay.
 */
#ifndef VH_REPLAY_H
#define VH_REPLAY_H

#include <stddef.h>
#include <stdint.h>

#include "vh_ecu.h"
#include "vh_types.h"

/* What an event does after its ticks */
enum {
    VH_REPLAY_NONE = 0,  /* nothing (a SIM_Sync STEP: its tick only; END) */
    VH_REPLAY_RX = 1,    /* hand in[i] to the ECU (vh_ecu_rx) */
    VH_REPLAY_RESET = 2  /* vh_ecu_reset (SIM_Sync RESET) */
};

/* Where a replay stands: the next event and how many of its ticks have run */
typedef struct {
    size_t event;
    uint32_t step;
} vh_replay_pos_t;

/* Events pos->event..n-1: steps[i] ticks of the ECU, then op[i]. Each frame the ECU transmits goes
 * to out[] with the index of its event in out_event[] and of its tick within that event in
 * out_step[]. Stops when out[] could not hold another tick's frames (cap - written < VH_ECU_MAX_TX)
 * or at n; returns the frames written, pos says where to go on (done when pos->event == n). */
size_t vh_replay_run(vh_ecu_t *ecu, const vh_frame_t *in, const uint8_t *op, const uint32_t *steps, size_t n,
                     vh_replay_pos_t *pos, vh_frame_t *out, uint32_t *out_event, uint32_t *out_step, size_t cap);

/* Parse the complete lines of buf[0..len) (with final != 0, an unterminated last line too) into
 * out[]/ts[] until cap frames: data frames only (remote and error frames are skipped and counted
 * in *skipped). *used = bytes consumed (whole lines), *lines = lines consumed. VH_OK, or VH_EINVAL
 * at a line that is not a candump -L frame (*used is then the offset of that line). */
int vh_candump_parse(const char *buf, size_t len, int final, vh_frame_t *out, double *ts, size_t cap,
                     size_t *n_out, size_t *used, size_t *lines, size_t *skipped);

#endif /* VH_REPLAY_H */
