/**
 * @file bands_hw.c
 * Per-band summary unit reader (bands_hw.h).
 */
#include "bands_hw.h"
#include "hal.h"

fw_status_t bands_hw_init(bands_hw_t *hw, uint32_t base, uint16_t width, uint8_t n_bands)
{
    uint32_t cfg;
    if (hw == NULL || n_bands == 0u || n_bands > RADIO_MAX_BANDS || width < n_bands ||
        width > BANDS_HW_MAX_WIDTH) {
        return FW_ERR_PARAM;
    }
    cfg = (uint32_t)width | ((uint32_t)n_bands << BANDS_HW_CFG_N_BANDS_SHIFT);
    Xil_Out32(base + BANDS_HW_CFG_OFFSET, cfg);
    if (Xil_In32(base + BANDS_HW_CFG_OFFSET) != cfg) {
        return FW_ERR_ID;
    }
    hw->base = base;
    hw->width = width;
    hw->n_bands = n_bands;
    hw->seen = (uint16_t)(Xil_In32(base + BANDS_HW_STATUS_OFFSET) & BANDS_HW_STATUS_FRAMES_MASK);
    hw->merged = 0u;
    hw->missed = 0u;
    hw->lost = 0u;
    return FW_OK;
}

/* radio_summary_add's insertion, for a band given by index */
static void add_to_band(radio_summary_t *s, uint32_t b, uint8_t d)
{
    uint8_t *top = s->top[b];
    uint32_t n = s->count[b];
    uint32_t j;
    if (n == s->min_support) {
        if (d <= top[n - 1u]) {
            return;
        }
        n--;
    }
    j = n;
    while (j > 0u && top[j - 1u] < d) {
        top[j] = top[j - 1u];
        j--;
    }
    top[j] = d;
    s->count[b] = (uint8_t)(n + 1u);
}

uint32_t bands_hw_collect(bands_hw_t *hw, radio_summary_t *s)
{
    /* on the stack, not in bss: live only here, where the stack is shallow (the deepest
     * call chain is the XBee set-up's at start-up), so it costs the 8 KB nothing */
    uint32_t words[RADIO_MAX_BANDS];
    uint32_t attempt;
    if (hw == NULL || s == NULL || s->width != hw->width || s->n_bands != hw->n_bands ||
        s->min_support > BANDS_HW_SLOTS) {
        return 0u;
    }
    for (attempt = 0u; attempt < 2u; attempt++) {
        uint32_t status = Xil_In32(hw->base + BANDS_HW_STATUS_OFFSET);
        uint16_t frames = (uint16_t)(status & BANDS_HW_STATUS_FRAMES_MASK);
        uint32_t b;
        if (frames == hw->seen) {
            return 0u;
        }
        for (b = 0u; b < hw->n_bands; b++) {
            words[b] = Xil_In32(hw->base + BANDS_HW_TOP_OFFSET + 4u * b);
        }
        if ((uint16_t)(Xil_In32(hw->base + BANDS_HW_STATUS_OFFSET) &
                       BANDS_HW_STATUS_FRAMES_MASK) != frames) {
            continue;           /* the next frame was published meanwhile: read it */
        }
        hw->missed += (uint16_t)(frames - hw->seen - 1u);
        hw->seen = frames;
        hw->merged++;
        if ((status & BANDS_HW_STATUS_LOST) != 0u) {
            hw->lost++;
        }
        for (b = 0u; b < hw->n_bands; b++) {
            uint32_t j;
            for (j = 0u; j < s->min_support; j++) {
                uint8_t d = (uint8_t)((words[b] >> (8u * j)) & 0xFFu);
                if (d == 0u) {
                    break;      /* slots are descending: the rest are empty */
                }
                add_to_band(s, b, d);
            }
        }
        return 1u;
    }
    return 0u;
}
