/**
 * @file hal.h
 * Hardware abstraction: the only place that touches addresses.
 *
 * On the target (HAL_TARGET defined) Xil_In32/Xil_Out32 are volatile 32-bit accesses to the
 * MicroBlaze MCS I/O bus. On the host they go through a bus hook (function pointers) that the
 * unit tests and the co-simulation install with hal_set_bus_hook(); with no hook installed,
 * reads return 0xFFFFFFFF and writes are dropped (an empty bus).
 */
#ifndef HAL_H
#define HAL_H

#include <stddef.h>
#include <stdint.h>

/** Bus hook for host builds. ctx is passed back unchanged. */
typedef uint32_t (*hal_read32_fn)(void *ctx, uint32_t addr);
typedef void (*hal_write32_fn)(void *ctx, uint32_t addr, uint32_t value);
typedef void (*hal_delay_us_fn)(void *ctx, uint32_t us);
typedef void (*hal_uart_write_fn)(void *ctx, const uint8_t *data, uint32_t len);

/** Install (or, with NULL functions, remove) the host bus hook. Any of the pointers may be
 *  NULL: delays then return at once, UART writes are dropped. */
void hal_set_bus_hook(hal_read32_fn rd, hal_write32_fn wr, hal_delay_us_fn delay,
                      hal_uart_write_fn uart, void *ctx);

uint32_t Xil_In32(uint32_t addr);
void Xil_Out32(uint32_t addr, uint32_t value);

/** Wait `us` microseconds. Target: the SoC timer's WAIT register (HAL_TIMER_BASEADDR), so the
 *  time does not depend on the CPU's speed and the CPU sleeps meanwhile. Host: the bus hook's
 *  delay. */
void hal_delay_us(uint32_t us);

/** Core clock cycles (HAL_CPU_HZ) since start-up, wrapping at 2^32: measure elapsed time as
 *  the unsigned difference of two readings. Target: the timer's COUNT register. Host: the sum
 *  of the delays so far (the host's bus is infinitely fast: only delays take time). */
uint32_t hal_ticks(void);

/** Send bytes to the radio UART (target: the SoC's UART, hdl/uart.py, at HAL_UART_BASEADDR).
 *  Each byte waits at most HAL_UART_TIMEOUT_POLLS status polls for room; returns FW_OK, or
 *  FW_ERR_TIMEOUT (the rest is not sent) when the transmitter never frees. */
int32_t hal_uart_write(const uint8_t *data, uint32_t len);

/** Offer one byte to the radio UART without waiting: returns 1 when it was taken, 0 when
 *  the transmitter is busy (try again later). Host: always taken (the bus hook's UART). */
int32_t hal_uart_put(uint8_t byte);

#ifndef HAL_UART_BASEADDR
#define HAL_UART_BASEADDR 0xC0020000u /**< hdl/soc.py UART_BASEADDR */
#endif
#define HAL_UART_DATA_OFFSET      0x0u  /**< write: send a byte */
#define HAL_UART_STATUS_OFFSET    0x4u  /**< bit 0: a byte may be written */
#define HAL_UART_STATUS_TX_READY  0x1u
#define HAL_UART_BAUD_OFFSET      0x8u  /**< core cycles per bit (hdl/uart.py BAUD) */
#define HAL_UART_DATA_RX_VALID    0x100u /**< DATA read: bit 8 set when a byte was received */
/** One byte takes 87 us at 115200 baud; a status poll at least 2 bus cycles (40 ns at 50 MHz):
 *  10000 polls (>= 400 us) cover a byte with margin. */
#define HAL_UART_TIMEOUT_POLLS 10000u

/** The soft CPU's timer (hdl/cpu.py CPUTimer): COUNT reads the core clock cycles since
 *  reset (32 bits, wrapping); a write of n to WAIT completes n core cycles later, the CPU
 *  stalled meanwhile. */
#ifndef HAL_TIMER_BASEADDR
#define HAL_TIMER_BASEADDR 0xC0030000u
#endif
#define HAL_TIMER_COUNT_OFFSET 0x0u
#define HAL_TIMER_WAIT_OFFSET  0x4u

#ifndef HAL_CPU_HZ
#define HAL_CPU_HZ 50000000u /**< the CPU and SoC core clock */
#endif

/** Register access for the generated stereo_regs.h map. */
#define STEREO_ReadReg(BaseAddress, RegOffset) Xil_In32((BaseAddress) + (RegOffset))
#define STEREO_WriteReg(BaseAddress, RegOffset, Data) \
    Xil_Out32((BaseAddress) + (RegOffset), (uint32_t)(Data))

#define ARRAY_SIZE(a) (sizeof(a) / sizeof((a)[0]))

#endif /* HAL_H */
