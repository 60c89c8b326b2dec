/**
 * @file iic.h
 * Polled IIC master driver for the AXI IIC-style controller (hdl/iic.py), dynamic mode.
 * Every wait (the bus free, a received byte, the end of a transfer) ends at a deadline of
 * IIC_TIMEOUT_US on the timer (hal_deadline_us) and returns FW_ERR_BUS_BUSY or
 * FW_ERR_TIMEOUT; `timeout_polls` status polls end it too, a backstop for a clock that does
 * not advance (hal.h "Timeouts"). After any error the controller is soft-reset so that the
 * next transfer starts clean.
 */
#ifndef IIC_H
#define IIC_H

#include <stdint.h>
#include "fw_status.h"
#include "hal.h"

/** Deadline of one wait. The longest of this driver's waits is for the first byte of a
 *  read: START, address, register, repeated START, address and the byte, five bytes of 9
 *  SCL clocks, 0.45 ms at 100 kHz (hdl/iic.py's rate at 50 MHz; 0.11 ms at 400 kHz). 2 ms
 *  leaves four times that for a device stretching SCL. */
#ifndef IIC_TIMEOUT_US
#define IIC_TIMEOUT_US 2000u
#endif

/** Default poll cap: never reached before IIC_TIMEOUT_US on a running timer (hal.h
 *  HAL_POLL_CAP). */
#define IIC_DEFAULT_TIMEOUT_POLLS HAL_POLL_CAP(IIC_TIMEOUT_US)

typedef struct {
    uint32_t base;           /**< controller base address */
    uint32_t timeout_polls;  /**< poll cap of every wait (the backstop to IIC_TIMEOUT_US) */
    uint32_t polls;          /**< polls used by the last call (for tests and tuning) */
    uint32_t errors;         /**< transfers that returned an error since iic_init */
} iic_dev_t;

/** Reset and enable the controller. timeout_polls 0 selects IIC_DEFAULT_TIMEOUT_POLLS; a
 *  smaller cap ends a wait before its deadline when the polls are fast (the co-simulation's
 *  host build, whose clock stands still while it polls, uses one). */
fw_status_t iic_init(iic_dev_t *dev, uint32_t base, uint32_t timeout_polls);

/** Write one 8-bit register: START, addr7+W, reg, val, STOP. */
fw_status_t iic_write_reg8(iic_dev_t *dev, uint8_t addr7, uint8_t reg, uint8_t val);

/** Read one 8-bit register: START, addr7+W, reg, repeated START, addr7+R, 1 byte, STOP. */
fw_status_t iic_read_reg8(iic_dev_t *dev, uint8_t addr7, uint8_t reg, uint8_t *val);

/** Read `len` (1..16) consecutive registers starting at `reg` (repeated start). */
fw_status_t iic_read_regs(iic_dev_t *dev, uint8_t addr7, uint8_t reg, uint8_t *buf,
                          uint32_t len);

#endif /* IIC_H */
