/**
 * @file iic.h
 * Polled IIC master driver for the AXI IIC-style controller (hdl/iic.py), dynamic mode.
 * Every wait is bounded by `timeout_polls` status-register reads and returns
 * FW_ERR_TIMEOUT when it runs out; after any error the controller is soft-reset so that the
 * next transfer starts clean.
 */
#ifndef IIC_H
#define IIC_H

#include <stdint.h>
#include "fw_status.h"

/** Default poll bound. One poll is an I/O-bus read plus loop overhead, about 10 cycles on
 *  an MCS at 50 MHz, so 20000 polls = about 4 ms: more than a whole 4-byte transfer at
 *  100 kHz (about 0.4 ms) with generous clock stretching. */
#define IIC_DEFAULT_TIMEOUT_POLLS 20000u

typedef struct {
    uint32_t base;           /**< controller base address */
    uint32_t timeout_polls;  /**< bound of every wait */
    uint32_t polls;          /**< polls used by the last call (for tests and tuning) */
    uint32_t errors;         /**< transfers that returned an error since iic_init */
} iic_dev_t;

/** Reset and enable the controller. timeout_polls 0 selects IIC_DEFAULT_TIMEOUT_POLLS. */
fw_status_t iic_init(iic_dev_t *dev, uint32_t base, uint32_t timeout_polls);

/** Write one 8-bit register: START, addr7+W, reg, val, STOP. */
fw_status_t iic_write_reg8(iic_dev_t *dev, uint8_t addr7, uint8_t reg, uint8_t val);

/** Read one 8-bit register: START, addr7+W, reg, repeated START, addr7+R, 1 byte, STOP. */
fw_status_t iic_read_reg8(iic_dev_t *dev, uint8_t addr7, uint8_t reg, uint8_t *val);

/** Read `len` (1..16) consecutive registers starting at `reg` (repeated start). */
fw_status_t iic_read_regs(iic_dev_t *dev, uint8_t addr7, uint8_t reg, uint8_t *buf,
                          uint32_t len);

#endif /* IIC_H */
