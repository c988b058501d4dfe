/* cffi declarations: vh_camber.h */
#define VH_CAMBER_N_MAX ...

typedef struct {
    float lsb_g[3];
    int64_t sum[3];
    int64_t sum_sq[3];
    float sum_mag;
    float sum_mag_c;
    uint32_t n;
    uint32_t n_saturated;
} vh_camber_capture_t;

typedef enum {
    VH_CAMBER_CAL_OK = 0, VH_CAMBER_CAL_TOO_FEW_SAMPLES = 1, VH_CAMBER_CAL_SATURATED = 2,
    VH_CAMBER_CAL_MOVING = 3, VH_CAMBER_CAL_MAGNITUDE = 4, VH_CAMBER_CAL_NOT_ORTHOGONAL = 5,
    VH_CAMBER_CAL_INVALID = 6
} vh_camber_cal_status_t;

typedef struct {
    uint32_t min_samples;
    float std_max_g;
    float mag_tol_g;
    float ortho_tol;
} vh_camber_cal_limits_t;

typedef struct {
    uint8_t status;
    uint8_t pose;
    uint32_t n[2];
    float std_g[2];
    float mag_g[2];
    float mean_g[6];
    float x_dot_z;
} vh_camber_cal_report_t;

typedef struct {
    float x_axis[3];
    float y_axis[3];
    float z_axis[3];
    float m[9];
    float m_inv[9];
    float lsb_g[3];
    float da_s_g[3];
    uint8_t valid;
} vh_camber_cal_t;

void vh_camber_cal_limits_default(vh_camber_cal_limits_t *lim);
int vh_camber_capture_init(vh_camber_capture_t *c, const float lsb_g[3]);
int vh_camber_capture_add(vh_camber_capture_t *c, const int16_t raw[3]);
int vh_camber_capture_add_n(vh_camber_capture_t *c, size_t n, const int16_t *raw);
int vh_camber_capture_mean(const vh_camber_capture_t *c, float mean_g[3]);
vh_camber_cal_status_t vh_camber_calibrate(vh_camber_cal_t *cal, vh_camber_cal_report_t *rep,
                                           const vh_camber_capture_t *x_down,
                                           const vh_camber_capture_t *z_down,
                                           const vh_camber_cal_limits_t *lim);
int vh_camber_cal_from_axes(vh_camber_cal_t *cal, const float x_axis[3], const float z_axis[3],
                            const float lsb_g[3], float ortho_tol);
void vh_camber_cal_apply(const vh_camber_cal_t *cal, const float counts[3], float a_s_g[3]);

void vh_camber_angles(const float a_s[3], float *theta_rad, float *psi_rad);
float vh_camber_bound(float theta_rad, float psi_rad, const float da[3], float g);

typedef enum {
    VH_CAMBER_OK = 0, VH_CAMBER_MOVING = 1, VH_CAMBER_NOT_STATIONARY_FLAG = 2,
    VH_CAMBER_MAGNITUDE = 3, VH_CAMBER_TOO_FEW_SAMPLES = 4, VH_CAMBER_NOT_CALIBRATED = 5,
    VH_CAMBER_SATURATED = 6
} vh_camber_reason_t;

typedef struct {
    uint16_t window;
    uint16_t min_samples;
    float mag_tol_g;
    float std_max_g;
} vh_camber_config_t;

typedef struct {
    float theta_rad;
    float psi_rad;
    float bound_rad;
    float a_s_g[3];
    float mag_g;
    float std_g;
    uint32_t n;
    uint8_t reason;
} vh_camber_result_t;

typedef struct {
    vh_camber_config_t cfg;
    vh_camber_cal_t cal;
    int64_t sum[3];
    int64_t sum_sq[3];
    uint32_t n;
    uint32_t n_moving_flag;
    uint32_t n_saturated;
    uint32_t results;
} vh_camber_t;

void vh_camber_config_default(vh_camber_config_t *cfg);
int vh_camber_init(vh_camber_t *c, const vh_camber_config_t *cfg, const vh_camber_cal_t *cal);
void vh_camber_reset(vh_camber_t *c);
int vh_camber_set_calibration(vh_camber_t *c, const vh_camber_cal_t *cal);
int vh_camber_step(vh_camber_t *c, const int16_t raw[3], bool stationary, vh_camber_result_t *out);
void vh_camber_evaluate(vh_camber_t *c, vh_camber_result_t *out);
size_t vh_camber_run(vh_camber_t *c, size_t n, const int16_t *raw, const uint8_t *stationary,
                     vh_camber_result_t *out, size_t out_cap);
