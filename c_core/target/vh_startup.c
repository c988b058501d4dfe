/* vh_startup.c - reset for the Cortex-M4F image: the vector table, .data copied from flash, .bss
 * zeroed, the FPU enabled, the stack painted (for its high-water mark), then main. Conventions as
 * CMSIS's startup files: initial SP in entry 0, reset in entry 1, the linker script's symbols. */
#include <stdint.h>

#include "vh_target.h"

extern uint32_t vh_data_load[], vh_data_start[], vh_data_end[];
extern uint32_t vh_bss_start[], vh_bss_end[];
extern uint32_t vh_stack_bottom[], vh_stack_top[];

int main(void);
void vh_reset_handler(void);
void vh_fault_handler(void);

#define SCB_CPACR (*(volatile uint32_t *)0xE000ED88u)

void vh_fault_handler(void)
{
    vh_target_fault(); /* tells the host, then waits for the emulator to be stopped */
}

/* the core's 16 exceptions; no peripheral interrupt is used (the link is polled) */
__attribute__((section(".vectors"), used)) static void (*const VECTORS[16])(void) = {
    (void (*)(void))(uintptr_t)vh_stack_top,
    vh_reset_handler,
    vh_fault_handler, /* NMI */
    vh_fault_handler, /* HardFault */
    vh_fault_handler, /* MemManage */
    vh_fault_handler, /* BusFault */
    vh_fault_handler, /* UsageFault */
    0, 0, 0, 0,
    vh_fault_handler, /* SVCall */
    vh_fault_handler, /* DebugMonitor */
    0,
    vh_fault_handler, /* PendSV */
    vh_fault_handler, /* SysTick */
};

void vh_reset_handler(void)
{
    uint32_t *src = vh_data_load, *dst;
    for (dst = vh_data_start; dst < vh_data_end;) {
        *dst++ = *src++;
    }
    for (dst = vh_bss_start; dst < vh_bss_end;) {
        *dst++ = 0u;
    }
    /* CP10 and CP11 full access: the FPU, before any float instruction runs */
    SCB_CPACR |= 0xFu << 20;
    __asm__ volatile("dsb\n\tisb" ::: "memory");
    vh_stack_paint();
    (void)main();
    for (;;) {
    }
}
