/* vh_replay.c - see vh_replay.h. Host only (never flashed): a log replay harness beside the
 * in-process lockstep of vh_dlsim.c. */
#include "vh_replay.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

size_t vh_replay_run(vh_ecu_t *ecu, const vh_frame_t *in, const uint8_t *op, const uint32_t *steps, size_t n,
                     vh_replay_pos_t *pos, vh_frame_t *out, uint32_t *out_event, uint32_t *out_step, size_t cap)
{
    size_t written = 0;
    while (pos->event < n) {
        const size_t i = pos->event;
        while (pos->step < steps[i]) {
            size_t k, got;
            if (cap - written < VH_ECU_MAX_TX) {
                return written;
            }
            got = vh_ecu_step(ecu, out + written, cap - written);
            for (k = 0; k < got; k++) {
                out_event[written + k] = (uint32_t)i;
                out_step[written + k] = pos->step;
            }
            written += got;
            pos->step++;
        }
        if (op[i] == VH_REPLAY_RX) {
            vh_ecu_rx(ecu, &in[i]);
        } else if (op[i] == VH_REPLAY_RESET) {
            vh_ecu_reset(ecu);
        }
        pos->event++;
        pos->step = 0;
    }
    return written;
}

/* Character classes by table (the parser's inner loops): 1 + the hex digit's value, 0 if none;
 * whitespace as isspace() in the C locale */
static const unsigned char HEX1[256] = {
    ['0'] = 1, ['1'] = 2, ['2'] = 3, ['3'] = 4, ['4'] = 5, ['5'] = 6, ['6'] = 7, ['7'] = 8, ['8'] = 9, ['9'] = 10,
    ['a'] = 11, ['b'] = 12, ['c'] = 13, ['d'] = 14, ['e'] = 15, ['f'] = 16,
    ['A'] = 11, ['B'] = 12, ['C'] = 13, ['D'] = 14, ['E'] = 15, ['F'] = 16,
};
static const unsigned char SPACE[256] = {[' '] = 1, ['\t'] = 1, ['\r'] = 1, ['\n'] = 1, ['\v'] = 1, ['\f'] = 1};

static int is_space(char c)
{
    return SPACE[(unsigned char)c];
}

static int hex_value(char c)
{
    return (int)HEX1[(unsigned char)c] - 1;
}

/* digits[.digits] in [p, e) as the nearest double, when that is exact arithmetic: the digits as an
 * integer m <= 2^53 and at most 22 of them after the point, so m and 10^n are exact doubles and one
 * IEEE division rounds m / 10^n correctly, as strtod does (Clinger's fast path). 0: not that form
 * (strtod reads it). A candump -l timestamp (10 + 6 digits) always is; strtod was half the parse. */
static int fast_decimal(const char *p, const char *e, double *t)
{
    static const double pow10[23] = {1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11,
                                     1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};
    uint64_t m = 0;
    size_t digits = 0;
    size_t frac = 0;
    int point = 0;
    for (; p < e; p++) {
        if (*p >= '0' && *p <= '9') {
            if (++digits > 17) {
                return 0;
            }
            m = m * 10u + (uint64_t)(*p - '0');
            frac += (size_t)point;
        } else if (*p == '.' && !point) {
            point = 1;
        } else {
            return 0;
        }
    }
    if (digits == 0 || m > (UINT64_C(1) << 53) || frac > 22) {
        return 0;
    }
    *t = (double)m / pow10[frac];
    return 1;
}

static int has_space(const char *p, const char *e)
{
    for (; p < e; p++) {
        if (is_space(*p)) {
            return 1;
        }
    }
    return 0;
}

/* One stripped, non-empty line [p, e). 1: a data frame in *f / *t; 0: a remote or error frame
 * (skipped); -1: not a candump -L line. Follows python-can's CanutilsLogReader: three fields
 * split at whitespace, "(timestamp) channel ID#data", and python-can's " R"/" T" direction as a
 * fourth. The third field is not scanned for its end: where it ends is known from the line's end
 * (and the direction), and decoding it in hex finds any whitespace inside it. */
