/* vh_dlsim.c - see vh_dlsim.h. */
#include <string.h>

#include "vh_dlsim.h"
#include "vh_e2e.h"
#include "vh_node_common.h"
#include "vh_pt.h"
#include "vh_pt_meta.h"

#define CIS_PERIOD_TICKS (VH_PT_CIS_ACCEL_CYCLE_TIME_US / VH_TICK_US)

int vh_dlsim_init(vh_dlsim_t *sim, const vh_dlp_params_t *prm, uint64_t plant_seed, const vh_dls_config_t *node)
{
    memset(sim, 0, sizeof *sim);
    if (vh_dlp_init(&sim->plant, prm, plant_seed) != VH_OK || vh_dls_init(&sim->node, node) != VH_OK) {
        return VH_EINVAL;
    }
    return VH_OK;
}

void vh_dlsim_reset(vh_dlsim_t *sim)
{
    int i;
    vh_dlp_reset(&sim->plant);
    vh_dls_reset(&sim->node);
    for (i = 0; sim->cis_on && i < VH_DLSIM_N_CIS; ++i) {
        const int pose = sim->cis[i].pose;
        vh_cambernode_reset(&sim->cis[i]);
        (void)vh_cambernode_set_pose(&sim->cis[i], pose);
    }
    sim->cis_counter = 0u;
    sim->ticks = 0u;
    if (sim->dls_secoc != NULL) {
        vh_secoc_bus_resync(sim->dls_secoc); /* the ECU may have restarted too */
    }
    if (sim->cis_secoc != NULL) {
        vh_secoc_bus_resync(sim->cis_secoc);
    }
}

void vh_dlsim_set_secoc(vh_dlsim_t *sim, vh_secoc_bus_t *dls, vh_secoc_bus_t *cis)
{
    sim->dls_secoc = dls;
    sim->cis_secoc = cis;
}

int vh_dlsim_set_camber(vh_dlsim_t *sim, const vh_cambernode_config_t cfg[VH_DLSIM_N_CIS], int pose)
{
    vh_cambernode_t nodes[VH_DLSIM_N_CIS];
    int i;
    if (cfg == NULL) {
        sim->cis_on = 0u;
        return VH_OK;
    }
    for (i = 0; i < VH_DLSIM_N_CIS; ++i) {
        if (vh_cambernode_init(&nodes[i], &cfg[i]) != VH_OK || vh_cambernode_set_pose(&nodes[i], pose) != VH_OK) {
            return VH_EINVAL;
        }
    }
    memcpy(sim->cis, nodes, sizeof nodes);
    sim->cis_on = 1u;
    return VH_OK;
}

/* CIS_Accel: one raw sample of each device, E2E protected. Counts travel as the chip gives them. */
static size_t cis_frame(vh_dlsim_t *sim, vh_frame_t *f)
{
    struct vh_pt_cis_accel_t m;
    int16_t raw[VH_DLSIM_N_CIS][3];
    int i;
    for (i = 0; i < VH_DLSIM_N_CIS; ++i) {
        vh_cambernode_step(&sim->cis[i], raw[i]);
    }
    memset(&m, 0, sizeof m);
    m.cis_lsb_micro_g = (uint16_t)(sim->cis[0].cfg.lsb_g[0] * 1e6 + 0.5);
    m.cis_acc_x_fl = raw[0][0]; m.cis_acc_y_fl = raw[0][1]; m.cis_acc_z_fl = raw[0][2];
    m.cis_acc_x_fr = raw[1][0]; m.cis_acc_y_fr = raw[1][1]; m.cis_acc_z_fr = raw[1][2];
    m.cis_acc_x_rl = raw[2][0]; m.cis_acc_y_rl = raw[2][1]; m.cis_acc_z_rl = raw[2][2];
    m.cis_acc_x_rr = raw[3][0]; m.cis_acc_y_rr = raw[3][1]; m.cis_acc_z_rr = raw[3][2];
    m.cis_present = 0xFu;
    vh_node_frame_init(f, VH_PT_CIS_ACCEL_FRAME_ID, VH_PT_CIS_ACCEL_LENGTH);
    (void)vh_pt_cis_accel_pack(f->data, &m, f->len);
    vh_e2e_protect(VH_PT_CIS_ACCEL_E2E, f->data, f->len, &sim->cis_counter);
    return 1u;
}

size_t vh_dlsim_tick(vh_dlsim_t *sim, double throttle, int gear, vh_frame_t *out, size_t cap)
{
    size_t n;
    vh_dlp_step(&sim->plant, throttle, gear);
    n = vh_dls_step(&sim->node, &sim->plant.truth, out, cap);
    if (sim->dls_secoc != NULL) {
        n = vh_secoc_bus_tx(sim->dls_secoc, out, n, cap);
    }
    if (sim->cis_on) {
        const size_t c = (sim->ticks % CIS_PERIOD_TICKS == 0u && n < cap) ? cis_frame(sim, out + n) : 0u;
        /* the devices' SecOC hook runs every tick, as a node's does: its sync frame is due by ticks */
        n += sim->cis_secoc != NULL ? vh_secoc_bus_tx(sim->cis_secoc, out + n, c, cap - n) : c;
    }
    ++sim->ticks;
    return n;
}

static size_t car_tick(void *self, size_t k, vh_frame_t *out, size_t cap)
{
    vh_dlsim_t *sim = self;
    const size_t i = k < sim->n ? k : sim->n - 1u;
    return vh_dlsim_tick(sim, sim->throttle[i], sim->gear[i], out, cap);
}

static const void *car_truth(void *self)
{
    return &((const vh_dlsim_t *)self)->plant.truth;
}

void vh_dlsim_car(vh_dlsim_t *sim, const double *throttle, const uint8_t *gear, size_t n, vh_car_t *car)
{
    sim->throttle = throttle;
    sim->gear = gear;
    sim->n = n;
    vh_car_init(car, sim, car_tick, NULL, car_truth, sizeof sim->plant.truth, VH_DLSIM_MAX_TX);
}
