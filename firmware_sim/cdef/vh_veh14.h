/* cffi declarations: vh_mftire.h, vh_veh14.h, vh_chsnode.h (vh_rng_t is declared in vh_dlplant.h) */
static const double VH_MFT_FZ_MAX;
typedef struct {
    double a[9];
    double b[9];
    double fz_scale;
} vh_mft_coef_t;
typedef struct {
    double fz;
    double bx, cx, dx, ex;
    double by, cy, dy, ey;
    double ux, uy;
    double kappa_m;
    double alpha_m;
    double tan_alpha_m;
    double sxm_drive;
    double sxm_brake;
    double inv_sxm_drive, inv_sxm_brake, inv_sym;
    double ky, kx;
    double dky, dkx;
} vh_mft_state_t;
void vh_mft_coef_default(vh_mft_coef_t *c);
int vh_mft_check(const vh_mft_coef_t *c);
double vh_mft_peak_u(double c, double e, double u0, int iters);
void vh_mft_load(vh_mft_state_t *s, const vh_mft_coef_t *c, double fz, double mu);
void vh_mft_load_near(vh_mft_state_t *s, const vh_mft_state_t *near, const vh_mft_coef_t *c, double fz, double mu);
void vh_mft_peaks(vh_mft_state_t *s, double ux, double uy, int iters);
void vh_mft_hold_peaks(vh_mft_state_t *s, const vh_mft_state_t *from);
double vh_mft_fx0(const vh_mft_state_t *s, double kappa);
double vh_mft_fy0(const vh_mft_state_t *s, double alpha);
void vh_mft_forces(const vh_mft_state_t *s, double kappa, double tan_alpha, double *fx, double *fy);
void vh_mft_eval(const vh_mft_coef_t *c, double fz, double mu, double kappa, double tan_alpha, double *fx,
                 double *fy);

static const double VH_V14_DT;
#define VH_V14_MAX_SUBSTEPS ...
static const double VH_V14_GRAVITY;
#define VH_V14_NW 4
enum { VH_V14_FL = 0, VH_V14_FR = 1, VH_V14_RL = 2, VH_V14_RR = 3 };
enum {
    VH_V14_X_PX = 0, VH_V14_X_PY = 1, VH_V14_X_YAW = 2, VH_V14_X_VX = 3, VH_V14_X_VY = 4, VH_V14_X_R = 5,
    VH_V14_X_Z = 6, VH_V14_X_VZ = 7, VH_V14_X_PHI = 8, VH_V14_X_P = 9, VH_V14_X_THETA = 10, VH_V14_X_Q = 11,
    VH_V14_X_ZU = 12, VH_V14_X_VZU = 16, VH_V14_X_W = 20, VH_V14_X_SK = 24, VH_V14_X_SA = 28, VH_V14_NX = 32
};
typedef struct {
    double ms;
    double ix;
    double iz;
    double lf, lr;
    double h;
    double tf, tr;
    double hf, hr;
    double kphi_f;
    double kphi_r;
    double cphi_f;
    double cphi_r;
    double rw;
    double iw;
    double iy;
    double m_uf;
    double m_ur;
    double k_f, k_r;
    double kt;
    double ct;
    double rho;
    double cda;
    double v_low;
    double relax_x;
    double relax_y;
    int min_substeps;
    vh_mft_coef_t tyre;
} vh_v14_params_t;
typedef struct {
    double steer;
    double drive[4];
    double brake[4];
    double mu[4];
} vh_v14_input_t;
typedef struct {
    double t;
    double px, py, yaw;
    double vx, vy, r;
    double ax, ay;
    double z, vz;
    double phi, p;
    double theta, q;
    double steer;
    double fx[4];
    double fy[4];
    double fxv[4];
    double fyv[4];
    double fz[4];
    double kappa[4];
    double alpha[4];
    double omega[4];
    double torque[4];
    double mu[4];
    double zu[4];
    double fyf, fyr;
    int substeps;
} vh_v14_truth_t;
typedef struct {
    double m_max;
    double rate_max;
    double tau;
} vh_v14_arc_params_t;
typedef struct {
    vh_v14_arc_params_t prm[2];
    double cmd[2];
    double lim[2];
    double m[2];
} vh_v14_arc_t;
typedef struct {
    vh_v14_params_t prm;
    vh_v14_truth_t truth;
    double x[32];
    uint64_t steps;
    uint32_t bad_inputs;
    double m;
    double e;
    double hp;
    double fz0[4];
    double fs0[4];
    double k_arb_f, k_arb_r;
    double c_f, c_r;
    double cx[4];
    double cy[4];
    double ip, iq;
    double det_x, det_y;
    double rate_fixed;
    vh_mft_state_t pk[4];
    double ck[4];
    vh_v14_arc_t arc;
} vh_v14_t;
void vh_v14_params_default(vh_v14_params_t *prm);
int vh_v14_init(vh_v14_t *p, const vh_v14_params_t *prm);
void vh_v14_reset(vh_v14_t *p);
int vh_v14_set_rolling(vh_v14_t *p, double vx);
void vh_v14_step(vh_v14_t *p, const vh_v14_input_t *in);
size_t vh_v14_run(vh_v14_t *p, size_t n, const vh_v14_input_t *in, vh_v14_truth_t *out);
double vh_v14_energy(const vh_v14_t *p);
void vh_v14_input_init(vh_v14_input_t *in, double mu);
void vh_v14_arc_params_default(vh_v14_arc_params_t *a);
int vh_v14_arc_config(vh_v14_t *p, const vh_v14_arc_params_t *front, const vh_v14_arc_params_t *rear);
void vh_v14_set_roll_moment(vh_v14_t *p, double m_front, double m_rear);

enum { VH_CHS_CH_AX = 0, VH_CHS_CH_AY = 1, VH_CHS_CH_YAW = 2, VH_CHS_CH_ROLL = 3, VH_CHS_CH_STEER = 4,
       VH_CHS_CH_W = 5, VH_CHS_CH_T = 9, VH_CHS_NCH = 13 };
typedef struct {
    double noise_std[13];
    double bias[13];
    uint64_t seed;
    uint32_t fail_mask;
    int accel_gravity;
} vh_chs_config_t;
typedef struct {
    vh_chs_config_t cfg;
    vh_rng_t rng;
    double meas[13];
    uint8_t counter;
    uint32_t frames;
} vh_chs_t;
void vh_chs_config_default(vh_chs_config_t *cfg);
int vh_chs_init(vh_chs_t *n, const vh_chs_config_t *cfg);
void vh_chs_reset(vh_chs_t *n);
size_t vh_chs_step(vh_chs_t *n, const vh_v14_truth_t *truth, vh_frame_t *out, size_t cap);
