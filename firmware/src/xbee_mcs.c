/**
 * @file xbee_mcs.c
 * The MicroBlaze MCS I/O Module UART (Xilinx PG116) as the XBee's xbee_io_t: UART_RX at
 * 0x80000000, UART_TX at 0x80000004, UART_STATUS at 0x80000008 (bit 0 RX valid data, bit 3
 * TX used) and, with "programmable baud rate" enabled in the core, UART_BAUD at 0x8000004C
 * (ratio = clock / (16 x baud) - 1). Not yet checked on hardware.
 */
#include "xbee.h"
#include "hal.h"

#define MCS_UART_RX_OFFSET       0x80000000u
#define MCS_UART_STATUS_OFFSET   0x80000008u
#define MCS_UART_BAUD_OFFSET     0x8000004Cu
#define MCS_UART_RX_VALID_MASK   0x01u

static void mcs_write(void *ctx, const uint8_t *data, uint32_t len)
{
    (void)ctx;
    hal_uart_write(data, len);
}

static int mcs_read(void *ctx, uint8_t *byte)
{
    (void)ctx;
    if ((Xil_In32(MCS_UART_STATUS_OFFSET) & MCS_UART_RX_VALID_MASK) == 0u) {
        return 0;
    }
    *byte = (uint8_t)(Xil_In32(MCS_UART_RX_OFFSET) & 0xFFu);
    return 1;
}

static void mcs_set_baud(void *ctx, uint32_t baud)
{
    (void)ctx;
    Xil_Out32(MCS_UART_BAUD_OFFSET, HAL_CPU_HZ / (16u * baud) - 1u);
}

static void mcs_delay(void *ctx, uint32_t us)
{
    (void)ctx;
    hal_delay_us(us);
}

void xbee_mcs_io(xbee_io_t *io)
{
    io->write = mcs_write;
    io->read = mcs_read;
    io->set_baud = mcs_set_baud;
    io->delay_us = mcs_delay;
    io->ctx = NULL;
}
