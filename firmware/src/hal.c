/**
 * @file hal.c
 * Xil_In32/Xil_Out32 and friends: volatile accesses on the target, a bus hook on the host.
 */
#include "hal.h"
#include "fw_status.h"

#ifdef HAL_TARGET

uint32_t Xil_In32(uint32_t addr)
{
    return *(volatile uint32_t *)(uintptr_t)addr;
}

void Xil_Out32(uint32_t addr, uint32_t value)
{
    *(volatile uint32_t *)(uintptr_t)addr = value;
}

/* the longest single WAIT, in microseconds: its cycle count fits 32 bits at any HAL_CPU_HZ
 * up to 4 GHz */
#define HAL_WAIT_CHUNK_US 1000000u

void hal_delay_us(uint32_t us)
{
    while (us > HAL_WAIT_CHUNK_US) {
        Xil_Out32(HAL_TIMER_BASEADDR + HAL_TIMER_WAIT_OFFSET,
                  HAL_WAIT_CHUNK_US * (HAL_CPU_HZ / 1000000u));
        us -= HAL_WAIT_CHUNK_US;
    }
    Xil_Out32(HAL_TIMER_BASEADDR + HAL_TIMER_WAIT_OFFSET, us * (HAL_CPU_HZ / 1000000u));
}

uint32_t hal_ticks(void)
{
    return Xil_In32(HAL_TIMER_BASEADDR + HAL_TIMER_COUNT_OFFSET);
}

int32_t hal_uart_write(const uint8_t *data, uint32_t len)
{
    uint32_t i;
    for (i = 0; i < len; i++) {
        if (hal_wait_set(HAL_UART_BASEADDR + HAL_UART_STATUS_OFFSET, HAL_UART_STATUS_TX_READY,
                         HAL_UART_TX_TIMEOUT_US) != FW_OK) {
            return FW_ERR_TIMEOUT;
        }
        Xil_Out32(HAL_UART_BASEADDR + HAL_UART_DATA_OFFSET, data[i]);
    }
    return FW_OK;
}

int32_t hal_uart_put(uint8_t byte)
{
    if ((Xil_In32(HAL_UART_BASEADDR + HAL_UART_STATUS_OFFSET) & HAL_UART_STATUS_TX_READY) == 0u) {
        return 0;
    }
    Xil_Out32(HAL_UART_BASEADDR + HAL_UART_DATA_OFFSET, byte);
    return 1;
}

#else /* host build */

static hal_read32_fn hook_rd;
static hal_write32_fn hook_wr;
static hal_delay_us_fn hook_delay;
static hal_uart_write_fn hook_uart;
static void *hook_ctx;

void hal_set_bus_hook(hal_read32_fn rd, hal_write32_fn wr, hal_delay_us_fn delay,
                      hal_uart_write_fn uart, void *ctx)
{
    hook_rd = rd;
    hook_wr = wr;
    hook_delay = delay;
    hook_uart = uart;
    hook_ctx = ctx;
}

uint32_t Xil_In32(uint32_t addr)
{
    return hook_rd != NULL ? hook_rd(hook_ctx, addr) : 0xFFFFFFFFu;
}

void Xil_Out32(uint32_t addr, uint32_t value)
{
    if (hook_wr != NULL) {
        hook_wr(hook_ctx, addr, value);
    }
}

static uint32_t host_ticks;
static hal_ticks_fn ticks_hook;
static void *ticks_ctx;

void hal_set_ticks_hook(hal_ticks_fn ticks, void *ctx)
{
    ticks_hook = ticks;
    ticks_ctx = ctx;
}

void hal_delay_us(uint32_t us)
{
    host_ticks += us * HAL_TICKS_PER_US;
    if (hook_delay != NULL) {
        hook_delay(hook_ctx, us);
    }
}

uint32_t hal_ticks(void)
{
    return host_ticks + (ticks_hook != NULL ? ticks_hook(ticks_ctx) : 0u);
}

int32_t hal_uart_write(const uint8_t *data, uint32_t len)
{
    if (hook_uart != NULL) {
        hook_uart(hook_ctx, data, len);
    }
    return FW_OK;
}

int32_t hal_uart_put(uint8_t byte)
{
    if (hook_uart != NULL) {
        hook_uart(hook_ctx, &byte, 1u);
    }
    return 1;
}

#endif

int32_t hal_wait_set(uint32_t addr, uint32_t mask, uint32_t timeout_us)
{
    uint32_t deadline = hal_deadline_us(timeout_us);
    uint32_t polls;
    for (polls = 0u; polls < HAL_POLL_CAP(timeout_us); polls++) {
        if ((Xil_In32(addr) & mask) != 0u) {
            return FW_OK;
        }
        if (hal_expired(deadline)) {
            break;
        }
    }
    return FW_ERR_TIMEOUT;
}

const char *fw_status_str(fw_status_t st)
{
    switch (st) {
    case FW_OK: return "OK";
    case FW_ERR_NACK: return "NACK";
    case FW_ERR_TIMEOUT: return "TIMEOUT";
    case FW_ERR_BUS_BUSY: return "BUS_BUSY";
    case FW_ERR_ARBITRATION: return "ARBITRATION";
    case FW_ERR_PARAM: return "PARAM";
    case FW_ERR_ID: return "ID";
    case FW_ERR_NO_LOCK: return "NO_LOCK";
    case FW_ERR_RX: return "RX";
    case FW_ERR_RECT_ABSENT: return "RECT_ABSENT";
    case FW_ERR_RECT_WARP: return "RECT_WARP";
    case FW_ERR_RECT_MAP: return "RECT_MAP";
    default: return "UNKNOWN";
    }
}
