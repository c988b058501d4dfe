/* vh_bench_ecu_secoc.c - the ECU tick with SecOC on, beside off (`vehest-can bench`).
 *
 * Every system's frames (a driveline launch, the chassis node, the roll node on the 14-DOF plant in a
 * 72 km/h steer ramp, the same for all); the DLS, chassis and roll nodes secure their frames. Three ECUs step tick by
 * tick in turn (a loaded machine slows all alike), each tick timed (vh_bench_common.h):
 *   ecu_tick_secoc_off     SecOC off, fed the frames as a node without SecOC sends them (tails zero)
 *   ecu_tick_secoc_on      SecOC on: the nodes' frames verified, the ECU's own secured frames
 *                          protected, its sync frames at 1 Hz
 *   ecu_tick_secoc_forged  on, and one forged ROLL_Sensors per tick besides (each costs the verifier
 *                          its VH_SECOC_VERIFY_ATTEMPTS candidates and the replay check: the worst case)
 * plus a check line "secoc_counts ticks accepted rejected" of the second ECU (0 rejected).
 * The keys are RFC 4493's published test key: a bench, not a secret. */
#define _POSIX_C_SOURCE 199309L
#include <stddef.h>
#include <stdio.h>
#include <string.h>

#include "vh_bench_common.h"
#include "vh_bench_drive.h"

#include "vh_ch.h"
#include "vh_chsnode.h"
#include "vh_dlsim.h"
#include "vh_ecu.h"
#include "vh_rollnode.h"
#include "vh_secoc_bus.h"
#include "vh_veh14.h"

#define N_SAMPLES 40000
#define PER_TICK 9 /* DLS + CHS + the roll node's 4, each node's sync frame */

static const uint8_t KEY[16] = {0x2b, 0x7e, 0x15, 0x16, 0x28, 0xae, 0xd2, 0xa6,
                                0xab, 0xf7, 0x15, 0x88, 0x09, 0xcf, 0x4f, 0x3c};

static vh_frame_t s_sec[N_SAMPLES][PER_TICK], s_plain[N_SAMPLES][PER_TICK];
static size_t s_n[N_SAMPLES];
static double s_off[N_SAMPLES], s_on[N_SAMPLES], s_forged[N_SAMPLES];

static int keyed(vh_secoc_bus_t *s, const char *self)
{
    vh_secoc_bus_init(s, (unsigned)vh_secoc_bus_node(self));
    return vh_secoc_bus_set_key(s, (unsigned)vh_secoc_bus_node("VEHEST"), KEY) == VH_OK &&
           vh_secoc_bus_set_key(s, (unsigned)vh_secoc_bus_node("ROLL"), KEY) == VH_OK &&
           vh_secoc_bus_set_key(s, (unsigned)vh_secoc_bus_node("DLS"), KEY) == VH_OK &&
           vh_secoc_bus_set_key(s, (unsigned)vh_secoc_bus_node("CHS"), KEY) == VH_OK &&
           vh_secoc_bus_start(s, 1u, UINT64_MAX) == VH_OK;
}

