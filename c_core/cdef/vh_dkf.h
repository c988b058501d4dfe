/* cffi declarations: vh_dkf.h */
#define VH_DKF_NX 4
#define VH_DKF_NZ 3
typedef enum { VH_DKF_EULER = 0, VH_DKF_ZOH = 1 } vh_dkf_disc_t;
typedef enum { VH_DKF_SPEEDS_TORQUE = 0, VH_DKF_SPEEDS = 1 } vh_dkf_meas_t;
typedef enum { VH_HEALTH_INIT = 0, VH_HEALTH_OK = 1, VH_HEALTH_DEGRADED = 2, VH_HEALTH_FAULT = 3 } vh_health_t;
enum { VH_DKF_Z_WO = 1, VH_DKF_Z_WW = 2, VH_DKF_Z_TO = 4, VH_DKF_Z_ALL = 7, VH_DKF_U_VALID = 8, VH_DKF_ALL_VALID = 15, VH_DKF_STALE = 16 };
typedef struct {
    double jo; double jv; double rd; double ri; double ks; double c; double ts;
    double q[4]; double r[3]; double p0[4]; double p_max; double x_max;
    int meas; int disc; int use_input;
} vh_dkf_config_t;
typedef struct {
    vh_dkf_config_t cfg;
    double ad[16]; double bd[4]; double x[4]; double p[16]; double k[12];
    uint32_t steps; uint32_t resets; uint8_t health; uint8_t x_init;
} vh_dkf_t;
void vh_dkf_config_default(vh_dkf_config_t *cfg, int meas);
double vh_dkf_road_load_coeff(double rt, double rho_a, double ca, double area, double wwo);
void vh_dkf_model(const vh_dkf_config_t *cfg, double a[16], double b[4]);
void vh_dkf_discretise(const double a[16], const double b[4], double ts, int disc, double ad[16], double bd[4]);
int vh_dkf_init(vh_dkf_t *f, const vh_dkf_config_t *cfg);
void vh_dkf_reset(vh_dkf_t *f);
int vh_dkf_step(vh_dkf_t *f, double u, const double z[3], unsigned mask);
int vh_dkf_set_ratio(vh_dkf_t *f, double ri);
uint32_t vh_dkf_run(vh_dkf_t *f, size_t n, const double *u, const double *z, const uint8_t *mask,
                    double *x_out, double *k_out, double *p_out);
int vh_dkf_turbine_torque(double we, double wt, double we_min, double *ti);
/* vh_tc.h */
void vh_tc_torques(double we, double wt, double *tp, double *ti);
double vh_tc_max_slope(void);
