/* vh_car.c - see vh_car.h. */
#include <string.h>

#include "vh_car.h"

void vh_car_init(vh_car_t *car, void *self, size_t (*tick)(void *, size_t, vh_frame_t *, size_t),
                 void (*rx)(void *, const vh_frame_t *), const void *(*truth)(void *), size_t truth_size, size_t max_tx)
{
    car->self = self;
    car->tick = tick;
    car->rx = rx;
    car->truth = truth;
    car->truth_size = truth_size;
    car->max_tx = max_tx;
}

size_t vh_car_tick(const vh_car_t *car, size_t k, vh_frame_t *out, size_t cap)
{
    return car->tick(car->self, k, out, cap);
}

void vh_car_rx(const vh_car_t *car, const vh_frame_t *f)
{
    if (car->rx != NULL) {
        car->rx(car->self, f);
    }
}

const void *vh_car_truth(const vh_car_t *car)
{
    return car->truth(car->self);
}

size_t vh_car_run(const vh_car_t *car, size_t k0, size_t n)
{
    vh_frame_t buf[VH_CAR_MAX_TX];
    const size_t max_car = car->max_tx < VH_CAR_MAX_TX ? car->max_tx : VH_CAR_MAX_TX;
    size_t t, total = 0u;
    for (t = 0; t < n; ++t) {
        total += car->tick(car->self, k0 + t, buf, max_car);
        (void)car->truth(car->self);
    }
    return total;
}

size_t vh_lockstep_run(const vh_car_t *car, vh_ecu_t *ecu, size_t k0, size_t n, void *truth, vh_frame_t *frames,
                       uint32_t *frame_tick, size_t cap)
{
    vh_frame_t buf[VH_CAR_MAX_TX + VH_ECU_MAX_TX];
    const size_t max_car = car->max_tx < VH_CAR_MAX_TX ? car->max_tx : VH_CAR_MAX_TX;
    size_t t, i, total = 0u;
    for (t = 0; t < n; ++t) {
        const size_t ncar = car->tick(car->self, k0 + t, buf, max_car);
        size_t nall;
        for (i = 0; i < ncar; ++i) {
            vh_ecu_rx(ecu, &buf[i]);
        }
        nall = ncar + vh_ecu_step(ecu, buf + ncar, VH_ECU_MAX_TX);
        for (i = ncar; car->rx != NULL && i < nall; ++i) {
            car->rx(car->self, &buf[i]); /* applied from the car's next tick */
        }
        for (i = 0; i < nall; ++i, ++total) {
            if (total < cap) {
                frames[total] = buf[i];
                frame_tick[total] = (uint32_t)(k0 + t);
            }
        }
        if (truth != NULL) {
            memcpy((unsigned char *)truth + t * car->truth_size, car->truth(car->self), car->truth_size);
        }
    }
    return total;
}
