/* vh_cambernode.c - see vh_cambernode.h. */
#include <math.h>

#include "vh_cambernode.h"
#include "vh_mat.h"


/* ---- Node ---------------------------------------------------------------------------------- */

void vh_cambernode_config_default(vh_cambernode_config_t *cfg)
{
    int k;
    cfg->theta_rad = 0.0;
    cfg->psi_rad = 0.0;
    for (k = 0; k < 3; ++k) {
        cfg->chip_rad[k] = 0.0;
        cfg->lsb_g[k] = 0.004;
        cfg->bias_g[k] = 0.0;
    }
    cfg->noise_std_g = 0.004;
    cfg->gravity_g = 1.0;
    cfg->seed = 1u;
}

int vh_cambernode_init(vh_cambernode_t *node, const vh_cambernode_config_t *cfg)
{
    double ca;
    double sa;
    double cb;
    double sb;
    double cc;
    double sc;
    if (!isfinite(cfg->theta_rad) || !isfinite(cfg->psi_rad) || !vh_mat_finite(cfg->chip_rad, 3)
        || !vh_mat_finite(cfg->lsb_g, 3) || !vh_mat_finite(cfg->bias_g, 3)
        || !isfinite(cfg->noise_std_g) || !isfinite(cfg->gravity_g) || !(cfg->noise_std_g >= 0.0)
        || !(cfg->gravity_g > 0.0) || !(cfg->lsb_g[0] > 0.0) || !(cfg->lsb_g[1] > 0.0)
        || !(cfg->lsb_g[2] > 0.0)) {
        return VH_EINVAL;
    }
    node->cfg = *cfg;
    /* R_SA = Rz(c2) Ry(c1) Rx(c0) */
    ca = cos(cfg->chip_rad[0]);
    sa = sin(cfg->chip_rad[0]);
    cb = cos(cfg->chip_rad[1]);
    sb = sin(cfg->chip_rad[1]);
    cc = cos(cfg->chip_rad[2]);
    sc = sin(cfg->chip_rad[2]);
    node->r_sa[0] = cc * cb;
    node->r_sa[1] = cc * sb * sa - sc * ca;
    node->r_sa[2] = cc * sb * ca + sc * sa;
    node->r_sa[3] = sc * cb;
    node->r_sa[4] = sc * sb * sa + cc * ca;
    node->r_sa[5] = sc * sb * ca - cc * sa;
    node->r_sa[6] = -sb;
    node->r_sa[7] = cb * sa;
    node->r_sa[8] = cb * ca;
    vh_cambernode_reset(node);
    return VH_OK;
}

void vh_cambernode_reset(vh_cambernode_t *node)
{
    int k;
    for (k = 0; k < 3; ++k) {
        node->dist_s[k] = 0.0;
    }
    vh_rng_seed(&node->rng, node->cfg.seed);
    node->pose = (uint8_t)VH_CAMBERNODE_WHEEL;
}

int vh_cambernode_set_pose(vh_cambernode_t *node, int pose)
{
    if (pose != VH_CAMBERNODE_WHEEL && pose != VH_CAMBERNODE_X_DOWN && pose != VH_CAMBERNODE_Z_DOWN) {
        return VH_EINVAL;
    }
    node->pose = (uint8_t)pose;
    return VH_OK;
}

int vh_cambernode_set_wheel(vh_cambernode_t *node, double theta_rad, double psi_rad)
{
    if (!isfinite(theta_rad) || !isfinite(psi_rad)) {
        return VH_EINVAL;
    }
    node->cfg.theta_rad = theta_rad;
    node->cfg.psi_rad = psi_rad;
    return VH_OK;
}

void vh_cambernode_set_disturbance(vh_cambernode_t *node, const double accel_s_g[3])
{
    int k;
    for (k = 0; k < 3; ++k) {
        node->dist_s[k] = isfinite(accel_s_g[k]) ? accel_s_g[k] : 0.0;
    }
}

void vh_cambernode_reading_s(const vh_cambernode_t *node, double r_s[3])
{
    const double g = node->cfg.gravity_g;
    const double th = node->cfg.theta_rad;
    const double psi = node->cfg.psi_rad;
    int k;
    switch (node->pose) {
    case VH_CAMBERNODE_X_DOWN:
        r_s[0] = g;
        r_s[1] = 0.0;
        r_s[2] = 0.0;
        break;
    case VH_CAMBERNODE_Z_DOWN:
        r_s[0] = 0.0;
        r_s[1] = 0.0;
        r_s[2] = g;
        break;
    default:
        /* (0, 0, g)_V in S: the third row of V<-S (eq. 3) */
        r_s[0] = -g * cos(th) * sin(psi);
        r_s[1] = g * sin(th);
        r_s[2] = g * cos(th) * cos(psi);
        break;
    }
    for (k = 0; k < 3; ++k) {
        r_s[k] -= node->dist_s[k];
    }
}

void vh_cambernode_true_m(const vh_cambernode_t *node, double m[9])
{
    int r;
    int c;
    for (r = 0; r < 3; ++r) {
        for (c = 0; c < 3; ++c) {
            m[r * 3 + c] = node->r_sa[c * 3 + r];
        }
    }
}

static int16_t quantise(double v, double lsb)
{
    double q = floor(v / lsb + 0.5); /* round half up */
    if (q > 32767.0) {
        return INT16_MAX;
    }
    if (q < -32768.0) {
        return INT16_MIN;
    }
    return (int16_t)q;
}

void vh_cambernode_step(vh_cambernode_t *node, int16_t raw[3])
{
    double r_s[3];
    int k;
    vh_cambernode_reading_s(node, r_s);
    for (k = 0; k < 3; ++k) {
        /* a_A = R_SA^T r_S: column k of R_SA */
        double a = node->r_sa[0 * 3 + k] * r_s[0] + node->r_sa[1 * 3 + k] * r_s[1]
                   + node->r_sa[2 * 3 + k] * r_s[2];
        double noise = (node->cfg.noise_std_g > 0.0) ? node->cfg.noise_std_g * vh_rng_gauss(&node->rng) : 0.0;
        raw[k] = quantise(a + node->cfg.bias_g[k] + noise, node->cfg.lsb_g[k]);
    }
}

void vh_cambernode_run(vh_cambernode_t *node, size_t n, int16_t *raw)
{
    size_t i;
    for (i = 0; i < n; ++i) {
        vh_cambernode_step(node, &raw[i * 3u]);
    }
}
