/* vh_v14car.c - see vh_v14car.h. */
#include <string.h>

#include "vh_v14car.h"

static int start(vh_v14car_t *car)
{
    vh_secoc_bus_t *chs_secoc = car->chs.secoc, *rln_secoc = car->rln.secoc;
    if (vh_v14_init(&car->plant, &car->prm) != VH_OK || vh_v14_set_rolling(&car->plant, car->v0) != VH_OK
        || vh_chs_init(&car->chs, &car->chs_cfg) != VH_OK) {
        return VH_EINVAL;
    }
    vh_chs_set_secoc(&car->chs, chs_secoc);
    if (car->roll_on) {
        if (vh_v14_arc_config(&car->plant, &car->arc[0], &car->arc[1]) != VH_OK
            || vh_rln_init(&car->rln, &car->rln_cfg) != VH_OK) {
            return VH_EINVAL;
        }
        vh_rln_set_secoc(&car->rln, rln_secoc);
    }
    memset(&car->truth, 0, sizeof car->truth);
    return VH_OK;
}

int vh_v14car_init(vh_v14car_t *car, const vh_v14_params_t *prm, double v0, const vh_chs_config_t *chs_cfg,
                   const vh_rln_config_t *rln_cfg, const vh_v14_arc_params_t arc[2])
{
    if (car == NULL || prm == NULL || chs_cfg == NULL || (rln_cfg == NULL) != (arc == NULL)) {
        return VH_EINVAL;
    }
    memset(car, 0, sizeof *car);
    car->prm = *prm;
    car->v0 = v0;
    car->chs_cfg = *chs_cfg;
    if (rln_cfg != NULL) {
        car->rln_cfg = *rln_cfg;
        car->arc[0] = arc[0];
        car->arc[1] = arc[1];
        car->roll_on = 1u;
    }
    return start(car);
}

void vh_v14car_reset(vh_v14car_t *car)
{
    (void)start(car); /* init checked the same configuration */
}

void vh_v14car_set_plant(vh_v14car_t *car, vh_v14car_plant_fn fn, void *ctx)
{
    car->ext = fn;
    car->ext_ctx = ctx;
}

static size_t car_tick(void *self, size_t k, vh_frame_t *out, size_t cap)
{
    vh_v14car_t *car = self;
    const size_t i = k < car->n ? k : car->n - 1u;
    size_t n;
    if (car->roll_on) {
        car->rln.cfg.mode_active = car->mode_active[i];
        vh_rln_actuate(&car->rln, &car->plant);
    }
    if (car->ext != NULL) {
        vh_v14_arc_step(&car->plant);
        car->ext(car->ext_ctx, &car->in[i], car->plant.arc.m, &car->plant.truth, car->plant.x);
    } else {
        vh_v14_step(&car->plant, &car->in[i]);
    }
    n = vh_chs_step(&car->chs, &car->plant.truth, out, cap < 3u ? cap : 3u);
    if (car->roll_on) {
        n += vh_rln_step(&car->rln, &car->plant, out + n, cap - n);
    }
    return n;
}

static void car_rx(void *self, const vh_frame_t *f)
{
    vh_rln_rx(&((vh_v14car_t *)self)->rln, f);
}

static const void *car_truth(void *self)
{
    vh_v14car_t *car = self;
    car->truth.plant = car->plant.truth;
    if (car->roll_on) {
        car->truth.m_applied[0] = car->plant.arc.m[0];
        car->truth.m_applied[1] = car->plant.arc.m[1];
        car->truth.m_cmd[0] = car->plant.arc.cmd[0];
        car->truth.m_cmd[1] = car->plant.arc.cmd[1];
        car->truth.arc_state = car->rln.state;
        car->truth.mode_active = car->rln.cfg.mode_active;
    }
    return &car->truth;
}

void vh_v14car_car(vh_v14car_t *car, const vh_v14_input_t *in, const uint8_t *mode_active, size_t n,
                   vh_car_t *out)
{
    car->in = in;
    car->mode_active = mode_active;
    car->n = n;
    vh_car_init(out, car, car_tick, car->roll_on ? car_rx : NULL, car_truth, sizeof car->truth, VH_V14CAR_MAX_TX);
}
