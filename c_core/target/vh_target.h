/* vh_target.h - the board support of the emulated Cortex-M4F image (QEMU mps2-an386): the frame
 * link's UART, the cycle probe and the stack paint. Never in the host's extension. */
#ifndef VH_TARGET_H
#define VH_TARGET_H

#include <stddef.h>
#include <stdint.h>

/* CMSDK APB UART0 (0x40004000), polled: one byte in, one byte out */
void vh_uart_init(void);
uint8_t vh_uart_get(void);
void vh_uart_put(uint8_t b);
void vh_uart_write(const void *p, size_t n);
void vh_uart_read(void *p, size_t n);

/* SysTick on the core clock, free-running 24-bit down-counter (reload 0xFFFFFF) */
void vh_systick_start(void);
static inline uint32_t vh_systick_now(void) { return *(volatile uint32_t *)0xE000E018u; }
/* counts since a reading t0 of the down-counter (less than one wrap ago) */
static inline uint32_t vh_systick_since(uint32_t t0) { return (t0 - vh_systick_now()) & 0xFFFFFFu; }

/* The stack below the caller's frame painted with a pattern; the deepest use since, in bytes from
 * the top of the stack (the lowest word changed); the depth of the caller's SP */
void vh_stack_paint(void);
uint32_t vh_stack_used(void);
uint32_t vh_stack_depth_here(void);
uint32_t vh_stack_size(void);

/* A fault: a 'F' message on the link (the faulting PC if known), then stop */
void vh_target_fault(void);

#endif
