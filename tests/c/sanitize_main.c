/* sanitize_main.c - drives the firmware under AddressSanitizer + UndefinedBehaviorSanitizer.
 *
 * Built by tests/test_sanitizers.py from the same sources as the extension. Exercises the codec,
 * E2E, the filter and the ECU tick with good frames, random garbage and hostile values, and (when
 * the simulator is built in) the in-process lockstep of plant, sensor node and ECU. Any sanitizer
 * report aborts with a non-zero status (-fno-sanitize-recover=all).
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "vh_dkf.h"
#include "vh_e2e.h"
#include "vh_ecu.h"
#include "vh_pt.h"
#include "vh_pt_meta.h"

static uint64_t rng_state = 0x9E3779B97F4A7C15ull;

static uint32_t rnd(void)
{
    rng_state ^= rng_state << 13;
    rng_state ^= rng_state >> 7;
    rng_state ^= rng_state << 17;
    return (uint32_t)(rng_state >> 16);
}

static void good_dls(vh_frame_t *f, uint8_t *counter, double torque)
{
    struct vh_pt_dls_sensors_t m;
    memset(&m, 0, sizeof m);
    m.out_shaft_speed = 10000u;
    m.wheel_speed_l = 2550u;
    m.wheel_speed_r = 2550u;
    m.shaft_torque = (int16_t)(torque / 0.25);
    m.engine_speed = 25000u;
    m.turbine_speed = 23255u;
    m.qf_out_shaft_speed = m.qf_wheel_speed_l = m.qf_wheel_speed_r = 1u;
    m.qf_shaft_torque = m.qf_engine_speed = m.qf_turbine_speed = 1u;
    m.gear_engaged = 2u;
    memset(f, 0, sizeof *f);
    f->id = VH_PT_DLS_SENSORS_FRAME_ID;
    f->len = VH_PT_DLS_SENSORS_LENGTH;
    f->flags = VH_FRAME_FD | VH_FRAME_BRS;
    (void)vh_pt_dls_sensors_pack(f->data, &m, f->len);
    vh_e2e_protect(VH_PT_DLS_SENSORS_E2E, f->data, f->len, counter);
}

#ifdef VH_WITH_SIM
int vh_sanitize_sim(void); /* sanitize_sim.c */
#endif

int main(void)
{
    static vh_ecu_t ecu;
    vh_ecu_config_t cfg;
    vh_frame_t rx, tx[VH_ECU_MAX_TX];
    uint8_t counter = 0u;
    size_t total_tx = 0u;
    long i;
    unsigned k;

    vh_ecu_config_default(&cfg);
    if (vh_ecu_init(&ecu, &cfg) != VH_OK) {
        fprintf(stderr, "init failed\n");
        return 1;
    }
    for (i = 0; i < 200000; ++i) {
        const uint32_t r = rnd();
        if (r % 10u < 7u) { /* mostly good frames, some with extreme torque */
            good_dls(&rx, &counter, (r % 97u == 0u) ? 8191.0 : 1500.0);
        } else { /* garbage of every length and ID */
            memset(&rx, 0, sizeof rx);
            rx.id = (r % 3u == 0u) ? VH_PT_DLS_SENSORS_FRAME_ID : (rnd() & 0x7FFu);
            rx.len = (uint8_t)(rnd() % 65u);
            rx.flags = (uint8_t)(rnd() & 7u);
            for (k = 0; k < rx.len; ++k) {
                rx.data[k] = (uint8_t)rnd();
            }
        }
        vh_ecu_rx(&ecu, &rx);
        total_tx += vh_ecu_step(&ecu, tx, (size_t)(rnd() % (VH_ECU_MAX_TX + 1u)));
        if (i % 50000 == 0) {
            vh_ecu_note_deadline_miss(&ecu, rnd());
        }
    }
    for (i = 0; i < VH_ECU_N_DKF; ++i) {
        if (!isfinite(ecu.app.drv.dkf[i].x[2])) {
            fprintf(stderr, "non-finite estimate\n");
            return 1;
        }
    }
    printf("ecu: %lu frames out, crc %u dlc %u unknown %u resets %u\n", (unsigned long)total_tx,
           ecu.cnt.crc_error, ecu.cnt.dlc_error, ecu.cnt.unknown_id, ecu.cnt.filter_reset);
#ifdef VH_WITH_SIM
    if (vh_sanitize_sim() != 0) {
        return 1;
    }
#endif
    printf("sanitize: ok\n");
    return 0;
}
