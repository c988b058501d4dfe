/* vh_camber.h - camber angle inspection at rest with a 3-axis accelerometer (seed 002).
 *
 * Frames: V vehicle (x forward, y right, z down); W wheel = V rotated by camber theta about x;
 * S inspection device = W rotated by misalignment yaw psi about y; A = the accelerometer chip
 * inside S. At rest on a level floor the device reads gravity, (0, 0, g)_V = (ax, ay, az)_S, and
 *     psi   = -atan(ax / az)                  (eq. 4; computed as atan2(-ax, az))
 *     theta = atan(ay / sqrt(ax^2 + az^2))    (eq. 6; independent of psi)
 * Readings use the paper's sign: an axis pointing straight down reads +1 g (the node reports
 * minus the chip's specific force).
 *
 * Chip-in-device calibration (eq. 7-19): N samples with the device's x axis down and N with
 * its z axis down give the constrained least-squares means (eq. 14-16), their unit vectors
 * x, z (eq. 17-18, the S axes seen in A), y = z x x, M = [x y z] (columns) and a_S = M^-1 a_A
 * (eq. 19). Captures are streamed (integer sums), so no sample buffer and no heap.
 *
 * Number format: single-precision float, as a Cortex-M4F would run it. The work per result is
 * a 3x3 product, two atan2 and a few sqrt; fixed point would need a CORDIC for no gain, and the
 * precision needed (0.01 deg ~ 2e-4 rad) is far above float's 6e-8. Sums over a window are
 * exact int64 on raw counts (no float drift however long the window); only the eq. 14 sum of
 * sample magnitudes is a float sum, Kahan-compensated. Units: accelerations in g (1 g = the
 * nominal gravity the chip's LSB is specified against), angles in rad.
 */
#ifndef VH_CAMBER_H
#define VH_CAMBER_H

#include <stdbool.h>
#include "vh_types.h"

/* Largest window or capture: keeps n * sum(raw^2) and sum(raw)^2 inside int64 (65535^2 * 2^30 < 2^63). */
#define VH_CAMBER_N_MAX 65535u

/* ---- Calibration (eq. 7-19) ------------------------------------------------------------ */

/* One calibration capture (one pose), accumulated sample by sample. */
typedef struct {
    float lsb_g[3];      /* g per count of each chip axis */
    int64_t sum[3];      /* sum of raw counts, exact */
    int64_t sum_sq[3];   /* sum of raw counts squared, exact (spread check) */
    float sum_mag;       /* sum of sample magnitudes |a_i| in g (eq. 14 numerator) */
    float sum_mag_c;     /* Kahan compensation of sum_mag */
    uint32_t n;          /* samples accumulated */
    uint32_t n_saturated;/* samples with a count at the int16 limits (still accumulated) */
} vh_camber_capture_t;

typedef enum {
    VH_CAMBER_CAL_OK = 0,
    VH_CAMBER_CAL_TOO_FEW_SAMPLES = 1, /* a capture has fewer than min_samples */
    VH_CAMBER_CAL_SATURATED = 2,       /* a count hit the int16 limits: the mean is clipped */
    VH_CAMBER_CAL_MOVING = 3,          /* sample spread above std_max_g: device not still */
    VH_CAMBER_CAL_MAGNITUDE = 4,       /* mean magnitude too far from 1 g: wrong scale or motion */
    VH_CAMBER_CAL_NOT_ORTHOGONAL = 5,  /* |x . z| above ortho_tol: poses not square */
    VH_CAMBER_CAL_INVALID = 6          /* different LSBs, non-finite or singular data */
} vh_camber_cal_status_t;

/* Capture acceptance limits (vh_camber_cal_limits_default gives the documented defaults). */
typedef struct {
    uint32_t min_samples; /* per capture; default 64 */
    float std_max_g;      /* sqrt(var_x + var_y + var_z) of a capture; default 0.03 g */
    float mag_tol_g;      /* | |mean| - 1 g |; default 0.05 g */
    float ortho_tol;      /* |x . z| = |cos(angle(x, z))|; default sin(1 deg) = 0.01745 */
} vh_camber_cal_limits_t;