static int parse_line(const char *p, const char *e, vh_frame_t *f, double *t)
{
    const char *tok[2];
    const char *tend[2];
    const char *s = p;
    const char *f2;
    const char *f2end;
    char num[64];
    char *endp;
    const char *hash;
    const char *d;
    size_t idlen, k, dlen;
    uint32_t id = 0;
    int direction;

    for (k = 0; k < 2; k++) {
        while (s < e && is_space(*s)) {
            s++;
        }
        tok[k] = s;
        while (s < e && !is_space(*s)) {
            s++;
        }
        tend[k] = s;
    }
    while (s < e && is_space(*s)) {
        s++;
    }
    /* " R" / " T" at the end: python-can's direction, a field of its own */
    direction = e - p >= 2 && e[-2] == ' ' && (e[-1] == 'r' || e[-1] == 'R' || e[-1] == 't' || e[-1] == 'T');
    f2 = s;
    f2end = direction ? e - 2 : e;
    while (f2end > f2 && is_space(f2end[-1])) {
        f2end--;
    }
    if (tend[1] == tok[1] || f2end <= f2) {
        return -1; /* fewer than three fields */
    }
    /* (timestamp) */
    k = (size_t)(tend[0] - tok[0]);
    if (k < 3 || k > sizeof num || tok[0][0] != '(' || tend[0][-1] != ')') {
        return -1;
    }
    if (!fast_decimal(tok[0] + 1, tend[0] - 1, t)) {
        for (d = tok[0] + 1; d < tend[0] - 1; d++) {
            if (!((*d >= '0' && *d <= '9') || *d == '.' || *d == 'e' || *d == 'E' || *d == '+' || *d == '-')) {
                return -1;
            }
        }
        memcpy(num, tok[0] + 1, k - 2);
        num[k - 2] = '\0';
        *t = strtod(num, &endp);
        if (*endp != '\0' || !isfinite(*t)) {
            return -1;
        }
    }
    /* ID#data, ID##Fdata, ID#R */
    hash = memchr(f2, '#', (size_t)(f2end - f2));
    if (hash == NULL) {
        return -1;
    }
    idlen = (size_t)(hash - f2);
    if (idlen == 0 || idlen > 8) {
        return -1; /* more than 8 hex digits does not fit a CAN ID (29 bits + the error flag) */
    }
    for (k = 0; k < idlen; k++) {
        int v = hex_value(f2[k]);
        if (v < 0) {
            return -1;
        }
        id = (id << 4) | (uint32_t)v;
    }
    memset(f, 0, sizeof *f);
    f->flags = idlen > 3 ? VH_FRAME_EXT : 0;
    d = hash + 1;
    if (d < f2end && *d == '#') {
        if (d + 1 >= f2end || d[1] < '0' || d[1] > '9') {
            return -1;
        }
        f->flags |= VH_FRAME_FD | ((d[1] - '0') & 1 ? VH_FRAME_BRS : 0);
        d += 2;
    }
    if ((d < f2end && (*d == 'r' || *d == 'R')) || ((id & 0x20000000u) && (id & 0x80u))) {
        /* a remote frame; CAN_ERR_FLAG | CAN_ERR_BUSERROR: an error frame */
        return has_space(d, f2end) ? -1 : 0;
    }
    id &= 0x1FFFFFFFu;
    if (!(f->flags & VH_FRAME_EXT) && id > 0x7FFu) {
        return -1;
    }
    dlen = (size_t)(f2end - d);
    if (dlen % 2 != 0 || dlen / 2 > VH_FRAME_MAX_LEN) {
        return -1;
    }
    for (k = 0; k < dlen / 2; k++) {
        int hi = hex_value(d[2 * k]);
        int lo = hex_value(d[2 * k + 1]);
        if (hi < 0 || lo < 0) {
            return -1; /* not hex, or whitespace: a fourth field */
        }
        f->data[k] = (uint8_t)(hi << 4 | lo);
    }
    f->id = id;
    f->len = (uint8_t)(dlen / 2);
    return 1;
}

int vh_candump_parse(const char *buf, size_t len, int final, vh_frame_t *out, double *ts, size_t cap,
                     size_t *n_out, size_t *used, size_t *lines, size_t *skipped)
{
    size_t pos = 0;
    *n_out = 0;
    *lines = 0;
    while (pos < len && *n_out < cap) {
        const char *line = buf + pos;
        const char *nl = memchr(line, '\n', len - pos);
        const char *e;
        size_t next;
        int r;
        if (nl == NULL && !final) {
            break;
        }
        e = nl != NULL ? nl : buf + len;
        next = (size_t)(e - buf) + (nl != NULL ? 1 : 0);
        while (line < e && is_space(*line)) {
            line++;
        }
        while (e > line && is_space(e[-1])) {
            e--;
        }
        if (line < e) {
            r = parse_line(line, e, &out[*n_out], &ts[*n_out]);
            if (r < 0) {
                *used = pos;
                return VH_EINVAL;
            }
            if (r > 0) {
                (*n_out)++;
            } else {
                (*skipped)++;
            }
        }
        pos = next;
        (*lines)++;
    }
    *used = pos;
    return VH_OK;
}
