/**
 * @file xiic_l.h
 * Register layout of the IIC controller, the subset of the Xilinx AXI IIC Bus Interface
 * (PG090, "Register Space"; names as in Xilinx embeddedsw drivers/iic/src/xiic_l.h) that
 * hdl/iic.py implements and iic.c uses. Offsets are bytes from the controller's base address.
 * tests/test_iic.py checks these values against hdl/iic.py.
 */
#ifndef XIIC_L_H
#define XIIC_L_H

#include "hal.h"

/** @name Register offsets
 * @{ */
#define XIIC_IISR_OFFSET      0x20u  /**< Interrupt Status Register (toggle on write) */
#define XIIC_RESETR_OFFSET    0x40u  /**< Soft Reset Register (write XIIC_RESET_MASK) */
#define XIIC_CR_REG_OFFSET    0x100u /**< Control Register */
#define XIIC_SR_REG_OFFSET    0x104u /**< Status Register (read only) */
#define XIIC_DTR_REG_OFFSET   0x108u /**< Data Tx Register: TX FIFO */
#define XIIC_DRR_REG_OFFSET   0x10Cu /**< Data Rx Register: RX FIFO */
#define XIIC_TFO_REG_OFFSET   0x114u /**< Tx FIFO Occupancy (entries - 1) */
#define XIIC_RFO_REG_OFFSET   0x118u /**< Rx FIFO Occupancy (entries - 1) */
#define XIIC_RFD_REG_OFFSET   0x120u /**< Rx FIFO Programmable Depth (RX_FIFO_PIRQ) */
/** @} */

/** Soft reset value: any other value written to RESETR is ignored. */
#define XIIC_RESET_MASK       0x0000000Au

/** @name Control Register masks
 * @{ */
#define XIIC_CR_ENABLE_DEVICE_MASK      0x01u /**< Device enable = 1 */
#define XIIC_CR_TX_FIFO_RESET_MASK      0x02u /**< Transmit FIFO reset = 1 */
#define XIIC_CR_MSMS_MASK               0x04u /**< Master starts Txing = 1 (not used in dynamic mode) */
#define XIIC_CR_DIR_IS_TX_MASK          0x08u /**< Dir of Tx, Txing = 1 (not used in dynamic mode) */
#define XIIC_CR_NO_ACK_MASK             0x10u /**< Tx Ack, no ack = 1 (not used in dynamic mode) */
#define XIIC_CR_REPEATED_START_MASK     0x20u /**< Repeated start = 1 (not used in dynamic mode) */
/** @} */

/** @name Status Register masks
 * @{ */
#define XIIC_SR_BUS_BUSY_MASK           0x04u /**< 1 = bus is busy (START seen, no STOP yet) */
#define XIIC_SR_MSTR_RDING_SLAVE_MASK   0x08u /**< 1 = master reading from slave */
#define XIIC_SR_TX_FIFO_FULL_MASK       0x10u /**< 1 = Tx FIFO full */
#define XIIC_SR_RX_FIFO_FULL_MASK       0x20u /**< 1 = Rx FIFO full */
#define XIIC_SR_RX_FIFO_EMPTY_MASK      0x40u /**< 1 = Rx FIFO empty */
#define XIIC_SR_TX_FIFO_EMPTY_MASK      0x80u /**< 1 = Tx FIFO empty */
/** @} */

/** @name Interrupt Status Register masks
 * @{ */
#define XIIC_INTR_ARB_LOST_MASK         0x01u /**< 1 = arbitration lost */
#define XIIC_INTR_TX_ERROR_MASK         0x02u /**< 1 = Tx error (no acknowledge) */
#define XIIC_INTR_TX_EMPTY_MASK         0x04u /**< 1 = Tx FIFO empty */
#define XIIC_INTR_RX_FULL_MASK          0x08u /**< 1 = Rx FIFO occupancy = RFD + 1 */
#define XIIC_INTR_BNB_MASK              0x10u /**< 1 = bus not busy */
/** @} */

/** @name Dynamic controller logic: flags in the upper bits of a TX FIFO word
 * @{ */
#define XIIC_TX_DYN_START_MASK          0x0100u /**< 1 = send a (repeated) START before this byte */
#define XIIC_TX_DYN_STOP_MASK           0x0200u /**< 1 = send a STOP after this byte */
/** @} */

#define XIIC_READ_OPERATION  1u /**< LSB of the address byte for a read */
#define XIIC_WRITE_OPERATION 0u /**< LSB of the address byte for a write */
#define XIIC_TX_FIFO_DEPTH   16u /**< entries in each FIFO */

/** Read a controller register. */
#define XIic_ReadReg(BaseAddress, RegOffset) Xil_In32((BaseAddress) + (RegOffset))
/** Write a controller register. */
#define XIic_WriteReg(BaseAddress, RegOffset, RegisterValue) \
    Xil_Out32((BaseAddress) + (RegOffset), (uint32_t)(RegisterValue))

#endif /* XIIC_L_H */
