/* vh_pil_main.c - the ECU on the emulated Cortex-M4F, driven over the frame link (UART0).
 *
 * The link (docs/firmware.md, "Processor in the loop"): messages of type (1 byte), length (u16,
 * little-endian) and payload, each way. The host sends the calibration block (the flashed
 * vh_ecu_config_t, byte for byte), received frames, ticks and resets; the image answers a tick with
 * the frames it transmits and the SysTick counts of each runnable. Polled, no interrupts, one stack.
 */
#include <math.h>
#include <stddef.h>
#include <string.h>

#include "vh_ecu.h"
#include "vh_mathf.h"
#include "vh_probe.h"
#include "vh_target.h"

enum {
    MSG_INIT = 'I',   /* -> config bytes; <- i32 status, u32 sizeof config, u32 init stack depth */
    MSG_RX = 'R',     /* -> u32 id, u8 flags, u8 len, data[len]; no answer */
    MSG_STEP = 'S',   /* -> -; <- 'T' */
    MSG_TX = 'T',     /* u32 tick, u8 n, n x (u32 id, u8 flags, u8 len, data[len]), u8 m, m x u32 counts:
                         each application's, the whole vh_ecu_step, the tick's vh_ecu_rx calls */
    MSG_RESET = 'Z',  /* -> -; <- 'Z' */
    MSG_READ = 'M',   /* -> u32 offset, u32 len in vh_ecu_t; <- the bytes */
    MSG_WRITE = 'P',  /* -> u32 offset, bytes into vh_ecu_t (a calibration the host applied to its copy); <- 'P' */
    MSG_STACK = 'W',  /* -> -; <- u32 deepest since the last 'W' (or init), u32 main's depth, u32 size; repaints */
    MSG_CAL = 'K',    /* -> u32 n; <- u32 SysTick counts of a loop of n x 2 instructions */
    MSG_LIBM = 'Q',   /* -> u8 function, floats; <- the function of each (pairs for atan2f): the target's vh_mathf against the host's */
    MSG_HELLO = 'H',  /* -> -; <- u32 sizeof vh_ecu_config_t, u32 sizeof vh_ecu_t, u16 applications, their names */
    MSG_ERROR = 'E'   /* <- a message it did not understand: its type */
};

#define MAX_PAYLOAD sizeof(vh_ecu_config_t)

static vh_ecu_t ecu;
static union {
    vh_ecu_config_t cfg;
    uint8_t raw[MAX_PAYLOAD];
} in;
static uint8_t out[4u + 1u + VH_ECU_MAX_TX * (6u + VH_FRAME_MAX_LEN) + 1u + 4u * (VH_PROBE_MAX_APPS + 2u)];
static vh_frame_t tx[VH_ECU_MAX_TX];
static uint32_t rx_counts; /* SysTick counts in vh_ecu_rx since the last tick */
static uint32_t main_depth;

static void put_u32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
    p[2] = (uint8_t)(v >> 16);
    p[3] = (uint8_t)(v >> 24);
}

static uint32_t get_u32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static void send(uint8_t type, const void *payload, size_t n)
{
    vh_uart_put(type);
    vh_uart_put((uint8_t)n);
    vh_uart_put((uint8_t)(n >> 8));
    vh_uart_write(payload, n);
}

static void do_step(void)
{
    size_t n, i, k, pos = 5u;
    uint32_t t0, counts;
    put_u32(out, ecu.tick);
    memset(vh_probe_counts, 0, sizeof vh_probe_counts);
    t0 = vh_systick_now();
    n = vh_ecu_step(&ecu, tx, VH_ECU_MAX_TX);
    counts = vh_systick_since(t0);
    out[4] = (uint8_t)n;
    for (i = 0; i < n; ++i) {
        put_u32(out + pos, tx[i].id);
        out[pos + 4] = tx[i].flags;
        out[pos + 5] = tx[i].len;
        memcpy(out + pos + 6, tx[i].data, tx[i].len);
        pos += 6u + tx[i].len;
    }
    out[pos++] = (uint8_t)(VH_ECU_N_APPS + 2u);
    for (k = 0; k < VH_ECU_N_APPS; ++k, pos += 4) {
        put_u32(out + pos, vh_probe_counts[k]);
    }
    put_u32(out + pos, counts);
    put_u32(out + pos + 4, rx_counts);
    pos += 8u;
    rx_counts = 0u;
    send(MSG_TX, out, pos);
}

static void do_rx(size_t len)
{
    static vh_frame_t f;
    uint32_t t0;
    if (len < 6u || in.raw[5] > VH_FRAME_MAX_LEN || len != 6u + in.raw[5]) {
        send(MSG_ERROR, "R", 1);
        return;
    }
    memset(&f, 0, sizeof f);
    f.id = get_u32(in.raw);
    f.flags = in.raw[4];
    f.len = in.raw[5];
    memcpy(f.data, in.raw + 6, f.len);
    t0 = vh_systick_now();
    vh_ecu_rx(&ecu, &f);
    rx_counts += vh_systick_since(t0);
}

