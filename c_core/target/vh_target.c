/* vh_target.c - see vh_target.h. Register maps: ARM CMSDK APB UART (DDI0479 "Cortex-M System
 * Design Kit" TRM: DATA 0x00, STATE 0x04 (bit 0 TX full, bit 1 RX full), CTRL 0x08 (bit 0 TX enable,
 * bit 1 RX enable), BAUDDIV 0x10, at least 16); SysTick (ARMv7-M ARM B3.3: CSR 0xE000E010, RVR
 * 0xE000E014, CVR 0xE000E018). */
#include "vh_target.h"

#define UART0 0x40004000u
#define REG(a) (*(volatile uint32_t *)(a))
#define UART_DATA REG(UART0 + 0x00u)
#define UART_STATE REG(UART0 + 0x04u)
#define UART_CTRL REG(UART0 + 0x08u)
#define UART_BAUDDIV REG(UART0 + 0x10u)
#define SYST_CSR REG(0xE000E010u)
#define SYST_RVR REG(0xE000E014u)
#define SYST_CVR REG(0xE000E018u)

#define PAINT 0xA5C3E10Fu

extern uint32_t vh_stack_bottom[], vh_stack_top[];
static uint32_t *paint_top; /* the SP at the last paint */

void vh_uart_init(void)
{
    UART_BAUDDIV = 16u; /* the fastest the UART allows (25 MHz / 16); QEMU does not pace it */
    UART_CTRL = 0x3u;   /* TX and RX on, no interrupts: polled */
}

uint8_t vh_uart_get(void)
{
    while (!(UART_STATE & 0x2u)) {
    }
    return (uint8_t)UART_DATA;
}

void vh_uart_put(uint8_t b)
{
    while (UART_STATE & 0x1u) {
    }
    UART_DATA = b;
}

void vh_uart_write(const void *p, size_t n)
{
    const uint8_t *b = p;
    while (n--) {
        vh_uart_put(*b++);
    }
}

void vh_uart_read(void *p, size_t n)
{
    uint8_t *b = p;
    while (n--) {
        *b++ = vh_uart_get();
    }
}

void vh_systick_start(void)
{
    SYST_RVR = 0xFFFFFFu;
    SYST_CVR = 0u;
    SYST_CSR = 0x5u; /* enabled, core clock, no interrupt */
}

static uint32_t *sp_now(void)
{
    uint32_t *sp;
    __asm__ volatile("mov %0, sp" : "=r"(sp));
    return sp;
}

void vh_stack_paint(void)
{
    uint32_t *p;
    paint_top = sp_now() - 16; /* this function's own frame stays */
    for (p = vh_stack_bottom; p < paint_top; ++p) {
        *p = PAINT;
    }
}

uint32_t vh_stack_used(void)
{
    const uint32_t *p = vh_stack_bottom;
    while (p < paint_top && *p == PAINT) {
        ++p;
    }
    return (uint32_t)((const uint8_t *)vh_stack_top - (const uint8_t *)p);
}

uint32_t vh_stack_depth_here(void)
{
    return (uint32_t)((const uint8_t *)vh_stack_top - (const uint8_t *)sp_now());
}

void vh_target_fault(void)
{
    vh_uart_put((uint8_t)'F');
    vh_uart_put(0u);
    vh_uart_put(0u);
    for (;;) {
    }
}

uint32_t vh_stack_size(void)
{
    return (uint32_t)((const uint8_t *)vh_stack_top - (const uint8_t *)vh_stack_bottom);
}
