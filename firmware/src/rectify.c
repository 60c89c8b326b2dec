/**
 * @file rectify.c
 * Start-up check and enable of the rectifiers (include/rectify.h).
 */
#include "rectify.h"

#include "hal.h"
#include "stereo_regs.h"

fw_status_t rect_setup(uint32_t base, const rect_table_t *t)
{
    uint32_t info = Xil_In32(base + STEREO_RECT_INFO_OFFSET);
    /* a rectifier's RECT_INFO is positive (span >= 2, bit 31 clear); a window nobody answers
     * reads 0 (MCS) or all ones (the RISC-V core's I/O timeout, the host's empty bus) */
    if ((int32_t)info <= 0) {
        return FW_ERR_RECT_ABSENT;
    }
    /* the fields sit at the same bits in both words: masked words compare as the fields */
    if ((t->need & STEREO_RECT_INFO_SPAN_MASK) > (info & STEREO_RECT_INFO_SPAN_MASK)) {
        return FW_ERR_RECT_WARP;
    }
    /* the map comes with the bitstream: without one the check word proves nothing (a map
     * whose check is 0 would pass against an empty memory) */
    if ((info & STEREO_RECT_INFO_PRELOADED_MASK) == 0u ||
        ((t->need ^ info) & STEREO_RECT_INFO_STRIDE_LOG2_MASK) != 0u ||
        (t->need & STEREO_RECT_INFO_NODE_ROWS_MASK) > (info & STEREO_RECT_INFO_NODE_ROWS_MASK) ||
        Xil_In32(base + STEREO_RECT_MAP_CHECK_OFFSET) != t->map_check) {
        return FW_ERR_RECT_MAP;
    }
    Xil_Out32(base + STEREO_RECT_VALID_POS_OFFSET, t->valid_pos);
    Xil_Out32(base + STEREO_RECT_VALID_SIZE_OFFSET, t->valid_size);
    Xil_Out32(base + STEREO_RECT_CTRL_OFFSET, t->ctrl);
    return FW_OK;
}

fw_status_t rect_setup_both(uint32_t base, const rect_table_t *t, uint32_t left_base,
                            const rect_table_t *left)
{
    fw_status_t st = rect_setup(left_base, left);
    if (st == FW_OK) {
        st = rect_setup(base, t);
        if (st != FW_OK) {
            Xil_Out32(left_base + STEREO_RECT_CTRL_OFFSET, 0u);
        }
    }
    return st;
}
