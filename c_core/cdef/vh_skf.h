/* cffi declarations: vh_skf.h (after vh_dkf.h: vh_health_t) */
#define VH_SKF_NX 7
#define VH_SKF_NY 4
#define VH_SKF_NU 13
enum { VH_SKF_VX = 0, VH_SKF_VY = 1, VH_SKF_R = 2, VH_SKF_PHI = 3, VH_SKF_P = 4, VH_SKF_FYF = 5, VH_SKF_FYR = 6 };
enum { VH_SKF_AX = 0, VH_SKF_AY = 1, VH_SKF_YR = 2, VH_SKF_YP = 3 };
enum { VH_SKF_Y_AX = 1, VH_SKF_Y_AY = 2, VH_SKF_Y_R = 4, VH_SKF_Y_P = 8, VH_SKF_Y_ALL = 15,
       VH_SKF_U_VALID = 16, VH_SKF_ALL_VALID = 31 };
typedef enum { VH_SKF_SKFMEC = 0, VH_SKF_EKF = 1 } vh_skf_variant_t;
typedef struct {
    double ax; double ay; double r; double p; double delta; double omega[4]; double torque[4];
} vh_skf_input_t;
typedef struct {
    double m; double ms; double iz; double ix; double lf; double lr; double h; double e; double hf; double hr;
    double kphif; double kphir; double cphif; double cphir; double rw; double iw; double tf; double tr; double g;
    double zeta1; double zeta2; double lt_gain; double ts; double tau_wdot; double s[7];
    double q[7]; double p0[7]; double r[4]; double gp[7]; double gy[2];
    double p_cap; double p_max; double x_max; int scaled; int mec;
} vh_skf_config_t;
typedef struct {
    vh_skf_config_t cfg;
    double d[7]; double w[7]; double qf[7]; double gpf[7];
    double x[7]; double p[49]; double k[28]; double innov[4]; double nu_ay;
    double w_prev[4]; double wdot[4]; double fx[4]; double fz[4]; double fy[4]; double cs_delta[2];
    uint32_t steps; uint32_t resets; uint32_t caps; uint8_t health; uint8_t x_init;
} vh_skf_t;
void vh_skf_config_default(vh_skf_config_t *cfg, int variant);
void vh_skf_zeta_steady(const vh_skf_config_t *cfg, double *zeta1, double *zeta2);
int vh_skf_init(vh_skf_t *f, const vh_skf_config_t *cfg);
void vh_skf_reset(vh_skf_t *f);
int vh_skf_step(vh_skf_t *f, const vh_skf_input_t *in, unsigned mask);
void vh_skf_state(const vh_skf_t *f, double x[7]);
uint32_t vh_skf_run(vh_skf_t *f, size_t n, const double *u, const uint8_t *mask, double *x_out,
                    double *fy_out, double *fz_out, double *p_out, uint8_t *health_out);
