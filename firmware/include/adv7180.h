/**
 * @file adv7180.h
 * Analog Devices ADV7180 NTSC/PAL video decoder over IIC.
 *
 * Register numbers follow the ADV7180 datasheet (Rev. J, "User Sub Map") and Linux
 * drivers/media/i2c/adv7180.c. Two decoders share the bus: ALSB low = 0x20, ALSB high = 0x21
 * (7-bit addresses; 0x40/0x42 as 8-bit write addresses).
 */
#ifndef ADV7180_H
#define ADV7180_H

#include <stdint.h>
#include "iic.h"

#define ADV7180_ADDR_ALSB_LOW   0x20u /**< 7-bit address with the ALSB pin low */
#define ADV7180_ADDR_ALSB_HIGH  0x21u /**< 7-bit address with the ALSB pin high */

#define ADV7180_REG_INPUT_CONTROL    0x00u /**< INSEL[3:0] input, VID_SEL[7:4] standard */
#define ADV7180_REG_OUTPUT_CONTROL   0x03u /**< output format and drive */
#define ADV7180_REG_EXT_OUTPUT_CTRL  0x04u /**< extended output control */
#define ADV7180_REG_AUTODETECT       0x07u /**< autodetect enable */
#define ADV7180_REG_ADI_CTRL         0x0Eu /**< ADI control: sub-map select */
#define ADV7180_REG_PWR_MAN          0x0Fu /**< power management; bit 7 = RES (soft reset) */
#define ADV7180_REG_STATUS1          0x10u /**< status 1 (read only) */
#define ADV7180_REG_IDENT            0x11u /**< chip identification (read only) */
#define ADV7180_REG_SHAP_FILTER_CTL1 0x17u /**< shaping filter control 1 */
#define ADV7180_REG_VS_FIELD_CTL1    0x31u /**< VS/FIELD control 1 */
#define ADV7180_REG_MANUAL_WIN_CTL1  0x3Du /**< manual window control */
#define ADV7180_REG_BLM_OPT          0x3Eu /**< BLM optimisation */
#define ADV7180_REG_BGB_OPT          0x3Fu /**< BGB optimisation */
#define ADV7180_REG_ADC_CFG          0x55u /**< ADC configuration (ADI required write) */
#define ADV7180_REG_NTSC_V_BIT_END   0xE6u /**< NTSC V bit end */

#define ADV7180_ID_7180              0x18u /**< IDENT value of an ADV7180 (Linux ADV7180_ID_7180) */
#define ADV7180_PWR_MAN_RES          0x80u /**< PWR_MAN: soft reset, self-clearing */
#define ADV7180_PWR_MAN_ON           0x04u /**< PWR_MAN: powered up */
#define ADV7180_STATUS1_IN_LOCK      0x01u /**< STATUS1: in lock (horizontal) */
#define ADV7180_STATUS1_LOST_LOCK    0x02u /**< STATUS1: lost lock since last read */
#define ADV7180_STATUS1_FSC_LOCK     0x04u /**< STATUS1: colour subcarrier locked */
#define ADV7180_STATUS1_AUTOD_MASK   0x70u /**< STATUS1: detected standard */
#define ADV7180_STATUS1_AUTOD_NTSC_M 0x00u /**< STATUS1.AUTOD: NTSC-M/J */

/** After a soft reset the decoder does not answer for a while (datasheet: wait 5 ms before
 *  further IIC writes; Linux waits 5..10 ms). The driver polls PWR_MAN every
 *  ADV7180_RESET_POLL_US until ADV7180_RESET_TIMEOUT_US (twice Linux's longest wait) have
 *  passed on the timer, and at most ADV7180_RESET_POLLS times: the backstop for a clock that
 *  does not advance, twice the polls the deadline allows (hal.h "Timeouts"). */
#define ADV7180_RESET_POLL_US    1000u
#define ADV7180_RESET_TIMEOUT_US 20000u
#define ADV7180_RESET_POLLS      (2u * ADV7180_RESET_TIMEOUT_US / ADV7180_RESET_POLL_US)

typedef struct {
    uint8_t reg; /**< register number */
    uint8_t val; /**< value */
} adv7180_reg_val_t;

/** The NTSC set-up table, in the order it is written (see adv7180.c for the sources). */
extern const adv7180_reg_val_t adv7180_ntsc_init[];
extern const uint32_t adv7180_ntsc_init_len;

typedef struct {
    iic_dev_t *iic;
    uint8_t addr7;
    uint8_t status1; /**< last STATUS1 read */
    int16_t failed_entry; /**< index of the table entry that failed, -1 if none */
} adv7180_t;

/** Bind a decoder to a bus and an address (0x20 or 0x21). */
fw_status_t adv7180_bind(adv7180_t *dec, iic_dev_t *iic, uint8_t addr7);
/** Read IDENT: FW_ERR_ID if it is not an ADV7180. */
fw_status_t adv7180_check_id(adv7180_t *dec);
/** Soft reset and bounded wait until the decoder answers again with RES cleared. */
fw_status_t adv7180_reset(adv7180_t *dec);
/** Full start-up: check ID, reset, check ID again, write adv7180_ntsc_init (stops at the
 *  first error, recording its index in failed_entry). */
fw_status_t adv7180_init(adv7180_t *dec);
/** Read STATUS1; *locked = 1 when IN_LOCK and FSC_LOCK are both set. */
fw_status_t adv7180_lock_status(adv7180_t *dec, uint8_t *locked);

#endif /* ADV7180_H */
