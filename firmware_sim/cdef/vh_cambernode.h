/* cffi declarations: vh_cambernode.h */
typedef enum {
    VH_CAMBERNODE_WHEEL = 0, VH_CAMBERNODE_X_DOWN = 1, VH_CAMBERNODE_Z_DOWN = 2
} vh_cambernode_pose_t;

typedef struct {
    double theta_rad;
    double psi_rad;
    double chip_rad[3];
    double lsb_g[3];
    double noise_std_g;
    double bias_g[3];
    double gravity_g;
    uint64_t seed;
} vh_cambernode_config_t;

typedef struct {
    vh_cambernode_config_t cfg;
    double r_sa[9];
    double dist_s[3];
    vh_rng_t rng;
    uint8_t pose;
} vh_cambernode_t;

void vh_cambernode_config_default(vh_cambernode_config_t *cfg);
int vh_cambernode_init(vh_cambernode_t *node, const vh_cambernode_config_t *cfg);
void vh_cambernode_reset(vh_cambernode_t *node);
int vh_cambernode_set_pose(vh_cambernode_t *node, int pose);
int vh_cambernode_set_wheel(vh_cambernode_t *node, double theta_rad, double psi_rad);
void vh_cambernode_set_disturbance(vh_cambernode_t *node, const double accel_s_g[3]);
void vh_cambernode_reading_s(const vh_cambernode_t *node, double r_s[3]);
void vh_cambernode_true_m(const vh_cambernode_t *node, double m[9]);
void vh_cambernode_step(vh_cambernode_t *node, int16_t raw[3]);
void vh_cambernode_run(vh_cambernode_t *node, size_t n, int16_t *raw);
