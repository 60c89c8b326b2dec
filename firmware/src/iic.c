/**
 * @file iic.c
 * Polled IIC master over the AXI IIC register layout (PG090 "Dynamic Controller Logic
 * Flow"): a START flag on the address word, a STOP flag on the last data word, and for a
 * read, the byte count written after the address. Unlike Xilinx's XIic_Send/XIic_Recv, every
 * wait here ends at a deadline (iic.h) and returns a status.
 */
#include "iic.h"
#include "hal.h"
#include "xiic_l.h"

static void iic_clear_isr(uint32_t base)
{
    /* IISR is toggle-on-write: writing back the bits that are set clears them */
    XIic_WriteReg(base, XIIC_IISR_OFFSET, XIic_ReadReg(base, XIIC_IISR_OFFSET));
}

static void iic_reinit(uint32_t base)
{
    XIic_WriteReg(base, XIIC_RESETR_OFFSET, XIIC_RESET_MASK);
    XIic_WriteReg(base, XIIC_RFD_REG_OFFSET, XIIC_TX_FIFO_DEPTH - 1u);
    XIic_WriteReg(base, XIIC_CR_REG_OFFSET, XIIC_CR_ENABLE_DEVICE_MASK | XIIC_CR_TX_FIFO_RESET_MASK);
    XIic_WriteReg(base, XIIC_CR_REG_OFFSET, XIIC_CR_ENABLE_DEVICE_MASK);
    iic_clear_isr(base);
}

fw_status_t iic_init(iic_dev_t *dev, uint32_t base, uint32_t timeout_polls)
{
    if (dev == NULL) {
        return FW_ERR_PARAM;
    }
    dev->base = base;
    dev->timeout_polls = timeout_polls != 0u ? timeout_polls : IIC_DEFAULT_TIMEOUT_POLLS;
    dev->polls = 0u;
    dev->errors = 0u;
    iic_reinit(base);
    return FW_OK;
}

/** Check the interrupt status for the two errors a transfer can end with. */
static fw_status_t iic_isr_error(uint32_t isr)
{
    if ((isr & XIIC_INTR_ARB_LOST_MASK) != 0u) {
        return FW_ERR_ARBITRATION;
    }
    if ((isr & XIIC_INTR_TX_ERROR_MASK) != 0u) {
        return FW_ERR_NACK;
    }
    return FW_OK;
}

/* what iic_wait waits for */
#define IIC_WAIT_BUS_FREE 0u  /* no transfer of ours or anybody else's in progress */
#define IIC_WAIT_DONE     1u  /* the queued transfer ended: TX FIFO empty and the STOP sent */
#define IIC_WAIT_RX       2u  /* one received byte, into *byte */

/** One wait: until `what` (or an error, but for IIC_WAIT_BUS_FREE), at most IIC_TIMEOUT_US,
 *  and dev->timeout_polls polls as the backstop. FW_ERR_BUS_BUSY or FW_ERR_TIMEOUT when it
 *  runs out. */
static fw_status_t iic_wait(iic_dev_t *dev, uint32_t what, uint8_t *byte)
{
    uint32_t deadline = hal_deadline_us(IIC_TIMEOUT_US);
    uint32_t n;
    for (n = 0u; n < dev->timeout_polls; n++) {
        uint32_t sr;
        fw_status_t st;
        dev->polls++;
        if (what == IIC_WAIT_RX) {
            if ((XIic_ReadReg(dev->base, XIIC_SR_REG_OFFSET) & XIIC_SR_RX_FIFO_EMPTY_MASK) == 0u) {
                *byte = (uint8_t)(XIic_ReadReg(dev->base, XIIC_DRR_REG_OFFSET) & 0xFFu);
                return FW_OK;
            }
        }
        if (what != IIC_WAIT_BUS_FREE) {
            st = iic_isr_error(XIic_ReadReg(dev->base, XIIC_IISR_OFFSET));
            if (st != FW_OK) {
                return st;
            }
        }
        if (what != IIC_WAIT_RX) {
            sr = XIic_ReadReg(dev->base, XIIC_SR_REG_OFFSET);
            if ((sr & XIIC_SR_BUS_BUSY_MASK) == 0u &&
                (what == IIC_WAIT_BUS_FREE || (sr & XIIC_SR_TX_FIFO_EMPTY_MASK) != 0u)) {
                return FW_OK;
            }
        }
        if (hal_expired(deadline)) {
            break;
        }
    }
    return what == IIC_WAIT_BUS_FREE ? FW_ERR_BUS_BUSY : FW_ERR_TIMEOUT;
}