/* What the calibration saw; filled as far as it got, whatever the status. */
typedef struct {
    uint8_t status;     /* vh_camber_cal_status_t */
    uint8_t pose;       /* capture the status is about: 0 x-down, 1 z-down, 2 both */
    uint32_t n[2];      /* samples per capture (x-down, z-down) */
    float std_g[2];     /* spread sqrt(sum of axis variances) per capture */
    float mag_g[2];     /* |constrained mean| = mean sample magnitude (eq. 8) */
    float mean_g[6];    /* eq. 14-16 means in A: x-down (0..2), z-down (3..5) */
    float x_dot_z;      /* orthogonality of the unit vectors (eq. 17-18) */
} vh_camber_cal_report_t;

/* A usable calibration: the S axes in A and the matrices of eq. 19. */
typedef struct {
    float x_axis[3]; /* eq. 17: S x axis in A (unit) */
    float y_axis[3]; /* y = z x x */
    float z_axis[3]; /* eq. 18: S z axis in A (unit) */
    float m[9];      /* eq. 19 M, row-major, columns x y z: a_A = M a_S */
    float m_inv[9];  /* M^-1, row-major: a_S = M^-1 a_A */
    float lsb_g[3];  /* g per count of each chip axis */
    float da_s_g[3]; /* resolution seen on S axes: |M^-1| lsb (row sums), the da of eq. 22 */
    uint8_t valid;   /* 1 after a successful calibrate / from_axes */
} vh_camber_cal_t;

void vh_camber_cal_limits_default(vh_camber_cal_limits_t *lim);

/* VH_EINVAL if an LSB is not finite and > 0 (capture left empty). */
int vh_camber_capture_init(vh_camber_capture_t *c, const float lsb_g[3]);
/* Adds one raw sample. VH_ENOSPC once VH_CAMBER_N_MAX samples are in (sample dropped). */
int vh_camber_capture_add(vh_camber_capture_t *c, const int16_t raw[3]);
/* vh_camber_capture_add over raw[n*3]; VH_ENOSPC if the capture filled up (rest dropped). */
int vh_camber_capture_add_n(vh_camber_capture_t *c, size_t n, const int16_t *raw);
/* eq. 14-16: the constrained least-squares mean in g. VH_EINVAL on an empty or zero capture. */
int vh_camber_capture_mean(const vh_camber_capture_t *c, float mean_g[3]);

/* Builds cal from an x-down and a z-down capture (eq. 14-19), checking them against lim.
 * cal is written (valid = 1) only when the status is VH_CAMBER_CAL_OK; rep may be NULL. */
vh_camber_cal_status_t vh_camber_calibrate(vh_camber_cal_t *cal, vh_camber_cal_report_t *rep,
                                           const vh_camber_capture_t *x_down,
                                           const vh_camber_capture_t *z_down,
                                           const vh_camber_cal_limits_t *lim);

/* Builds cal from stored unit axes (a calibration file): y = z x x, M, M^-1 (eq. 19).
 * VH_EINVAL (cal.valid = 0) if a value is not finite, an axis norm is off 1 by more than 1e-3,
 * |x . z| > ortho_tol, an LSB is not > 0, or M is singular. */
int vh_camber_cal_from_axes(vh_camber_cal_t *cal, const float x_axis[3], const float z_axis[3],
                            const float lsb_g[3], float ortho_tol);

/* a_S = M^-1 a_A (eq. 19) with a_A = counts * lsb; counts may be a window mean. */
void vh_camber_cal_apply(const vh_camber_cal_t *cal, const float counts[3], float a_s_g[3]);

/* ---- Angles and error bound (eq. 4-6, 20-23) -------------------------------------------- */

/* eq. 4 and 6 from a device-frame acceleration (any scale). */
void vh_camber_angles(const float a_s[3], float *theta_rad, float *psi_rad);

