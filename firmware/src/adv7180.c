/**
 * @file adv7180.c
 * ADV7180 set-up: chip ID, soft reset, NTSC init table, lock status.
 */
#include "adv7180.h"
#include "hal.h"

/*
 * NTSC-M on CVBS input AIN1, 8-bit ITU-R BT.656 4:2:2 output (embedded SAV/EAV codes).
 * Sources:
 *   [DS]    ADV7180 datasheet Rev. J, register map (User Sub Map) and reset values;
 *   [LINUX] Linux drivers/media/i2c/adv7180.c (adv7180_init, adv7180_set_std, set_power);
 *   [ADI]   ADI's recommended ADV7180 start-up script for CVBS ("ADI required writes").
 * Entries are written in order; the decoder's register file afterwards holds the last value
 * written to each register.
 */
const adv7180_reg_val_t adv7180_ntsc_init[] = {
    { ADV7180_REG_PWR_MAN, ADV7180_PWR_MAN_ON },   /* power up, PDBP=1 [LINUX set_power] */
    { ADV7180_REG_INPUT_CONTROL, 0x50u },          /* INSEL=0 CVBS on AIN1, VID_SEL=0101 forced NTSC-M
                                                      [LINUX ADV7180_INPUT_CONTROL_NTSC_M] */
    { ADV7180_REG_OUTPUT_CONTROL, 0x0Cu },         /* 8-bit BT.656 on P15..P8, outputs on [DS reset value] */
    { ADV7180_REG_EXT_OUTPUT_CTRL, 0xC5u },        /* BT.656-4 timing, blank C during VBI
                                                      [LINUX ADV7180_EXTENDED_OUTPUT_CONTROL_NTSCDIS] */
    { ADV7180_REG_AUTODETECT, 0x7Fu },             /* autodetect set (unused while forced) [LINUX default] */
    { ADV7180_REG_SHAP_FILTER_CTL1, 0x41u },       /* select SH1 luma shaping filter [ADI] */
    { ADV7180_REG_VS_FIELD_CTL1, 0x02u },          /* NEWAVMODE off: standard SAV/EAV [ADI] */
    { ADV7180_REG_MANUAL_WIN_CTL1, 0xA2u },        /* manual window, colour kill threshold 2 [ADI] */
    { ADV7180_REG_BLM_OPT, 0x6Au },                /* BLM optimisation [ADI] */
    { ADV7180_REG_BGB_OPT, 0xA0u },                /* BGB optimisation [ADI] */
    { ADV7180_REG_ADI_CTRL, 0x80u },               /* enter the ADI hidden map [ADI required write] */
    { ADV7180_REG_ADC_CFG, 0x81u },                /* ADC configuration [ADI required write] */
    { ADV7180_REG_ADI_CTRL, 0x00u },               /* back to the user sub map [ADI] */
    { ADV7180_REG_NTSC_V_BIT_END, 0x4Fu },         /* manual NVEND: V bit end for NTSC
                                                      [LINUX ADV7180_NTSC_V_BIT_END_MANUAL_NVEND] */
};
const uint32_t adv7180_ntsc_init_len = ARRAY_SIZE(adv7180_ntsc_init);

fw_status_t adv7180_bind(adv7180_t *dec, iic_dev_t *iic, uint8_t addr7)
{
    if (dec == NULL || iic == NULL ||
        (addr7 != ADV7180_ADDR_ALSB_LOW && addr7 != ADV7180_ADDR_ALSB_HIGH)) {
        return FW_ERR_PARAM;
    }
    dec->iic = iic;
    dec->addr7 = addr7;
    dec->status1 = 0u;
    dec->failed_entry = -1;
    return FW_OK;
}

fw_status_t adv7180_check_id(adv7180_t *dec)
{
    uint8_t id = 0u;
    fw_status_t st = iic_read_reg8(dec->iic, dec->addr7, ADV7180_REG_IDENT, &id);
    if (st != FW_OK) {
        return st;
    }
    return id == ADV7180_ID_7180 ? FW_OK : FW_ERR_ID;
}

fw_status_t adv7180_reset(adv7180_t *dec)
{
    uint32_t i;
    uint32_t deadline;
    fw_status_t st = iic_write_reg8(dec->iic, dec->addr7, ADV7180_REG_PWR_MAN,
                                    ADV7180_PWR_MAN_RES);
    if (st != FW_OK) {
        return st;
    }
    deadline = hal_deadline_us(ADV7180_RESET_TIMEOUT_US);
    for (i = 0u; i < ADV7180_RESET_POLLS; i++) {
        uint8_t pwr = 0xFFu;
        hal_delay_us(ADV7180_RESET_POLL_US);
        st = iic_read_reg8(dec->iic, dec->addr7, ADV7180_REG_PWR_MAN, &pwr);
        if (st == FW_OK && (pwr & ADV7180_PWR_MAN_RES) == 0u) {
            return FW_OK;
        }
        if (st != FW_OK && st != FW_ERR_NACK) {
            return st; /* a timeout or a lost arbitration is not "still resetting" */
        }
        if (hal_expired(deadline)) {
            break;
        }
    }
    return FW_ERR_TIMEOUT;
}

fw_status_t adv7180_init(adv7180_t *dec)
{
    uint32_t i;
    fw_status_t st;
    if (dec == NULL || dec->iic == NULL) {
        return FW_ERR_PARAM;
    }
    dec->failed_entry = -1;
    st = adv7180_check_id(dec);
    if (st != FW_OK) {
        return st;
    }
    st = adv7180_reset(dec);
    if (st != FW_OK) {
        return st;
    }
    for (i = 0u; i < ARRAY_SIZE(adv7180_ntsc_init); i++) {
        st = iic_write_reg8(dec->iic, dec->addr7, adv7180_ntsc_init[i].reg,
                            adv7180_ntsc_init[i].val);
        if (st != FW_OK) {
            dec->failed_entry = (int16_t)i;
            return st;
        }
    }
    return FW_OK;
}

fw_status_t adv7180_lock_status(adv7180_t *dec, uint8_t *locked)
{
    uint8_t s = 0u;
    fw_status_t st;
    if (dec == NULL || locked == NULL) {
        return FW_ERR_PARAM;
    }
    st = iic_read_reg8(dec->iic, dec->addr7, ADV7180_REG_STATUS1, &s);
    if (st != FW_OK) {
        return st;
    }
    dec->status1 = s;
    *locked = (uint8_t)((s & (ADV7180_STATUS1_IN_LOCK | ADV7180_STATUS1_FSC_LOCK)) ==
              (ADV7180_STATUS1_IN_LOCK | ADV7180_STATUS1_FSC_LOCK));
    return FW_OK;
}
