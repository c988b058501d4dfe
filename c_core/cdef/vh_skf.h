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
int vh_skfq_params_from_config(const vh_skf_config_t *cfg, struct vh_skfq_params_s *prm);
void vh_skfq_quantise_inputs(size_t n, const double *u, int32_t *q);

/* vh_fix.h */
typedef struct { int32_t m; int32_t e; } vh_fix_k_t;
#define VH_FIX_GUARD 3
int64_t vh_fix_asr64(int64_t x, int s);
int32_t vh_fix_sat32(int64_t x, uint32_t *sat);
int32_t vh_fix_rshift_rnd(int64_t x, int s, uint32_t *sat);
int32_t vh_fix_lshift_sat(int32_t x, int s, uint32_t *sat);
int32_t vh_fix_convert(int32_t x, int fin, int fout, uint32_t *sat);
int32_t vh_fix_add(int32_t a, int32_t b, uint32_t *sat);
int32_t vh_fix_sub(int32_t a, int32_t b, uint32_t *sat);
int32_t vh_fix_mul(int32_t a, int fa, int32_t b, int fb, int fo, uint32_t *sat);
int32_t vh_fix_kmul(vh_fix_k_t k, int32_t v, int fin, int fout, uint32_t *sat);
int64_t vh_fix_dot(const int32_t *a, int sa, const int32_t *b, int sb, int n);
int32_t vh_fix_div(int32_t num, int32_t den, int s, uint32_t *sat);
void vh_fix_sincos(int32_t angle_q30, int32_t *sin_q30, int32_t *cos_q30, uint32_t *sat);

/* vh_skfq.h */
#define VH_SKFQ_FX 21
#define VH_SKFQ_FA 24
#define VH_SKFQ_FW 27
#define VH_SKFQ_FD 30
#define VH_SKFQ_FO 21
#define VH_SKFQ_FT 16
#define VH_SKFQ_FN 14
#define VH_SKFQ_FR 28
#define VH_SKFQ_FWD 15
#define VH_SKFQ_FP 26
#define VH_SKFQ_FPHI 29
#define VH_SKFQ_FH 27
#define VH_SKFQ_FU 24
#define VH_SKFQ_FK 15
#define VH_SKFQ_NX 7
#define VH_SKFQ_NY 4
#define VH_SKFQ_NU 13
typedef struct {
    int32_t ax; int32_t ay; int32_t r; int32_t p; int32_t delta; int32_t omega[4]; int32_t torque[4];
} vh_skfq_input_t;
typedef struct vh_skfq_params_s {
    vh_fix_k_t c_vx0; vh_fix_k_t c_vy1; vh_fix_k_t c_vy4; vh_fix_k_t c_r2; vh_fix_k_t c_p1; vh_fix_k_t c_p4;
    vh_fix_k_t c_phi_p; vh_fix_k_t c_fy_p[2]; int32_t phi_row[3];
    vh_fix_k_t k_m_rvy; vh_fix_k_t k_m_rvx; vh_fix_k_t k_mse_pr; vh_fix_k_t k_mse_rvx;
    vh_fix_k_t k_kphi; vh_fix_k_t k_cphi;
    vh_fix_k_t k_lf; vh_fix_k_t k_lr; vh_fix_k_t k_tf; vh_fix_k_t k_tr; vh_fix_k_t k_hf; vh_fix_k_t k_hr;
    int32_t fz0[2]; vh_fix_k_t k_fz_ax; vh_fix_k_t k_lat_ay[2]; vh_fix_k_t k_lat_phi[2]; vh_fix_k_t k_gy[2];
    vh_fix_k_t k_inv_fz[2]; vh_fix_k_t k_drho[2]; vh_fix_k_t k_phi; vh_fix_k_t k_inv_sf[2];
    vh_fix_k_t k_inv_ts; vh_fix_k_t k_alpha; vh_fix_k_t k_inv_rw; vh_fix_k_t k_iw_rw;
    vh_fix_k_t k_sr; vh_fix_k_t k_sp; vh_fix_k_t k_inv_m; vh_fix_k_t k_mse_pr_m;
    vh_fix_k_t k_ixx_det; vh_fix_k_t k_mse_det;
    vh_fix_k_t k_gp[7]; int32_t q[7]; int32_t p0[7]; int32_t r[4]; int32_t p_cap; int32_t p_max; int32_t x_max;
    int32_t mec;
    vh_fix_k_t k_seed_vx; vh_fix_k_t k_seed_fy[2]; vh_fix_k_t k_seed_phi;
} vh_skfq_params_t;
typedef struct {
    vh_skfq_params_t prm;
    int32_t x[7]; int32_t p[49]; int32_t innov[4]; int32_t nu_ay; int32_t w_prev[4]; int32_t wdot[4];
    int32_t fx[4]; int32_t fz[4]; int32_t fy[4]; int32_t cs_delta[2];
    uint32_t steps; uint32_t resets; uint32_t caps; uint32_t sat; uint32_t sat_step;
    uint8_t health; uint8_t x_init;
} vh_skfq_t;
int vh_skfq_init(vh_skfq_t *f, const vh_skfq_params_t *prm);
void vh_skfq_reset(vh_skfq_t *f);
int vh_skfq_step(vh_skfq_t *f, const vh_skfq_input_t *in, unsigned mask);
uint32_t vh_skfq_run(vh_skfq_t *f, size_t n, const int32_t *u, const uint8_t *mask, int32_t *x_out,
                     int32_t *fy_out, int32_t *fz_out, int32_t *p_out, uint8_t *health_out);
