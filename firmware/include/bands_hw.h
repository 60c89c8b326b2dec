/**
 * @file bands_hw.h
 * The SoC's per-band obstacle summary unit (hdl/bands.py, rule in golden/bands.py): instead
 * of draining every record from the result FIFO into radio_summary_add, the firmware merges,
 * once a frame, the unit's summary of the last complete frame into the same radio_summary_t.
 *
 * The unit keeps, per frame and band, the BANDS_HW_SLOTS largest disparities. The
 * min_support-th largest of a union is the min_support-th largest of the union of each part's
 * min_support largest, so for min_support <= BANDS_HW_SLOTS the report built from the merged
 * frames equals the one radio_summary_add builds from the same frames' records, ties and empty
 * bands included (tests/test_bands.py, firmware/tests/test_bands_hw.c).
 *
 * Register window: hdl/regmap.py BANDS_BASEADDR, BANDS_REGS (tests/test_bands.py checks that
 * the values below agree).
 */
#ifndef BANDS_HW_H
#define BANDS_HW_H

#include <stdint.h>
#include "fw_status.h"
#include "radio.h"

#define BANDS_HW_BASEADDR          0xC0050000u  /**< hdl/regmap.py BANDS_BASEADDR */
#define BANDS_HW_CFG_OFFSET        0x000u       /**< rw: width bits 10..0, n_bands bits 22..16 */
#define BANDS_HW_STATUS_OFFSET     0x004u       /**< ro: frames, built, bad_cfg, lost */
#define BANDS_HW_DROPS_OFFSET      0x008u       /**< ro: records dropped, frames aborted */
#define BANDS_HW_RECORDS_OFFSET    0x00Cu       /**< rw: bit 0, the records also go to the
                                                     result FIFO (RESULT); reset 0 */
#define BANDS_HW_TOP_OFFSET        0x100u       /**< ro: one word per band, band 0 first */
#define BANDS_HW_CFG_N_BANDS_SHIFT 16u
#define BANDS_HW_STATUS_FRAMES_MASK 0xFFFFu     /**< frames published (wraps) */
#define BANDS_HW_STATUS_BUILT      (1u << 16)   /**< band table ready for CFG */
#define BANDS_HW_STATUS_BAD_CFG    (1u << 17)   /**< CFG out of range: every record dropped */
#define BANDS_HW_STATUS_LOST       (1u << 18)   /**< the published frame lost records */
#define BANDS_HW_SLOTS             4u           /**< disparities per band word (golden.bands.SLOTS) */
#define BANDS_HW_MAX_WIDTH         1024u

typedef struct {
    uint32_t base;
    uint16_t width;
    uint8_t n_bands;
    uint16_t seen;      /**< STATUS.frames of the last frame taken (merged or missed) */
    uint32_t merged;    /**< frames merged into a summary */
    uint32_t missed;    /**< frames published but not merged: read too late, or changed twice
                             while being read */
    uint32_t lost;      /**< merged frames of which the unit dropped records */
} bands_hw_t;

/** Write CFG (width, n_bands) and read it back; the unit then fills its band table (width
 *  cycles; STATUS.built). Frames published before are not merged. FW_ERR_PARAM (nothing
 *  written) unless 1 <= n_bands <= RADIO_MAX_BANDS and n_bands <= width <= 1024; FW_ERR_ID
 *  when the read-back differs (no unit at base). */
fw_status_t bands_hw_init(bands_hw_t *hw, uint32_t base, uint16_t width, uint8_t n_bands);

/** If the unit published a frame since the last call, merge its summary into s (which must
 *  have been opened with radio_summary_init for the same width and n_bands, and min_support
 *  <= BANDS_HW_SLOTS) and return 1; else 0. A frame is merged only when STATUS.frames reads
 *  the same before and after its words (a frame published in between: read again, at most
 *  twice per call). Frames skipped are counted in hw->missed. Cost: n_bands + 2 register
 *  reads and at most n_bands * min_support insertions. Returns 0 on mismatched s. */
uint32_t bands_hw_collect(bands_hw_t *hw, radio_summary_t *s);

#endif /* BANDS_HW_H */