/* eq. 22: worst-case |d theta| = (|sin th sin psi| da_x + |cos th| da_y + |sin th cos psi| da_z) / g,
 * da and g in the same unit. At theta = 0 it is da_y / g (eq. 23). */
float vh_camber_bound(float theta_rad, float psi_rad, const float da[3], float g);

/* ---- Inspection (measurement) ------------------------------------------------------------ */

typedef enum {
    VH_CAMBER_OK = 0,                  /* published */
    VH_CAMBER_MOVING = 1,              /* window spread above std_max_g: not steady */
    VH_CAMBER_NOT_STATIONARY_FLAG = 2, /* the caller's stationary flag was false in the window */
    VH_CAMBER_MAGNITUDE = 3,           /* | |mean a| - 1 g | above mag_tol_g */
    VH_CAMBER_TOO_FEW_SAMPLES = 4,     /* fewer than min_samples in the window */
    VH_CAMBER_NOT_CALIBRATED = 5,      /* no valid calibration loaded */
    VH_CAMBER_SATURATED = 6            /* a count at the int16 limits in the window */
} vh_camber_reason_t;

typedef struct {
    uint16_t window;      /* samples per result (consecutive blocks); min_samples..VH_CAMBER_N_MAX */
    uint16_t min_samples; /* >= 2; a shorter window (vh_camber_evaluate) is refused */
    float mag_tol_g;      /* default 0.05 g */
    float std_max_g;      /* sqrt(var_x + var_y + var_z) over the window; default 0.03 g */
} vh_camber_config_t;

typedef struct {
    float theta_rad; /* eq. 6 camber; 0 unless reason == VH_CAMBER_OK */
    float psi_rad;   /* eq. 4 device misalignment; 0 unless OK */
    float bound_rad; /* eq. 22 worst case for theta, psi and the resolution; 0 unless OK */
    float a_s_g[3];  /* window mean in S (eq. 19); diagnostic, set when calibrated and n > 0 */
    float mag_g;     /* |a_s_g| */
    float std_g;     /* window spread sqrt(sum of axis variances) */
    uint32_t n;      /* samples in the window */
    uint8_t reason;  /* vh_camber_reason_t */
} vh_camber_result_t;

typedef struct {
    vh_camber_config_t cfg;
    vh_camber_cal_t cal;
    int64_t sum[3];        /* window sums of raw counts, exact */
    int64_t sum_sq[3];
    uint32_t n;
    uint32_t n_moving_flag;/* samples with stationary == false */
    uint32_t n_saturated;
    uint32_t results;      /* results produced since init */
} vh_camber_t;

void vh_camber_config_default(vh_camber_config_t *cfg); /* window 256, min 32 */

/* VH_EINVAL for an out-of-range config (instance untouched). cal may be NULL or invalid:
 * every result is then VH_CAMBER_NOT_CALIBRATED until vh_camber_set_calibration. */
int vh_camber_init(vh_camber_t *c, const vh_camber_config_t *cfg, const vh_camber_cal_t *cal);
void vh_camber_reset(vh_camber_t *c); /* empties the window */
/* VH_EINVAL (and not calibrated) if cal is NULL or not valid; empties the window either way. */
int vh_camber_set_calibration(vh_camber_t *c, const vh_camber_cal_t *cal);
/* Adds one raw sample; when the window is full writes *out, empties the window, returns 1. */
int vh_camber_step(vh_camber_t *c, const int16_t raw[3], bool stationary, vh_camber_result_t *out);
/* Evaluates whatever the window holds now (possibly TOO_FEW_SAMPLES) and empties it. */
void vh_camber_evaluate(vh_camber_t *c, vh_camber_result_t *out);
/* Steps over n samples raw[n*3] with stationary[n] (NULL: all stationary). Writes up to
 * out_cap results; returns how many windows completed. */
size_t vh_camber_run(vh_camber_t *c, size_t n, const int16_t *raw, const uint8_t *stationary,
                     vh_camber_result_t *out, size_t out_cap);

#endif /* VH_CAMBER_H */
