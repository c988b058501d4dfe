/* vh_v14car.h - the 14-DOF car (vh_veh14.h) behind the car interface (vh_car.h): the plant, its
 * chassis sensor node (vh_chsnode.h) and, where the active roll system is fitted, the roll node with
 * the actuators it supervises (vh_rollnode.h). The car of the tyre-force and the roll system.
 *
 * Per tick, as the roll system's actuators need it: the roll node's commands into the plant, the
 * plant's step with the tick's input, the chassis node's frames, then the roll node's.
 */
#ifndef VH_V14CAR_H
#define VH_V14CAR_H

#include <stddef.h>
#include <stdint.h>

#include "vh_car.h"
#include "vh_chsnode.h"
#include "vh_rollnode.h"
#include "vh_veh14.h"

/* CHS_Sensors, CHS_RideHeight and the chassis node's SecOC sync frame; the roll node's four frames
 * and its sync frame */
#define VH_V14CAR_MAX_TX 8

/* The car's truth: the plant's, then the roll actuators' (zero without them). */
typedef struct {
    vh_v14_truth_t plant;
    double m_applied[2];  /* applied roll moments front, rear over the tick [Nm] */
    double m_cmd[2];      /* commanded [Nm] */
    uint8_t arc_state;    /* the roll node's supervision state (VH_RLN_ARC_*) */
    uint8_t mode_active;  /* the driver's roll-mode switch at this tick */
} vh_v14car_truth_t;

/* A plant in place of vh_veh14 (another vehicle model behind the same nodes): advances its own state
 * (in ctx) by one tick with `in` and the actuators' applied roll moments m (front, rear: on the body,
 * the reaction on that axle), and writes what vh_v14_step leaves for the nodes: *truth (the state at
 * the tick's start with the forces of `in`) and the unsprung heave rates after the tick in
 * x[VH_V14_X_VZU + i] (the roll node's wheel accelerometers). */
typedef void (*vh_v14car_plant_fn)(void *ctx, const vh_v14_input_t *in, const double m[2], vh_v14_truth_t *truth,
                                   double *x);

typedef struct {
    vh_v14_params_t prm;
    double v0;                     /* initial speed [m/s] */
    vh_chs_config_t chs_cfg;
    vh_rln_config_t rln_cfg;
    vh_v14_arc_params_t arc[2];    /* the actuators, front and rear */
    uint8_t roll_on;               /* roll node and actuators fitted */
    vh_v14_t plant;
    vh_chs_t chs;
    vh_rln_t rln;                  /* roll_on only; its cfg (fail/stuck masks, bias) may change between ticks */
    const vh_v14_input_t *in;      /* the drive: one input per tick, caller-owned */
    const uint8_t *mode_active;    /* the driver's switch per tick (roll_on only), caller-owned */
    size_t n;                      /* ticks of the drive (>= 1): its last input holds after */
    vh_v14car_truth_t truth;
    vh_v14car_plant_fn ext;        /* another plant, or NULL: vh_veh14 with prm */
    void *ext_ctx;
} vh_v14car_t;

/* VH_OK, or VH_EINVAL (nothing usable) when the plant refuses prm or v0, a node its config or the
 * plant the actuators' limits. rln_cfg and arc NULL: no roll system fitted. The car starts reset. */
int vh_v14car_init(vh_v14car_t *car, const vh_v14_params_t *prm, double v0, const vh_chs_config_t *chs_cfg,
                   const vh_rln_config_t *rln_cfg, const vh_v14_arc_params_t arc[2]);
/* As after init: plant, nodes and actuators at their start; the nodes' SecOC hooks (vh_chs_set_secoc,
 * vh_rln_set_secoc on car->chs / car->rln) are kept. */
void vh_v14car_reset(vh_v14car_t *car);
/* Another plant in place of vh_veh14 from the next tick on (NULL: back to vh_veh14); prm still gives the
 * nodes the corner geometry and the actuators their limits. The caller resets its state with the car's. */
void vh_v14car_set_plant(vh_v14car_t *car, vh_v14car_plant_fn fn, void *ctx);
/* The car interface of car, driven by in[k] (and mode_active[k]) for k < n. */
void vh_v14car_car(vh_v14car_t *car, const vh_v14_input_t *in, const uint8_t *mode_active, size_t n,
                   vh_car_t *out);

#endif /* VH_V14CAR_H */
