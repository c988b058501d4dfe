/* fuzz_ecu.c - coverage-guided fuzz target (libFuzzer) for the ECU's RX + tick path.
 *
 * The input is a program of records, each starting with an op byte:
 *   0  raw frame:        id selector, flags, len, payload  (anything, CRC almost never right)
 *   1  protected frame:  which RX message, counter step, payload; the E2E CRC and alive counter
 *                        are made right, so the fuzzer reaches the decode, the checks behind
 *                        E2E (SNA, qualifiers, ranges) and the filters
 *   2  ticks:            step the ECU 1..16 times with a fuzzed TX capacity
 *   3  deadline misses / reset
 * The camber calibration is loaded (as a daemon with --camber-cal runs). After every step the
 * transmitted frames are checked: known IDs only, the DBC length, within the capacity; the
 * driveline estimates stay finite. A violation is a crash (abort), like a sanitizer report.
 */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "vh_ch.h"
#include "vh_ch_meta.h"
#include "vh_e2e.h"
#include "vh_ecu.h"
#include "vh_pt.h"
#include "vh_pt_meta.h"

typedef struct {
    uint32_t id;
    uint8_t len;
    uint16_t data_id;
} rx_msg_t;

static const rx_msg_t RX[] = {
    {VH_PT_DLS_SENSORS_FRAME_ID, VH_PT_DLS_SENSORS_LENGTH, VH_PT_DLS_SENSORS_E2E_DATA_ID},
    {VH_PT_CIS_ACCEL_FRAME_ID, VH_PT_CIS_ACCEL_LENGTH, VH_PT_CIS_ACCEL_E2E_DATA_ID},
    {VH_CH_CHS_SENSORS_FRAME_ID, VH_CH_CHS_SENSORS_LENGTH, VH_CH_CHS_SENSORS_E2E_DATA_ID},
};
#define N_RX (sizeof RX / sizeof RX[0])

static const struct {
    uint32_t id;
    uint8_t len;
} TX[] = {
    {VH_PT_VEHEST_DRIVELINE_EST_FRAME_ID, VH_PT_VEHEST_DRIVELINE_EST_LENGTH},
    {VH_PT_VEHEST_STATUS_FRAME_ID, VH_PT_VEHEST_STATUS_LENGTH},
    {VH_PT_VEHEST_CAMBER_FRAME_ID, VH_PT_VEHEST_CAMBER_LENGTH},
    {VH_PT_VEHEST_SYNC_ACK_FRAME_ID, VH_PT_VEHEST_SYNC_ACK_LENGTH},
    {VH_CH_VEHEST_TIRE_FORCE_EST_FRAME_ID, VH_CH_VEHEST_TIRE_FORCE_EST_LENGTH},
    {VH_CH_VEHEST_CHASSIS_STATUS_FRAME_ID, VH_CH_VEHEST_CHASSIS_STATUS_LENGTH},
    {VH_CH_VEHEST_TIRE_FORCE_ADAPTIVE_FRAME_ID, VH_CH_VEHEST_TIRE_FORCE_ADAPTIVE_LENGTH},
};

typedef struct {
    const uint8_t *p;
    size_t n;
} input_t;

static int take(input_t *in, uint8_t *b)
{
    if (in->n == 0u) {
        return 0;
    }
    *b = *in->p++;
    in->n--;
    return 1;
}

static void check_tx(const vh_ecu_t *ecu, const vh_frame_t *tx, size_t n, size_t cap)
{
    size_t i, k;
    int known;
    if (n > cap) {
        abort();
    }
    for (i = 0; i < n; ++i) {
        known = 0;
        for (k = 0; k < sizeof TX / sizeof TX[0]; ++k) {
            if (tx[i].id == TX[k].id) {
                known = 1;
                if (tx[i].len != TX[k].len || (tx[i].flags & VH_FRAME_EXT)) {
                    abort();
                }
            }
        }
        if (!known) {
            abort();
        }
    }
    for (i = 0; i < VH_ECU_N_DKF; ++i) {
        if (!isfinite(ecu->dkf[i].x[2])) {
            abort();
        }
    }
}

