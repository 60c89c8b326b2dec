/**
 * @file xbee.h
 * Start-up configuration of the robot's XBee 802.15.4 module with AT commands (Digi XBee
 * 802.15.4 product manual 90000982: "Command mode", "API operation", AT commands AP, BD, MY,
 * DL, ID, WR, CN).
 *
 * The module leaves the factory in transparent mode (AP = 0) at 9600 baud; the radio link
 * budget (radio.h) assumes API mode 2 (escaped) at 115200 baud. xbee_configure():
 *
 *  1. at 115200 baud, asks in API mode for AP and MY (an AT Command frame, 0x08, each):
 *     a module already configured answers both and nothing is written;
 *  2. otherwise, at 9600 and then at 115200 baud, enters command mode (guard time of
 *     silence, "+++", guard time, "OK\r"), sends ATAP2, ATBD7, ATMY, ATDL, ATID, ATWR, ATCN
 *     and checks that each answers "OK\r";
 *  3. switches its UART to 115200 baud and checks again in API mode that AP = 2 and MY is
 *     the configured address.
 *
 * Every response is checked and every wait is bounded: XBEE_RESPONSE_US per byte of a
 * response, on the timer (hal_deadline_us, with XBEE_RESPONSE_POLLS polls as the backstop,
 * hal.h "Timeouts"), and the guard times around "+++" (delays). With no module at all it
 * returns FW_ERR_TIMEOUT after about 2 x (2 x XBEE_GUARD_US + XBEE_RESPONSE_US) +
 * 3 x XBEE_RESPONSE_US. A module that answers something else ("ERROR", a wrong value, a bad
 * frame) gives FW_ERR_RX.
 */
#ifndef XBEE_H
#define XBEE_H

#include <stdint.h>
#include "fw_status.h"

#define XBEE_FACTORY_BAUD   9600u
#define XBEE_LINK_BAUD      115200u
#define XBEE_BD_LINK        7u         /**< ATBD value for 115200 baud */
/* A build may shorten the two waits (-D, firmware/Makefile FIRMWARE_DEFS), as the simulation's
 * test of a missing module does: with the module's factory GT they take seconds to simulate. */
#ifndef XBEE_GUARD_US
#define XBEE_GUARD_US       1100000u   /**< GT (1 s factory default) plus 10 % */
#endif
#ifndef XBEE_RESPONSE_US
/** Longest wait for a byte of a response: the first byte covers the module's work on the
 *  command (WR, which writes its flash, takes longest), the next ones follow within a frame
 *  (1.04 ms at 9600 baud). */
#define XBEE_RESPONSE_US    200000u
#endif
#define XBEE_POLL_US        20u        /**< delay between two polls of an empty UART: below one
                                             byte time at 115200 baud (87 us), as the UART
                                             holds one received byte */
/** Poll cap of one response wait: twice the polls XBEE_RESPONSE_US allows, as each poll
 *  waits XBEE_POLL_US. */
#define XBEE_RESPONSE_POLLS (2u * XBEE_RESPONSE_US / XBEE_POLL_US)
#define XBEE_AT_FRAME_ID    0x52u      /**< frame id of the API-mode AT queries */
#define XBEE_ROBOT_ADDR     0x0002u    /**< MY of the robot's module */
#define XBEE_STATION_ADDR   0x0001u    /**< DL: the base station (app.h APP_RADIO_DEST) */
#define XBEE_PAN_ID         0x3332u    /**< ID: the modules' factory PAN */

/** The UART the module hangs on. read returns 1 and a byte, or 0 if none is waiting. */
typedef struct {
    void (*write)(void *ctx, const uint8_t *data, uint32_t len);
    int (*read)(void *ctx, uint8_t *byte);
    void (*set_baud)(void *ctx, uint32_t baud);
    void (*delay_us)(void *ctx, uint32_t us);
    void *ctx;
} xbee_io_t;

typedef struct {
    uint16_t my_addr;     /**< MY: the robot's 16-bit address */
    uint16_t dest_addr;   /**< DL: the base station's 16-bit address */
    uint16_t pan_id;      /**< ID: PAN identifier */
} xbee_config_t;

typedef struct {
    uint8_t was_configured;  /**< 1: the module already answered in API mode 2 at 115200 */
    uint32_t factory_baud;   /**< baud command mode answered at (0 if not entered) */
    uint8_t commands_ok;     /**< AT commands answered "OK" */
} xbee_result_t;

/** Configure the module (see the file comment). result may be NULL. */
fw_status_t xbee_configure(const xbee_io_t *io, const xbee_config_t *cfg,
                           xbee_result_t *result);

/**
 * Retry without blocking: whether a module that did not answer at start-up answers now. The
 * caller sends the bytes of xbee_probe_query (the API-mode "AP" query, XBEE_AT_FRAME_ID) at
 * 115200 baud and feeds every byte it receives to xbee_probe_feed, which returns 1 once the
 * module's answer "AP = 2" has come: the module is in API mode 2 and takes the reports. It
 * waits for nothing, so a frame loop can send a query every few seconds and go on. A module
 * still in its factory configuration (transparent mode) does not answer: only xbee_configure,
 * whose guard times block for seconds, configures it.
 */
typedef struct {
    uint8_t matched;      /**< bytes of the expected answer received so far */
} xbee_probe_t;

/** The query's frame (XBEE_PROBE_QUERY_LEN bytes) in buf. */
#define XBEE_PROBE_QUERY_LEN 8u
void xbee_probe_query(uint8_t buf[XBEE_PROBE_QUERY_LEN]);

/** One received byte; 1 when it completes the answer "AP = 2" (then matching starts over). */
int xbee_probe_feed(xbee_probe_t *probe, uint8_t byte);

/** The SoC's radio UART (hdl/uart.py) as an xbee_io_t (xbee_uart.c, target builds). */
void xbee_uart_io(xbee_io_t *io);

#endif /* XBEE_H */
