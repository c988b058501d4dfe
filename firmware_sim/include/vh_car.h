/* vh_car.h - the interface every simulated car implements, and the in-process lockstep that runs
 * any car against the ECU.
 *
 * A car is a plant with the sensor nodes (and actuators) that talk for it on the bus. It is driven
 * by its own inputs, one per tick, set before the run (throttle and gear, steering and torques...).
 * Per tick the lockstep calls tick (the plant steps, the nodes sample and return their frames), hands
 * those frames to the ECU, steps the ECU, gives the ECU's frames back to the car (rx; a car whose
 * actuators listen applies them from its next tick) and keeps the car's truth. The same calls serve
 * a car on a bus (the Python simulator calls vh_car_tick / vh_car_rx per tick), so every mode sees
 * bit-identical frames.
 */
#ifndef VH_CAR_H
#define VH_CAR_H

#include <stddef.h>
#include <stdint.h>

#include "vh_ecu.h"
#include "vh_types.h"

/* The most frames a car sends in one tick (vh_car_t.max_tx of every car stays within it). */
#define VH_CAR_MAX_TX 8

typedef struct {
    void *self;
    /* Tick k of the drive: frames to out[0..cap), returns how many. */
    size_t (*tick)(void *self, size_t k, vh_frame_t *out, size_t cap);
    /* One frame the ECU sent; NULL: the car listens to none (the loop stays open). */
    void (*rx)(void *self, const vh_frame_t *f);
    /* The truth after the last tick: truth_size bytes. */
    const void *(*truth)(void *self);
    size_t truth_size;
    size_t max_tx; /* <= VH_CAR_MAX_TX */
} vh_car_t;

/* A car's interface filled in (what each car's own vh_*_car calls). */
void vh_car_init(vh_car_t *car, void *self, size_t (*tick)(void *, size_t, vh_frame_t *, size_t),
                 void (*rx)(void *, const vh_frame_t *), const void *(*truth)(void *), size_t truth_size, size_t max_tx);
size_t vh_car_tick(const vh_car_t *car, size_t k, vh_frame_t *out, size_t cap);
void vh_car_rx(const vh_car_t *car, const vh_frame_t *f);
const void *vh_car_truth(const vh_car_t *car);

/* Ticks k0 .. k0+n-1 of the car alone, its frames dropped (what the car costs); returns their number. */
size_t vh_car_run(const vh_car_t *car, size_t k0, size_t n);

/* Ticks k0 .. k0+n-1 of car and ECU in lockstep. Per tick: car frames -> vh_ecu_rx -> vh_ecu_step
 * -> the ECU's frames to the car. truth (n * truth_size bytes) receives the car's truth of each
 * tick (NULL: not kept). Every frame on the bus, the car's then the ECU's, goes to frames[] with
 * its tick in frame_tick[] until cap is reached; returns the number of frames (more than cap means
 * some were not stored). */
size_t vh_lockstep_run(const vh_car_t *car, vh_ecu_t *ecu, size_t k0, size_t n, void *truth, vh_frame_t *frames,
                       uint32_t *frame_tick, size_t cap);

#endif /* VH_CAR_H */
