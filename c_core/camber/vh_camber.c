/* vh_camber.c - see vh_camber.h. Single-precision float only (no double literals or calls). */
#include <math.h>
#include <string.h>

#include "vh_camber.h"
#include "vh_mathf.h" /* sin, cos, atan2: the same bits on the ECU and the host */

static bool finite3(const float v[3])
{
    return isfinite(v[0]) && isfinite(v[1]) && isfinite(v[2]);
}

static bool lsb_ok(const float lsb_g[3])
{
    return finite3(lsb_g) && lsb_g[0] > 0.0f && lsb_g[1] > 0.0f && lsb_g[2] > 0.0f;
}

static bool is_saturated(const int16_t raw[3])
{
    int k;
    for (k = 0; k < 3; ++k) {
        if (raw[k] == INT16_MAX || raw[k] == INT16_MIN) {
            return true;
        }
    }
    return false;
}

static float norm3(const float v[3])
{
    return sqrtf(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
}

/* Spread sqrt(var_x + var_y + var_z) in g from exact integer sums. n * sum_sq - sum^2 is exact
 * in int64 for n <= VH_CAMBER_N_MAX and |raw| <= 2^15, and never negative. */
static float spread_g(const int64_t sum[3], const int64_t sum_sq[3], uint32_t n, const float lsb_g[3])
{
    float var = 0.0f;
    float nf = (float)n;
    int k;
    for (k = 0; k < 3; ++k) {
        int64_t num = (int64_t)n * sum_sq[k] - sum[k] * sum[k];
        var += (float)num / (nf * nf) * lsb_g[k] * lsb_g[k];
    }
    return sqrtf(var);
}

/* ---- Calibration ----------------------------------------------------------------------- */

void vh_camber_cal_limits_default(vh_camber_cal_limits_t *lim)
{
    lim->min_samples = 64u;
    lim->std_max_g = 0.03f;
    lim->mag_tol_g = 0.05f;
    lim->ortho_tol = 0.01745241f; /* sin(1 deg) */
}

int vh_camber_capture_init(vh_camber_capture_t *c, const float lsb_g[3])
{
    int k;
    memset(c, 0, sizeof *c); /* no samples; lsb 0 until it is known good */
    if (!lsb_ok(lsb_g)) {
        return VH_EINVAL;
    }
    for (k = 0; k < 3; ++k) {
        c->lsb_g[k] = lsb_g[k];
    }
    return VH_OK;
}

int vh_camber_capture_add(vh_camber_capture_t *c, const int16_t raw[3])
{
    float a[3];
    float y;
    float t;
    int k;
    if (c->n >= VH_CAMBER_N_MAX) {
        return VH_ENOSPC;
    }
    for (k = 0; k < 3; ++k) {
        c->sum[k] += raw[k];
        c->sum_sq[k] += (int64_t)raw[k] * raw[k];
        a[k] = (float)raw[k] * c->lsb_g[k];
    }
    /* Kahan sum of |a_i|: a plain float sum of 65535 terms can be off by up to
     * N * eps / 2 ~ 4e-3 relative (typically ~1e-6); compensated it stays near eps.
     * Needs IEEE evaluation order (no -ffast-math, which would fold the compensation away). */
    y = norm3(a) - c->sum_mag_c;
    t = c->sum_mag + y;
    c->sum_mag_c = (t - c->sum_mag) - y;
    c->sum_mag = t;
    c->n_saturated += is_saturated(raw) ? 1u : 0u;
    c->n++;
    return VH_OK;
}

int vh_camber_capture_add_n(vh_camber_capture_t *c, size_t n, const int16_t *raw)
{
    size_t i;
    for (i = 0; i < n; ++i) {
        if (vh_camber_capture_add(c, &raw[i * 3u]) != VH_OK) {
            return VH_ENOSPC;
        }
    }
    return VH_OK;
}

int vh_camber_capture_mean(const vh_camber_capture_t *c, float mean_g[3])
{
    float s[3];
    float s_norm;
    float scale;
    int k;
    if (c->n == 0u) {
        return VH_EINVAL;
    }
    for (k = 0; k < 3; ++k) {
        s[k] = (float)c->sum[k] * c->lsb_g[k];
    }
    s_norm = norm3(s);
    if (!(s_norm > 0.0f) || !isfinite(s_norm)) {
        return VH_EINVAL;
    }
    /* eq. 14-16: mean_k = (sum_k / N) * sum|a_i| / |sum a_i|; the constraint (eq. 8) puts the
     * mean on the sphere of radius mean|a_i| without changing its direction. */
    scale = c->sum_mag / s_norm / (float)c->n;
    for (k = 0; k < 3; ++k) {
        mean_g[k] = s[k] * scale;
    }
    return VH_OK;
}

static void cross3(const float a[3], const float b[3], float out[3])
{
    out[0] = a[1] * b[2] - a[2] * b[1];
    out[1] = a[2] * b[0] - a[0] * b[2];
    out[2] = a[0] * b[1] - a[1] * b[0];
}

static float dot3(const float a[3], const float b[3])
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/* 3x3 inverse by the adjugate; VH_EINVAL when |det| is tiny (M of unit axes has det ~ 1). */
static int inv3(const float m[9], float out[9])
{
    float det;
    float inv_det;
    int k;
    out[0] = m[4] * m[8] - m[5] * m[7];
    out[1] = m[2] * m[7] - m[1] * m[8];
    out[2] = m[1] * m[5] - m[2] * m[4];
    out[3] = m[5] * m[6] - m[3] * m[8];
    out[4] = m[0] * m[8] - m[2] * m[6];
    out[5] = m[2] * m[3] - m[0] * m[5];
    out[6] = m[3] * m[7] - m[4] * m[6];
    out[7] = m[1] * m[6] - m[0] * m[7];
    out[8] = m[0] * m[4] - m[1] * m[3];
    det = m[0] * out[0] + m[1] * out[3] + m[2] * out[6];
    if (!isfinite(det) || fabsf(det) < 0.5f) {
        return VH_EINVAL;
    }
    inv_det = 1.0f / det;
    for (k = 0; k < 9; ++k) {
        out[k] *= inv_det;
    }
    return VH_OK;
}

int vh_camber_cal_from_axes(vh_camber_cal_t *cal, const float x_axis[3], const float z_axis[3],
                            const float lsb_g[3], float ortho_tol)
{
    float y[3];
    float m[9];
    float m_inv[9];
    int r;
    int k;
    cal->valid = 0u;
    if (!finite3(x_axis) || !finite3(z_axis) || !lsb_ok(lsb_g) || !isfinite(ortho_tol)
        || !(ortho_tol >= 0.0f)) {
        return VH_EINVAL;
    }
    if (fabsf(norm3(x_axis) - 1.0f) > 1e-3f || fabsf(norm3(z_axis) - 1.0f) > 1e-3f) {
        return VH_EINVAL;
    }
    if (fabsf(dot3(x_axis, z_axis)) > ortho_tol) {
        return VH_EINVAL;
    }
    cross3(z_axis, x_axis, y); /* y = z x x keeps S right-handed */
    for (r = 0; r < 3; ++r) { /* eq. 19: columns of M are the S axes in A */
        m[r * 3 + 0] = x_axis[r];
        m[r * 3 + 1] = y[r];
        m[r * 3 + 2] = z_axis[r];
    }
    if (inv3(m, m_inv) != VH_OK) {
        return VH_EINVAL;
    }
    for (k = 0; k < 3; ++k) {
        cal->x_axis[k] = x_axis[k];
        cal->y_axis[k] = y[k];
        cal->z_axis[k] = z_axis[k];
        cal->lsb_g[k] = lsb_g[k];
    }
    for (k = 0; k < 9; ++k) {
        cal->m[k] = m[k];
        cal->m_inv[k] = m_inv[k];
    }
    /* An error of up to lsb_j on chip axis j shows on S axis i as up to sum_j |Minv_ij| lsb_j. */
    for (r = 0; r < 3; ++r) {
        cal->da_s_g[r] = fabsf(m_inv[r * 3 + 0]) * lsb_g[0] + fabsf(m_inv[r * 3 + 1]) * lsb_g[1]
                         + fabsf(m_inv[r * 3 + 2]) * lsb_g[2];
    }
    cal->valid = 1u;
    return VH_OK;
}

static vh_camber_cal_status_t check_capture(const vh_camber_capture_t *c, int pose,
                                            const vh_camber_cal_limits_t *lim,
                                            vh_camber_cal_report_t *rep)
{
    float mean[3];
    int k;
    rep->n[pose] = c->n;
    if (c->n < lim->min_samples || c->n < 2u) {
        return VH_CAMBER_CAL_TOO_FEW_SAMPLES;
    }
    if (c->n_saturated > 0u) {
        return VH_CAMBER_CAL_SATURATED;
    }
    rep->std_g[pose] = spread_g(c->sum, c->sum_sq, c->n, c->lsb_g);
    if (vh_camber_capture_mean(c, mean) != VH_OK) {
        return VH_CAMBER_CAL_INVALID;
    }
    for (k = 0; k < 3; ++k) {
        rep->mean_g[pose * 3 + k] = mean[k];
    }
    rep->mag_g[pose] = norm3(mean);
    if (!(rep->std_g[pose] <= lim->std_max_g)) {
        return VH_CAMBER_CAL_MOVING;
    }
    if (!(fabsf(rep->mag_g[pose] - 1.0f) <= lim->mag_tol_g)) {
        return VH_CAMBER_CAL_MAGNITUDE;
    }
    return VH_CAMBER_CAL_OK;
}

vh_camber_cal_status_t vh_camber_calibrate(vh_camber_cal_t *cal, vh_camber_cal_report_t *rep,
                                           const vh_camber_capture_t *x_down,
                                           const vh_camber_capture_t *z_down,
                                           const vh_camber_cal_limits_t *lim)
{
    vh_camber_cal_report_t local;
    vh_camber_cal_status_t st;
    float xu[3];
    float zu[3];
    int k;
    if (rep == NULL) {
        rep = &local;
    }
    rep->status = VH_CAMBER_CAL_INVALID;
    rep->pose = 2u;
    rep->x_dot_z = 0.0f;
    for (k = 0; k < 2; ++k) {
        rep->n[k] = 0u;
        rep->std_g[k] = 0.0f;
        rep->mag_g[k] = 0.0f;
    }
    for (k = 0; k < 6; ++k) {
        rep->mean_g[k] = 0.0f;
    }
    for (k = 0; k < 3; ++k) {
        if (x_down->lsb_g[k] != z_down->lsb_g[k]) {
            return VH_CAMBER_CAL_INVALID;
        }
    }
    if (!lsb_ok(x_down->lsb_g)) {
        return VH_CAMBER_CAL_INVALID;
    }
    rep->n[0] = x_down->n;
    rep->n[1] = z_down->n;
    st = check_capture(x_down, 0, lim, rep);
    if (st != VH_CAMBER_CAL_OK) {
        rep->pose = 0u;
        rep->status = (uint8_t)st;
        return st;
    }
    st = check_capture(z_down, 1, lim, rep);
    if (st != VH_CAMBER_CAL_OK) {
        rep->pose = 1u;
        rep->status = (uint8_t)st;
        return st;
    }
    /* eq. 17-18: unit vectors of the constrained means */
    for (k = 0; k < 3; ++k) {
        xu[k] = rep->mean_g[k] / rep->mag_g[0];
        zu[k] = rep->mean_g[3 + k] / rep->mag_g[1];
    }
    rep->x_dot_z = dot3(xu, zu);
    if (!(fabsf(rep->x_dot_z) <= lim->ortho_tol)) {
        st = VH_CAMBER_CAL_NOT_ORTHOGONAL;
    } else if (vh_camber_cal_from_axes(cal, xu, zu, x_down->lsb_g, lim->ortho_tol) != VH_OK) {
        st = VH_CAMBER_CAL_INVALID;
    } else {
        st = VH_CAMBER_CAL_OK;
    }
    rep->status = (uint8_t)st;
    return st;
}

void vh_camber_cal_apply(const vh_camber_cal_t *cal, const float counts[3], float a_s_g[3])
{
    float a[3];
    int r;
    for (r = 0; r < 3; ++r) {
        a[r] = counts[r] * cal->lsb_g[r];
    }
    for (r = 0; r < 3; ++r) { /* eq. 19 */
        a_s_g[r] = cal->m_inv[r * 3 + 0] * a[0] + cal->m_inv[r * 3 + 1] * a[1]
                   + cal->m_inv[r * 3 + 2] * a[2];
    }
}

/* ---- Angles and bound --------------------------------------------------------------------- */

void vh_camber_angles(const float a_s[3], float *theta_rad, float *psi_rad)
{
    /* eq. 4: psi = -atan(ax / az); atan2 equals it for az > 0 and stays defined otherwise */
    *psi_rad = vh_atan2f(-a_s[0], a_s[2]);
    /* eq. 6: theta = atan(ay / sqrt(ax^2 + az^2)), free of psi */
    *theta_rad = vh_atan2f(a_s[1], sqrtf(a_s[0] * a_s[0] + a_s[2] * a_s[2]));
}

float vh_camber_bound(float theta_rad, float psi_rad, const float da[3], float g)
{
    float st = vh_sinf(theta_rad);
    /* eq. 22 */
    return (fabsf(st * vh_sinf(psi_rad) * da[0]) + fabsf(vh_cosf(theta_rad) * da[1])
            + fabsf(st * vh_cosf(psi_rad) * da[2]))
           / g;
}

/* ---- Inspection --------------------------------------------------------------------------- */

void vh_camber_config_default(vh_camber_config_t *cfg)
{
    cfg->window = 256u;
    cfg->min_samples = 32u;
    cfg->mag_tol_g = 0.05f;
    cfg->std_max_g = 0.03f;
}

void vh_camber_reset(vh_camber_t *c)
{
    int k;
    for (k = 0; k < 3; ++k) {
        c->sum[k] = 0;
        c->sum_sq[k] = 0;
    }
    c->n = 0u;
    c->n_moving_flag = 0u;
    c->n_saturated = 0u;
}

int vh_camber_set_calibration(vh_camber_t *c, const vh_camber_cal_t *cal)
{
    vh_camber_reset(c);
    if (cal == NULL || cal->valid != 1u || !lsb_ok(cal->lsb_g)) {
        c->cal.valid = 0u;
        return VH_EINVAL;
    }
    c->cal = *cal;
    return VH_OK;
}

int vh_camber_init(vh_camber_t *c, const vh_camber_config_t *cfg, const vh_camber_cal_t *cal)
{
    if (cfg->min_samples < 2u || cfg->window < cfg->min_samples || !isfinite(cfg->mag_tol_g)
        || !(cfg->mag_tol_g > 0.0f) || !isfinite(cfg->std_max_g) || !(cfg->std_max_g > 0.0f)) {
        return VH_EINVAL;
    }
    c->cfg = *cfg;
    c->results = 0u;
    c->cal.valid = 0u;
    if (cal != NULL && cal->valid == 1u) {
        (void)vh_camber_set_calibration(c, cal);
    }
    vh_camber_reset(c);
    return VH_OK;
}

static void clear_result(vh_camber_result_t *out, uint32_t n, vh_camber_reason_t reason)
{
    int k;
    out->theta_rad = 0.0f;
    out->psi_rad = 0.0f;
    out->bound_rad = 0.0f;
    for (k = 0; k < 3; ++k) {
        out->a_s_g[k] = 0.0f;
    }
    out->mag_g = 0.0f;
    out->std_g = 0.0f;
    out->n = n;
    out->reason = (uint8_t)reason;
}

void vh_camber_evaluate(vh_camber_t *c, vh_camber_result_t *out)
{
    float mean_counts[3];
    vh_camber_reason_t reason;
    float theta;
    float psi;
    int k;
    c->results++;
    if (c->cal.valid != 1u) {
        clear_result(out, c->n, VH_CAMBER_NOT_CALIBRATED);
        vh_camber_reset(c);
        return;
    }
    if (c->n < c->cfg.min_samples) {
        clear_result(out, c->n, VH_CAMBER_TOO_FEW_SAMPLES);
        vh_camber_reset(c);
        return;
    }
    clear_result(out, c->n, VH_CAMBER_OK);
    /* The mean of a_S over the window is M^-1 applied to the mean count (eq. 19 is linear). */
    for (k = 0; k < 3; ++k) {
        mean_counts[k] = (float)c->sum[k] / (float)c->n;
    }
    vh_camber_cal_apply(&c->cal, mean_counts, out->a_s_g);
    out->mag_g = norm3(out->a_s_g);
    /* The trace of the covariance is rotation invariant, so the spread in A is the one in S. */
    out->std_g = spread_g(c->sum, c->sum_sq, c->n, c->cal.lsb_g);
    if (c->n_moving_flag > 0u) {
        reason = VH_CAMBER_NOT_STATIONARY_FLAG;
    } else if (c->n_saturated > 0u) {
        reason = VH_CAMBER_SATURATED;
    } else if (!(out->std_g <= c->cfg.std_max_g)) {
        reason = VH_CAMBER_MOVING;
    } else if (!(fabsf(out->mag_g - 1.0f) <= c->cfg.mag_tol_g)) {
        reason = VH_CAMBER_MAGNITUDE;
    } else {
        reason = VH_CAMBER_OK;
    }
    out->reason = (uint8_t)reason;
    if (reason == VH_CAMBER_OK) {
        vh_camber_angles(out->a_s_g, &theta, &psi);
        out->theta_rad = theta;
        out->psi_rad = psi;
        /* eq. 22 with g = the measured |a| (eq. 20's exact denominator) and da = the chip
         * resolution carried to the S axes */
        out->bound_rad = vh_camber_bound(theta, psi, c->cal.da_s_g, out->mag_g);
    }
    vh_camber_reset(c);
}

int vh_camber_step(vh_camber_t *c, const int16_t raw[3], bool stationary, vh_camber_result_t *out)
{
    int k;
    for (k = 0; k < 3; ++k) {
        c->sum[k] += raw[k];
        c->sum_sq[k] += (int64_t)raw[k] * raw[k];
    }
    c->n_moving_flag += stationary ? 0u : 1u;
    c->n_saturated += is_saturated(raw) ? 1u : 0u;
    c->n++;
    if (c->n < c->cfg.window) {
        return 0;
    }
    vh_camber_evaluate(c, out);
    return 1;
}

size_t vh_camber_run(vh_camber_t *c, size_t n, const int16_t *raw, const uint8_t *stationary,
                     vh_camber_result_t *out, size_t out_cap)
{
    vh_camber_result_t res;
    size_t i;
    size_t done = 0u;
    for (i = 0; i < n; ++i) {
        bool still = (stationary == NULL) || (stationary[i] != 0u);
        if (vh_camber_step(c, &raw[i * 3u], still, &res)) {
            if (done < out_cap) {
                out[done] = res;
            }
            done++;
        }
    }
    return done;
}
