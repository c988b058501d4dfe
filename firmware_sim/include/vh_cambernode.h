/* vh_cambernode.h - simulated camber inspection device: a wheel-mounted 3-axis accelerometer
 * node (seed 002) that samples, adds chip errors and quantises to raw int16 counts.
 *
 * Truth (double precision, this is the plant side):
 *   V -> W: camber theta about x; W -> S: device misalignment yaw psi about y (eq. 1-3), so at
 *   rest the device reads g_S = g (-cos th sin psi, sin th, cos th cos psi) (row 3 of V<-S).
 *   Calibration fixture poses: device x axis straight down, g_S = (g, 0, 0); z down, (0, 0, g).
 *   Chip A inside S: a_S = R_SA a_A with R_SA = Rz(c2) Ry(c1) Rx(c0) from three small angles,
 *   so the chip reads a_A = R_SA^T a_S and eq. 19's true M is R_SA^T.
 * Sign: the node reports the paper's down-positive reading, i.e. minus the chip's specific
 * force: r_S = g_S - d_S, where d_S is a disturbing acceleration of the device (vehicle or hand
 * motion) given in S. Counts = round((R_SA^T r_S + bias + noise) / lsb), saturated to int16.
 * Noise: white Gaussian, std noise_std_g per axis, from the simulated car's vh_rng seeded from
 * the config.
 */
#ifndef VH_CAMBERNODE_H
#define VH_CAMBERNODE_H

#include "vh_rng.h"
#include "vh_types.h"

typedef enum {
    VH_CAMBERNODE_WHEEL = 0,  /* on the wheel: gravity from theta, psi */
    VH_CAMBERNODE_X_DOWN = 1, /* calibration fixture, device x axis down */
    VH_CAMBERNODE_Z_DOWN = 2  /* calibration fixture, device z axis down */
} vh_cambernode_pose_t;

typedef struct {
    double theta_rad;   /* true camber */
    double psi_rad;     /* true device misalignment yaw */
    double chip_rad[3]; /* chip rotation in S about x, y, z (R_SA = Rz Ry Rx) */
    double lsb_g[3];    /* resolution, g per count; default 0.004 (4 mg) */
    double noise_std_g; /* per-axis white noise std; default 0.004 */
    double bias_g[3];   /* per-axis offset in A; default 0 */
    double gravity_g;   /* local gravity in units of the chip's g; default 1 */
    uint64_t seed;      /* RNG seed (vh_rng_seed) */
} vh_cambernode_config_t;

typedef struct {
    vh_cambernode_config_t cfg;
    double r_sa[9];     /* row-major, a_S = R_SA a_A */
    double dist_s[3];   /* disturbing acceleration in S, g */
    vh_rng_t rng;       /* the simulated car's shared generator, seeded from cfg.seed */
    uint8_t pose;       /* vh_cambernode_pose_t */
} vh_cambernode_t;

void vh_cambernode_config_default(vh_cambernode_config_t *cfg);
/* VH_EINVAL for a non-finite value, lsb <= 0, noise < 0 or gravity <= 0 (node untouched). */
int vh_cambernode_init(vh_cambernode_t *node, const vh_cambernode_config_t *cfg);
/* Back to the wheel pose, no disturbance, RNG re-seeded: the same sample stream again. */
void vh_cambernode_reset(vh_cambernode_t *node);
int vh_cambernode_set_pose(vh_cambernode_t *node, int pose);              /* VH_EINVAL if unknown */
int vh_cambernode_set_wheel(vh_cambernode_t *node, double theta_rad, double psi_rad);
void vh_cambernode_set_disturbance(vh_cambernode_t *node, const double accel_s_g[3]);
/* The noise-free reading in S for the current pose and disturbance (truth). */
void vh_cambernode_reading_s(const vh_cambernode_t *node, double r_s[3]);
/* The true eq. 19 matrix M = R_SA^T (row-major): a_A = M a_S. */
void vh_cambernode_true_m(const vh_cambernode_t *node, double m[9]);
/* One sample: raw[3] counts. */
void vh_cambernode_step(vh_cambernode_t *node, int16_t raw[3]);
/* n samples into raw[n*3]. */
void vh_cambernode_run(vh_cambernode_t *node, size_t n, int16_t *raw);

#endif /* VH_CAMBERNODE_H */