static void do_init(size_t len)
{
    uint8_t r[12];
    int32_t status = -2; /* the host's vh_ecu_config_t is not this one's size */
    uint32_t depth;
    vh_stack_paint();
    if (len == sizeof(vh_ecu_config_t)) {
        status = (int32_t)vh_ecu_init_params(&ecu, &in.cfg);
    }
    depth = vh_stack_used();
    vh_stack_paint(); /* from here on, the ticks' and the frames' depth */
    put_u32(r, (uint32_t)status);
    put_u32(r + 4, (uint32_t)sizeof(vh_ecu_config_t));
    put_u32(r + 8, depth - main_depth);
    send(MSG_INIT, r, sizeof r);
}

static void do_hello(void)
{
    size_t k, pos = 10u;
    put_u32(out, (uint32_t)sizeof(vh_ecu_config_t));
    put_u32(out + 4, (uint32_t)sizeof(vh_ecu_t));
    out[8] = (uint8_t)VH_ECU_N_APPS;
    out[9] = 0u;
    for (k = 0; k < VH_ECU_N_APPS; ++k) {
        const size_t n = strlen(vh_probe_app_name[k]) + 1u;
        memcpy(out + pos, vh_probe_app_name[k], n);
        pos += n;
    }
    send(MSG_HELLO, out, pos);
}

static void do_write(size_t len)
{
    uint32_t off;
    if (len < 4u || (off = get_u32(in.raw)) > sizeof ecu || len - 4u > sizeof ecu - off) {
        send(MSG_ERROR, "P", 1);
        return;
    }
    memcpy((uint8_t *)&ecu + off, in.raw + 4, len - 4u);
    send(MSG_WRITE, NULL, 0);
}

static void do_read(size_t len)
{
    uint32_t off, n;
    if (len != 8u) {
        send(MSG_ERROR, "M", 1);
        return;
    }
    off = get_u32(in.raw);
    n = get_u32(in.raw + 4);
    if (off > sizeof ecu || n > sizeof ecu - off || n > 0xFFFFu) {
        send(MSG_ERROR, "M", 1);
        return;
    }
    send(MSG_READ, (const uint8_t *)&ecu + off, n);
}

static void do_cal(size_t len)
{
    uint8_t r[4];
    uint32_t n, t0;
    if (len != 4u) {
        send(MSG_ERROR, "K", 1);
        return;
    }
    n = get_u32(in.raw);
    t0 = vh_systick_now();
    __asm__ volatile("1: subs %0, %0, #1\n\tbne 1b" : "+r"(n) : : "cc");
    put_u32(r, vh_systick_since(t0));
    send(MSG_CAL, r, sizeof r);
}

/* The float32 functions the firmware calls (vh_mathf.c; sqrtf from newlib), on the target's build; in place */
static void do_libm(size_t len)
{
    size_t i, m = 0u;
    const size_t n = (len - 1u) / sizeof(float);
    const uint8_t fn = in.raw[0];
    uint8_t *v = in.raw + 1;
    for (i = 0; i < n; ++i) {
        float x, y = 0.0f, r;
        memcpy(&x, v + 4u * i, sizeof x);
        switch (fn) {
        case 0: r = vh_sinf(x); break;
        case 1: r = vh_cosf(x); break;
        case 2: r = vh_atanf(x); break;
        case 3:
            memcpy(&y, v + 4u * ++i, sizeof y);
            r = vh_atan2f(x, y);
            break;
        default: r = sqrtf(x); break;
        }
        memcpy(v + 4u * m++, &r, sizeof r);
    }
    send(MSG_LIBM, v, m * sizeof(float));
}

int main(void)
{
    main_depth = vh_stack_depth_here();
    vh_uart_init();
    vh_systick_start();
    vh_stack_paint();
    for (;;) {
        const uint8_t type = vh_uart_get();
        size_t len = vh_uart_get();
        len |= (size_t)vh_uart_get() << 8;
        if (len > sizeof in.raw) { /* not this protocol: nothing more can be framed */
            send(MSG_ERROR, &type, 1);
            for (;;) {
            }
        }
        vh_uart_read(in.raw, len);
        switch (type) {
        case MSG_INIT:
            do_init(len);
            break;
        case MSG_RX:
            do_rx(len);
            break;
        case MSG_STEP:
            do_step();
            break;
        case MSG_RESET:
            vh_ecu_reset(&ecu);
            send(MSG_RESET, NULL, 0);
            break;
        case MSG_READ:
            do_read(len);
            break;
        case MSG_WRITE:
            do_write(len);
            break;
        case MSG_STACK: {
            uint8_t r[12];
            put_u32(r, vh_stack_used() - main_depth);
            put_u32(r + 4, main_depth);
            put_u32(r + 8, vh_stack_size());
            vh_stack_paint();
            send(MSG_STACK, r, sizeof r);
            break;
        }
        case MSG_LIBM:
            if (len >= 1u) {
                do_libm(len);
            }
            break;
        case MSG_CAL:
            do_cal(len);
            break;
        case MSG_HELLO:
            do_hello();
            break;
        default:
            send(MSG_ERROR, &type, 1);
        }
    }
}
