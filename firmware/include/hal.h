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
#include "fw_status.h"

#ifndef HAL_CPU_HZ
#define HAL_CPU_HZ 50000000u /**< the CPU and SoC core clock */
#endif

/** Bus hook for host builds. ctx is passed back unchanged. */
typedef uint32_t (*hal_read32_fn)(void *ctx, uint32_t addr);
typedef void (*hal_write32_fn)(void *ctx, uint32_t addr, uint32_t value);
typedef void (*hal_delay_us_fn)(void *ctx, uint32_t us);
typedef void (*hal_uart_write_fn)(void *ctx, const uint8_t *data, uint32_t len);
typedef uint32_t (*hal_ticks_fn)(void *ctx);

/** Install (or, with NULL functions, remove) the host bus hook. Any of the pointers may be
 *  NULL: delays then return at once, UART writes are dropped. */
void hal_set_bus_hook(hal_read32_fn rd, hal_write32_fn wr, hal_delay_us_fn delay,
                      hal_uart_write_fn uart, void *ctx);

/** Host builds: add a clock of the harness's own to hal_ticks (NULL removes it). The unit
 *  tests give it a modelled cost per bus access, or a simulated device's time, so that a
 *  wait's deadline is reached while it polls. */
void hal_set_ticks_hook(hal_ticks_fn ticks, void *ctx);

uint32_t Xil_In32(uint32_t addr);
void Xil_Out32(uint32_t addr, uint32_t value);

/** Wait `us` microseconds. Target: the SoC timer's WAIT register (HAL_TIMER_BASEADDR), so the
 *  time does not depend on the CPU's speed and the CPU sleeps meanwhile. Host: the bus hook's
 *  delay. */
void hal_delay_us(uint32_t us);

/** Core clock cycles (HAL_CPU_HZ) since start-up, wrapping at 2^32: measure elapsed time as
 *  the unsigned difference of two readings. Target: the timer's COUNT register. Host: the sum
 *  of the delays so far (the host's bus is infinitely fast: only delays take time), plus the
 *  ticks hook's count when one is installed. */
uint32_t hal_ticks(void);

/**
 * Timeouts. A wait for the hardware takes a deadline, polls, and gives up once
 * hal_expired(deadline):
 *
 *     uint32_t deadline = hal_deadline_us(T_US);
 *     for (polls = 0u; polls < HAL_POLL_CAP(T_US); polls++) {
 *         if (done()) return FW_OK;
 *         if (hal_expired(deadline)) break;
 *     }
 *     return FW_ERR_TIMEOUT;
 *
 * The deadline is the contract: the wait lasts T_US whatever the CPU's speed. The poll cap
 * is the backstop, for a clock that does not advance: a stuck timer, or the host build, whose
 * clock stands still between delays (hal_ticks). HAL_POLL_CAP(T_US) polls take at least
 * T_US on any core (a poll is at least HAL_MIN_POLL_CYCLES cycles), so on the target the cap
 * never ends a wait before its deadline.
 *
 * The comparison is of the unsigned difference, read as signed: it is right across the
 * counter's wrap for timeouts up to 2^31 ticks (42 s at 50 MHz) and for a deadline looked
 * at up to 2^31 ticks after it passed.
 */
#define HAL_TICKS_PER_US (HAL_CPU_HZ / 1000000u)
#define HAL_MIN_POLL_CYCLES 4u
#define HAL_POLL_CAP(us) ((us) * HAL_TICKS_PER_US / HAL_MIN_POLL_CYCLES)

/** The hal_ticks value `us` microseconds from now (us < 2^31 / HAL_TICKS_PER_US). */
static inline uint32_t hal_deadline_us(uint32_t us)
{
    return hal_ticks() + us * HAL_TICKS_PER_US;
}

/** 1 once hal_ticks has reached `deadline` (a hal_deadline_us value), 0 before. */
static inline int hal_expired(uint32_t deadline)
{
    return (uint32_t)(hal_ticks() - deadline) < 0x80000000u;
}

/** Poll the register at addr until a bit of mask is set, at most timeout_us (> 0, on
 *  hal_expired) and, as the backstop, HAL_POLL_CAP(timeout_us) reads. Returns FW_OK when the bit came,
 *  FW_ERR_TIMEOUT otherwise. */
int32_t hal_wait_set(uint32_t addr, uint32_t mask, uint32_t timeout_us);

/** Send bytes to the radio UART (target: the SoC's UART, hdl/uart.py, at HAL_UART_BASEADDR).
 *  Each byte waits at most HAL_UART_TX_TIMEOUT_US for room (hal_wait_set); returns FW_OK, or
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
/** The UART holds one byte besides the one it is sending, so room comes within one frame
 *  (10 bits): 1.04 ms at 9600 baud, the slowest rate in use (the XBee's factory rate,
 *  xbee.h), 87 us at 115200. The wait allows about three frames at 9600. */
#define HAL_UART_TX_TIMEOUT_US 3000u

/** The soft CPU's timer (hdl/cpu.py CPUTimer): COUNT reads the core clock cycles since
 *  reset (32 bits, wrapping); a write of n to WAIT completes n core cycles later, the CPU
 *  stalled meanwhile. */
#ifndef HAL_TIMER_BASEADDR
#define HAL_TIMER_BASEADDR 0xC0030000u
#endif
#define HAL_TIMER_COUNT_OFFSET 0x0u
#define HAL_TIMER_WAIT_OFFSET  0x4u

/** Register access for the generated stereo_regs.h map. */
#define STEREO_ReadReg(BaseAddress, RegOffset) Xil_In32((BaseAddress) + (RegOffset))
#define STEREO_WriteReg(BaseAddress, RegOffset, Data) \
    Xil_Out32((BaseAddress) + (RegOffset), (uint32_t)(Data))

#define ARRAY_SIZE(a) (sizeof(a) / sizeof((a)[0]))

#endif /* HAL_H */