static vh_ecu_t ecu; /* fuzzing harness state (not firmware): one instance, re-initialised per input */

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static const float x[3] = {1.0f, 0.0f, 0.0f}, z[3] = {0.0f, 0.0f, 1.0f}, lsb[3] = {0.004f, 0.004f, 0.004f};
    vh_ecu_config_t cfg;
    vh_camber_cal_t cal;
    vh_frame_t f, tx[VH_ECU_MAX_TX];
    uint8_t counter[N_RX] = {0u, 0u, 0u};
    input_t in = {data, size};
    uint8_t op, a, b, c;
    unsigned w, k;

    vh_ecu_config_default(&cfg);
    if (vh_ecu_init(&ecu, &cfg) != VH_OK || vh_camber_cal_from_axes(&cal, x, z, lsb, 1e-3f) != VH_OK) {
        abort();
    }
    for (w = 0; w < VH_ECU_N_WHEELS; ++w) {
        (void)vh_ecu_set_camber_calibration(&ecu, w, &cal);
    }
    while (take(&in, &op)) {
        switch (op & 3u) {
        case 0: /* raw frame */
            if (!take(&in, &a) || !take(&in, &b) || !take(&in, &c)) {
                return 0;
            }
            memset(&f, 0, sizeof f);
            f.id = (a < 2u * N_RX) ? RX[a % N_RX].id : ((uint32_t)a << 3 | (op >> 2)) & 0x7FFu;
            f.flags = b & 7u;
            f.len = (uint8_t)(c % 65u);
            for (k = 0; k < f.len && take(&in, &f.data[k]); ++k) {
            }
            vh_ecu_rx(&ecu, &f);
            break;
        case 1: /* a frame the E2E check accepts (or, with a counter step of 0 or > 1, flags) */
            if (!take(&in, &a) || !take(&in, &b)) {
                return 0;
            }
            memset(&f, 0, sizeof f);
            f.id = RX[a % N_RX].id;
            f.len = RX[a % N_RX].len;
            f.flags = VH_FRAME_FD | VH_FRAME_BRS;
            for (k = 2; k < f.len && take(&in, &f.data[k]); ++k) { /* bytes 0-1: CRC, counter */
            }
            counter[a % N_RX] = (uint8_t)(counter[a % N_RX] + (b & 3u) - 1u); /* protect adds 1 */
            vh_e2e_p01_protect(f.data, f.len, RX[a % N_RX].data_id, &counter[a % N_RX]);
            vh_ecu_rx(&ecu, &f);
            break;
        case 2: /* ticks */
            if (!take(&in, &a)) {
                return 0;
            }
            for (k = 0; k <= (a & 15u); ++k) {
                const size_t cap = (size_t)((a >> 4) % (VH_ECU_MAX_TX + 1u));
                check_tx(&ecu, tx, vh_ecu_step(&ecu, tx, cap), cap);
            }
            break;
        default: /* deadline misses, now and then a reset */
            if (!take(&in, &a)) {
                return 0;
            }
            if (a == 0xFFu) {
                vh_ecu_reset(&ecu);
            } else {
                vh_ecu_note_deadline_miss(&ecu, a);
            }
            break;
        }
    }
    check_tx(&ecu, tx, vh_ecu_step(&ecu, tx, VH_ECU_MAX_TX), VH_ECU_MAX_TX);
#ifdef VH_FUZZ_CANARY
    /* The suite's positive control: a "bug" behind an accepted chassis frame and a filter step.
     * The fuzzer must get there (and report it) from its seeds, or the harness reaches too little. */
    if (ecu.chs.heard && ecu.chs.skf.steps > 0u) {
        abort();
    }
#endif
    return 0;
}