/* Every tick's frames, secured by the DLS, chassis and roll nodes, and as nodes without SecOC send them. */
static int make_frames(void)
{
    static vh_dlsim_t sim;
    static vh_v14_t plant;
    static vh_v14_params_t prm;
    static vh_rln_t roll;
    static vh_secoc_bus_t node, peer, dls, chs_sec;
    vh_v14_input_t in;
    vh_chs_config_t ccfg;
    vh_chs_t chs;
    vh_rln_config_t rcfg;
    size_t j;
    int i;

    vh_v14_params_default(&prm);
    vh_chs_config_default(&ccfg);
    vh_rln_config_default(&rcfg);
    rcfg.mode_active = 1u;
    if (!vh_bench_launch_init(&sim) || vh_v14_init(&plant, &prm) != VH_OK ||
        vh_v14_set_rolling(&plant, 20.0) != VH_OK || vh_chs_init(&chs, &ccfg) != VH_OK ||
        vh_rln_init(&roll, &rcfg) != VH_OK || !keyed(&node, "ROLL") || !keyed(&peer, "VEHEST") ||
        !keyed(&dls, "DLS") || !keyed(&chs_sec, "CHS")) {
        return 0;
    }
    vh_rln_set_secoc(&roll, &node);
    vh_chs_set_secoc(&chs, &chs_sec);
    vh_dlsim_set_secoc(&sim, &dls, NULL);
    vh_v14_input_init(&in, 1.0);
    for (i = 0; i < N_SAMPLES; ++i) {
        const double t = i * 5e-4;
        in.steer = 0.0873 * (t < 0.5 ? 0.0 : (t < 2.5 ? (t - 0.5) / 2.0 : 1.0));
        s_n[i] = vh_bench_launch_tick(&sim, i, &s_sec[i][0], 2u);
        vh_rln_actuate(&roll, &plant);
        vh_v14_step(&plant, &in);
        s_n[i] += vh_chs_step(&chs, &plant.truth, &s_sec[i][s_n[i]], 2u); /* + its sync frame */
        s_n[i] += vh_rln_step(&roll, &plant, &s_sec[i][s_n[i]], PER_TICK - s_n[i]);
        for (j = 0; j < s_n[i]; ++j) { /* the verified copy has the tail zeroed: what SecOC off sends */
            if (vh_secoc_bus_rx(&peer, &s_sec[i][j], &s_plain[i][j]) == VH_SECOC_BUS_PASS) {
                s_plain[i][j] = s_sec[i][j];
            }
        }
    }
    return peer.cnt.rejected == 0u;
}

int main(void)
{
    static vh_ecu_t off, on, forged;
    static vh_secoc_bus_t s_on_ecu, s_forged_ecu;
    vh_ecu_config_t cfg;
    vh_frame_t tx[VH_ECU_MAX_TX], fake;
    double clock_ns, t0;
    size_t j;
    int i;
    volatile size_t sink = 0u;

    clock_ns = vh_bench_clock(s_off, N_SAMPLES);
    if (!make_frames()) {
        return 1;
    }
    vh_ecu_config_default(&cfg);
    if (vh_ecu_init(&off, &cfg) != VH_OK || vh_ecu_init(&on, &cfg) != VH_OK || vh_ecu_init(&forged, &cfg) != VH_OK ||
        !keyed(&s_on_ecu, "VEHEST") || !keyed(&s_forged_ecu, "VEHEST")) {
        return 1;
    }
    vh_ecu_set_secoc(&on, &s_on_ecu);
    vh_ecu_set_secoc(&forged, &s_forged_ecu);
    memset(&fake, 0xA5, sizeof fake);
    fake.id = VH_CH_ROLL_SENSORS_FRAME_ID;
    fake.len = VH_CH_ROLL_SENSORS_LENGTH;
    fake.flags = VH_FRAME_FD | VH_FRAME_BRS;
    for (i = 0; i < N_SAMPLES; ++i) {
        t0 = vh_bench_now_ns();
        for (j = 0; j < s_n[i]; ++j) {
            vh_ecu_rx(&off, &s_plain[i][j]);
        }
        sink += vh_ecu_step(&off, tx, VH_ECU_MAX_TX);
        s_off[i] = vh_bench_now_ns() - t0;

        t0 = vh_bench_now_ns();
        for (j = 0; j < s_n[i]; ++j) {
            vh_ecu_rx(&on, &s_sec[i][j]);
        }
        sink += vh_ecu_step(&on, tx, VH_ECU_MAX_TX);
        s_on[i] = vh_bench_now_ns() - t0;

        fake.data[i % 44] = (uint8_t)i; /* a different forgery every tick */
        t0 = vh_bench_now_ns();
        vh_ecu_rx(&forged, &fake);
        for (j = 0; j < s_n[i]; ++j) {
            vh_ecu_rx(&forged, &s_sec[i][j]);
        }
        sink += vh_ecu_step(&forged, tx, VH_ECU_MAX_TX);
        s_forged[i] = vh_bench_now_ns() - t0;
    }
    vh_bench_report("ecu_tick_secoc_off", s_off, N_SAMPLES, clock_ns);
    vh_bench_report("ecu_tick_secoc_on", s_on, N_SAMPLES, clock_ns);
    vh_bench_report("ecu_tick_secoc_forged", s_forged, N_SAMPLES, clock_ns);
    printf("secoc_counts %d %u %u\n", N_SAMPLES, (unsigned)s_on_ecu.cnt.accepted, (unsigned)s_on_ecu.cnt.rejected);
    return sink == 0u ? 0 : 0;
}
