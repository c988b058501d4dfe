/* vh_tf_types.h - what the double (vh_skf) and the fixed-point (vh_skfq) SKFMEC share: the
 * sizes, the state and measurement indices and the validity mask of a step (seed 000).
 * Declarations only, no types with doubles: the integer-only filter includes this, not vh_skf.h.
 */
#ifndef VH_TF_TYPES_H
#define VH_TF_TYPES_H

#define VH_SKF_NX 7
#define VH_SKF_NY 4
#define VH_SKF_NU 13 /* doubles in vh_skf_input_t */

/* State and measurement indices. */
enum { VH_SKF_VX = 0, VH_SKF_VY = 1, VH_SKF_R = 2, VH_SKF_PHI = 3, VH_SKF_P = 4, VH_SKF_FYF = 5, VH_SKF_FYR = 6 };
enum { VH_SKF_AX = 0, VH_SKF_AY = 1, VH_SKF_YR = 2, VH_SKF_YP = 3 };
/* Validity mask of a step: measurement bits, and one bit for the inputs (steer, wheel speeds,
 * torques). Without a measurement bit that row is not used (and eq. 39 takes 0 for an invalid
 * ax or ay); without U_VALID the last longitudinal forces and steering angle are held. Either
 * makes the step DEGRADED. A non-finite input clears the whole mask for that step. */
enum {
    VH_SKF_Y_AX = 1u, VH_SKF_Y_AY = 2u, VH_SKF_Y_R = 4u, VH_SKF_Y_P = 8u, VH_SKF_Y_ALL = 15u,
    VH_SKF_U_VALID = 16u, VH_SKF_ALL_VALID = 31u
};
/* What the first usable sample needs, to seed the state (vx from the wheel speeds, the axle
 * forces and roll angle from a_y, r; the roll rate p where it is valid, else 0: a car without a
 * roll-rate sensor runs without it, DEGRADED): the step waits without them. */
enum { VH_SKF_SEED_VALID = VH_SKF_U_VALID | VH_SKF_Y_AY | VH_SKF_Y_R };

#endif /* VH_TF_TYPES_H */
