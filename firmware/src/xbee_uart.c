/**
 * @file xbee_uart.c
 * The SoC's radio UART (hdl/uart.py, at HAL_UART_BASEADDR) as the XBee's xbee_io_t: DATA
 * (0x0: write sends a byte through hal_uart_write; a read returns the received byte with
 * HAL_UART_DATA_RX_VALID set, or 0), BAUD (0x8: core cycles per bit, rounded to the nearest,
 * for the factory 9600 baud and the link's 115200).
 */
#include "xbee.h"
#include "hal.h"

static void uart_write(void *ctx, const uint8_t *data, uint32_t len)
{
    (void)ctx;
    (void)hal_uart_write(data, len);
}

static int uart_read(void *ctx, uint8_t *byte)
{
    uint32_t v;
    (void)ctx;
    v = Xil_In32(HAL_UART_BASEADDR + HAL_UART_DATA_OFFSET);
    if ((v & HAL_UART_DATA_RX_VALID) == 0u) {
        return 0;
    }
    *byte = (uint8_t)(v & 0xFFu);
    return 1;
}

static void uart_set_baud(void *ctx, uint32_t baud)
{
    (void)ctx;
    if (baud != 0u) {
        Xil_Out32(HAL_UART_BASEADDR + HAL_UART_BAUD_OFFSET, (HAL_CPU_HZ + baud / 2u) / baud);
    }
}

static void uart_delay(void *ctx, uint32_t us)
{
    (void)ctx;
    hal_delay_us(us);
}

void xbee_uart_io(xbee_io_t *io)
{
    io->write = uart_write;
    io->read = uart_read;
    io->set_baud = uart_set_baud;
    io->delay_us = uart_delay;
    io->ctx = NULL;
}
