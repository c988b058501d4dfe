/* cffi declarations: vh_dlplant.h, vh_dlsnode.h */
#define VH_DLP_NGEARS 5
static const double VH_DLP_DT;
#define VH_DLP_MAX_SUBSTEPS ...
static const double VH_DLP_CONV_RC;
static const double VH_DLP_GRAVITY;
enum { VH_DLP_X_WE = 0, VH_DLP_X_WO = 1, VH_DLP_X_WW = 2, VH_DLP_X_TS = 3, VH_DLP_X_GOV = 4, VH_DLP_NX = 5 };
typedef struct {
    double jo;
    double jv;
    double rd;
    double ri[5];
    double ks;
    double cs;
    double rt;
    double mu_r;
    double rho;
    double ca;
    double area;
    double roll_w_eps;
    double je;
    double te_peak;
    double fric0;
    double fric1;
    double w_idle;
    double gov_kp;
    double gov_ki;
    double gov_max;
    double road_std;
    double road_bw;
    double road_w_ref;
} vh_dlp_params_t;
typedef struct {
    double t;
    double throttle;
    int gear;
    double we;
    double wt;
    double wo;
    double ww;
    double to;
    double ti;
    double tp;
    double te;
    double tl;
    double td;
    double v;
    double sr;
} vh_dlp_truth_t;
typedef struct {
    vh_dlp_params_t prm;
    vh_dlp_truth_t truth;
    double x[5];
    double rough;
    double rough_a;
    double rough_b;
    vh_rng_t rng;
    uint64_t seed;
    uint64_t steps;
    uint32_t bad_inputs;
    ...;
} vh_dlp_t;
void vh_dlp_params_default(vh_dlp_params_t *prm);
int vh_dlp_init(vh_dlp_t *p, const vh_dlp_params_t *prm, uint64_t seed);
void vh_dlp_reset(vh_dlp_t *p);
int vh_dlp_set_rolling(vh_dlp_t *p, double v, int gear);
void vh_dlp_step(vh_dlp_t *p, double throttle, int gear);
size_t vh_dlp_run(vh_dlp_t *p, size_t n, const double *throttle, int gear, vh_dlp_truth_t *out);
void vh_dlp_converter(double we, double wt, double *tp, double *ti);
double vh_dlp_full_load_torque(const vh_dlp_params_t *prm, double we);
double vh_dlp_road_load(const vh_dlp_params_t *prm, double ww);

enum { VH_DLS_CH_WO = 0, VH_DLS_CH_WL = 1, VH_DLS_CH_WR = 2, VH_DLS_CH_TO = 3, VH_DLS_CH_WE = 4,
       VH_DLS_CH_WT = 5, VH_DLS_NCH = 6 };
typedef struct {
    double noise_std[6];
    uint64_t seed;
    uint32_t fail_mask;
} vh_dls_config_t;
typedef struct {
    vh_dls_config_t cfg;
    vh_rng_t rng;
    double meas[6];
    uint8_t counter;
    uint32_t frames;
} vh_dls_t;
void vh_dls_config_default(vh_dls_config_t *cfg);
int vh_dls_init(vh_dls_t *n, const vh_dls_config_t *cfg);
void vh_dls_reset(vh_dls_t *n);
size_t vh_dls_step(vh_dls_t *n, const vh_dlp_truth_t *truth, vh_frame_t *out, size_t cap);