/** End of every transfer: count errors, leave the controller clean. */
static fw_status_t iic_finish(iic_dev_t *dev, fw_status_t st)
{
    if (st != FW_OK) {
        dev->errors++;
        if (st == FW_ERR_NACK || st == FW_ERR_ARBITRATION) {
            /* the controller sends STOP itself after a NACK: give it the time to */
            (void)iic_wait(dev, IIC_WAIT_BUS_FREE, NULL);
        }
        iic_reinit(dev->base);
    }
    return st;
}

static fw_status_t iic_start(iic_dev_t *dev)
{
    fw_status_t st;
    dev->polls = 0u;
    st = iic_wait(dev, IIC_WAIT_BUS_FREE, NULL);
    if (st != FW_OK) {
        return st;
    }
    iic_clear_isr(dev->base);
    return FW_OK;
}

fw_status_t iic_write_reg8(iic_dev_t *dev, uint8_t addr7, uint8_t reg, uint8_t val)
{
    fw_status_t st;
    if (dev == NULL || addr7 > 0x7Fu) {
        return FW_ERR_PARAM;
    }
    st = iic_start(dev);
    if (st != FW_OK) {
        return iic_finish(dev, st);
    }
    XIic_WriteReg(dev->base, XIIC_DTR_REG_OFFSET,
                  XIIC_TX_DYN_START_MASK | ((uint32_t)addr7 << 1) | XIIC_WRITE_OPERATION);
    XIic_WriteReg(dev->base, XIIC_DTR_REG_OFFSET, reg);
    XIic_WriteReg(dev->base, XIIC_DTR_REG_OFFSET, XIIC_TX_DYN_STOP_MASK | val);
    return iic_finish(dev, iic_wait(dev, IIC_WAIT_DONE, NULL));
}

fw_status_t iic_read_regs(iic_dev_t *dev, uint8_t addr7, uint8_t reg, uint8_t *buf,
                          uint32_t len)
{
    fw_status_t st;
    uint32_t i;
    if (dev == NULL || buf == NULL || addr7 > 0x7Fu || len == 0u || len > XIIC_TX_FIFO_DEPTH) {
        return FW_ERR_PARAM;
    }
    st = iic_start(dev);
    if (st != FW_OK) {
        return iic_finish(dev, st);
    }
    XIic_WriteReg(dev->base, XIIC_DTR_REG_OFFSET,
                  XIIC_TX_DYN_START_MASK | ((uint32_t)addr7 << 1) | XIIC_WRITE_OPERATION);
    XIic_WriteReg(dev->base, XIIC_DTR_REG_OFFSET, reg);
    XIic_WriteReg(dev->base, XIIC_DTR_REG_OFFSET,
                  XIIC_TX_DYN_START_MASK | ((uint32_t)addr7 << 1) | XIIC_READ_OPERATION);
    XIic_WriteReg(dev->base, XIIC_DTR_REG_OFFSET, XIIC_TX_DYN_STOP_MASK | len);
    for (i = 0u; i < len; i++) {
        st = iic_wait(dev, IIC_WAIT_RX, &buf[i]);
        if (st != FW_OK) {
            return iic_finish(dev, st);
        }
    }
    return iic_finish(dev, iic_wait(dev, IIC_WAIT_DONE, NULL));
}

fw_status_t iic_read_reg8(iic_dev_t *dev, uint8_t addr7, uint8_t reg, uint8_t *val)
{
    return iic_read_regs(dev, addr7, reg, val, 1u);
}
