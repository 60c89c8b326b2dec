/**
 * @file pipeline.c
 * Pipeline configuration and readout. Every offset, shift and mask comes from the generated
 * stereo_regs.h: nothing here knows a bit position.
 */
#include "pipeline.h"
#include "hal.h"
#include "stereo_regs.h"

#define FIELD_MAX(R, F) (STEREO_##R##_##F##_MASK >> STEREO_##R##_##F##_SHIFT)

void pipeline_default_config(pipeline_config_t *cfg)
{
    cfg->mode = STEREO_GROUND_MODE_RESET;
    cfg->k = STEREO_GROUND_K_RESET;
    cfg->jnd_hue = STEREO_GROUND_JND_HUE_RESET;
    cfg->jnd_luma = STEREO_GROUND_JND_LUMA_RESET;
    cfg->s_min = STEREO_GROUND_S_MIN_RESET;
    cfg->ref_x = STEREO_GROUND_REF_POS_REF_X_RESET;
    cfg->ref_y = STEREO_GROUND_REF_POS_REF_Y_RESET;
    cfg->ref_w = STEREO_GROUND_REF_SIZE_REF_W_RESET;
    cfg->ref_h = STEREO_GROUND_REF_SIZE_REF_H_RESET;
    cfg->hue_centre0 = STEREO_GROUND_INIT_HUE_CENTRE0_RESET;
    cfg->luma_centre0 = STEREO_GROUND_INIT_LUMA_CENTRE0_RESET;
    cfg->y_lo = STEREO_GROUND_CLIP_Y_LO_RESET;
    cfg->y_hi = STEREO_GROUND_CLIP_Y_HI_RESET;
    cfg->frac = STEREO_GROUND_SET_FRAC_RESET;
    cfg->min_support = STEREO_GROUND_SET_MIN_SUPPORT_RESET;
    cfg->blend_shift = STEREO_GROUND_SET_BLEND_SHIFT_RESET;
    cfg->hue_and_luma = STEREO_GROUND_SET_HUE_AND_LUMA_RESET;
    cfg->fallback_shift = STEREO_GROUND_SET_FALLBACK_SHIFT_RESET;
    cfg->edge_threshold = STEREO_SOBEL_EDGE_THRESHOLD_RESET;
    cfg->ratio = STEREO_SOBEL_RATIO_RESET;
    cfg->nms = STEREO_SOBEL_NMS_RESET;
    cfg->right_threshold = STEREO_SOBEL_RIGHT_RIGHT_THRESHOLD_RESET;
    cfg->d_min = STEREO_MATCH_D_MIN_RESET;
    cfg->d_max = STEREO_MATCH_D_MAX_RESET;
    cfg->uniqueness = STEREO_MATCH_UNIQUENESS_RESET;
    cfg->candidate_mode = STEREO_MATCH_CANDIDATE_MODE_RESET;
    cfg->widen = STEREO_MATCH_WIDEN_RESET;
    cfg->camera_mode_drop = STEREO_MATCH_CAMERA_MODE_DROP_RESET;
}

fw_status_t pipeline_check_id(uint32_t base)
{
    uint32_t id = STEREO_ReadReg(base, STEREO_ID_OFFSET);
    if (STEREO_GET(ID, MAGIC, id) != STEREO_ID_MAGIC ||
        STEREO_GET(ID, VERSION, id) != STEREO_MAP_VERSION) {
        return FW_ERR_ID;
    }
    return FW_OK;
}

/* v <= max, through a function so that a field as wide as its uint8_t member (MATCH.d_min,
 * d_max) needs no always-true comparison, and a narrower map still gets its check. */
static int fits(uint32_t v, uint32_t max)
{
    return v <= max;
}

static int config_valid(const pipeline_config_t *c)
{
    return c->mode <= 2u && c->k <= FIELD_MAX(GROUND, K) && c->jnd_hue <= FIELD_MAX(GROUND, JND_HUE) &&
           c->jnd_luma <= FIELD_MAX(GROUND, JND_LUMA) &&
           c->ref_x <= FIELD_MAX(GROUND_REF_POS, REF_X) && c->ref_y <= FIELD_MAX(GROUND_REF_POS, REF_Y) &&
           c->ref_w <= FIELD_MAX(GROUND_REF_SIZE, REF_W) && c->ref_h <= FIELD_MAX(GROUND_REF_SIZE, REF_H) &&
           c->hue_centre0 <= 191u && c->y_lo <= c->y_hi &&
           c->blend_shift <= FIELD_MAX(GROUND_SET, BLEND_SHIFT) && c->hue_and_luma <= 1u &&
           c->fallback_shift <= FIELD_MAX(GROUND_SET, FALLBACK_SHIFT) &&
           c->edge_threshold <= FIELD_MAX(SOBEL, EDGE_THRESHOLD) &&
           c->ratio <= FIELD_MAX(SOBEL, RATIO) && c->nms <= 1u &&
           c->right_threshold <= FIELD_MAX(SOBEL_RIGHT, RIGHT_THRESHOLD) &&
           fits(c->d_min, FIELD_MAX(MATCH, D_MIN)) && fits(c->d_max, FIELD_MAX(MATCH, D_MAX)) &&
           c->d_min <= c->d_max && (uint32_t)(c->d_max - c->d_min) < STEREO_MATCH_SPAN &&
           c->candidate_mode <= 1u && c->widen <= 1u &&
           c->camera_mode_drop <= 1u;
}

typedef struct {
    uint32_t offset;
    uint32_t value;
} reg_write_t;

fw_status_t pipeline_configure(uint32_t base, const pipeline_config_t *c)
{
    reg_write_t w[9];
    uint32_t i;
    if (c == NULL || !config_valid(c)) {
        return FW_ERR_PARAM;
    }
    w[0].offset = STEREO_GROUND_OFFSET;
    w[0].value = STEREO_SET(GROUND, MODE, c->mode) | STEREO_SET(GROUND, K, c->k) |
                 STEREO_SET(GROUND, JND_HUE, c->jnd_hue) | STEREO_SET(GROUND, JND_LUMA, c->jnd_luma) |
                 STEREO_SET(GROUND, S_MIN, c->s_min);
    w[1].offset = STEREO_GROUND_REF_POS_OFFSET;
    w[1].value = STEREO_SET(GROUND_REF_POS, REF_X, c->ref_x) | STEREO_SET(GROUND_REF_POS, REF_Y, c->ref_y);
    w[2].offset = STEREO_GROUND_REF_SIZE_OFFSET;
    w[2].value = STEREO_SET(GROUND_REF_SIZE, REF_W, c->ref_w) | STEREO_SET(GROUND_REF_SIZE, REF_H, c->ref_h);
    w[3].offset = STEREO_GROUND_INIT_OFFSET;
    w[3].value = STEREO_SET(GROUND_INIT, HUE_CENTRE0, c->hue_centre0) |
                 STEREO_SET(GROUND_INIT, LUMA_CENTRE0, c->luma_centre0);
    w[4].offset = STEREO_SOBEL_OFFSET;
    w[4].value = STEREO_SET(SOBEL, EDGE_THRESHOLD, c->edge_threshold) |
                 STEREO_SET(SOBEL, RATIO, c->ratio) | STEREO_SET(SOBEL, NMS, c->nms);
    w[5].offset = STEREO_SOBEL_RIGHT_OFFSET;
    w[5].value = STEREO_SET(SOBEL_RIGHT, RIGHT_THRESHOLD, c->right_threshold);
    w[6].offset = STEREO_MATCH_OFFSET;
    w[6].value = STEREO_SET(MATCH, D_MIN, c->d_min) | STEREO_SET(MATCH, D_MAX, c->d_max) |
                 STEREO_SET(MATCH, UNIQUENESS, c->uniqueness) |
                 STEREO_SET(MATCH, CANDIDATE_MODE, c->candidate_mode) |
                 STEREO_SET(MATCH, WIDEN, c->widen) |
                 STEREO_SET(MATCH, CAMERA_MODE_DROP, c->camera_mode_drop);
    w[7].offset = STEREO_GROUND_CLIP_OFFSET;
    w[7].value = STEREO_SET(GROUND_CLIP, Y_LO, c->y_lo) | STEREO_SET(GROUND_CLIP, Y_HI, c->y_hi);
    w[8].offset = STEREO_GROUND_SET_OFFSET;
    w[8].value = STEREO_SET(GROUND_SET, FRAC, c->frac) |
                 STEREO_SET(GROUND_SET, MIN_SUPPORT, c->min_support) |
                 STEREO_SET(GROUND_SET, BLEND_SHIFT, c->blend_shift) |
                 STEREO_SET(GROUND_SET, HUE_AND_LUMA, c->hue_and_luma) |
                 STEREO_SET(GROUND_SET, FALLBACK_SHIFT, c->fallback_shift);
    for (i = 0u; i < ARRAY_SIZE(w); i++) {
        STEREO_WriteReg(base, w[i].offset, w[i].value);
    }
    for (i = 0u; i < ARRAY_SIZE(w); i++) {
        if (STEREO_ReadReg(base, w[i].offset) != w[i].value) {
            return FW_ERR_ID;
        }
    }
    return FW_OK;
}

fw_status_t pipeline_set_window(uint32_t base, uint8_t d_min, uint8_t d_max)
{
    uint32_t keep = ~(STEREO_MATCH_D_MIN_MASK | STEREO_MATCH_D_MAX_MASK);
    uint32_t v;
    if (d_min > d_max || (uint32_t)(d_max - d_min) >= STEREO_MATCH_SPAN ||
        !fits(d_min, FIELD_MAX(MATCH, D_MIN)) || !fits(d_max, FIELD_MAX(MATCH, D_MAX))) {
        return FW_ERR_PARAM;
    }
    v = (STEREO_ReadReg(base, STEREO_MATCH_OFFSET) & keep) |
        STEREO_SET(MATCH, D_MIN, d_min) | STEREO_SET(MATCH, D_MAX, d_max);
    STEREO_WriteReg(base, STEREO_MATCH_OFFSET, v);
    return STEREO_ReadReg(base, STEREO_MATCH_OFFSET) == v ? FW_OK : FW_ERR_ID;
}

void pipeline_read_config(uint32_t base, pipeline_config_t *c)
{
    uint32_t v = STEREO_ReadReg(base, STEREO_GROUND_OFFSET);
    c->mode = (uint8_t)STEREO_GET(GROUND, MODE, v);
    c->k = (uint8_t)STEREO_GET(GROUND, K, v);
    c->jnd_hue = (uint8_t)STEREO_GET(GROUND, JND_HUE, v);
    c->jnd_luma = (uint8_t)STEREO_GET(GROUND, JND_LUMA, v);
    c->s_min = (uint8_t)STEREO_GET(GROUND, S_MIN, v);
    v = STEREO_ReadReg(base, STEREO_GROUND_REF_POS_OFFSET);
    c->ref_x = (uint16_t)STEREO_GET(GROUND_REF_POS, REF_X, v);
    c->ref_y = (uint16_t)STEREO_GET(GROUND_REF_POS, REF_Y, v);
    v = STEREO_ReadReg(base, STEREO_GROUND_REF_SIZE_OFFSET);
    c->ref_w = (uint16_t)STEREO_GET(GROUND_REF_SIZE, REF_W, v);
    c->ref_h = (uint16_t)STEREO_GET(GROUND_REF_SIZE, REF_H, v);
    v = STEREO_ReadReg(base, STEREO_GROUND_INIT_OFFSET);
    c->hue_centre0 = (uint8_t)STEREO_GET(GROUND_INIT, HUE_CENTRE0, v);
    c->luma_centre0 = (uint8_t)STEREO_GET(GROUND_INIT, LUMA_CENTRE0, v);
    v = STEREO_ReadReg(base, STEREO_SOBEL_OFFSET);
    c->edge_threshold = (uint16_t)STEREO_GET(SOBEL, EDGE_THRESHOLD, v);
    c->ratio = (uint8_t)STEREO_GET(SOBEL, RATIO, v);
    c->nms = (uint8_t)STEREO_GET(SOBEL, NMS, v);
    v = STEREO_ReadReg(base, STEREO_SOBEL_RIGHT_OFFSET);
    c->right_threshold = (uint16_t)STEREO_GET(SOBEL_RIGHT, RIGHT_THRESHOLD, v);
    v = STEREO_ReadReg(base, STEREO_MATCH_OFFSET);
    c->d_min = (uint8_t)STEREO_GET(MATCH, D_MIN, v);
    c->d_max = (uint8_t)STEREO_GET(MATCH, D_MAX, v);
    c->uniqueness = (uint8_t)STEREO_GET(MATCH, UNIQUENESS, v);
    c->candidate_mode = (uint8_t)STEREO_GET(MATCH, CANDIDATE_MODE, v);
    c->widen = (uint8_t)STEREO_GET(MATCH, WIDEN, v);
    c->camera_mode_drop = (uint8_t)STEREO_GET(MATCH, CAMERA_MODE_DROP, v);
    v = STEREO_ReadReg(base, STEREO_GROUND_CLIP_OFFSET);
    c->y_lo = (uint8_t)STEREO_GET(GROUND_CLIP, Y_LO, v);
    c->y_hi = (uint8_t)STEREO_GET(GROUND_CLIP, Y_HI, v);
    v = STEREO_ReadReg(base, STEREO_GROUND_SET_OFFSET);
    c->frac = (uint8_t)STEREO_GET(GROUND_SET, FRAC, v);
    c->min_support = (uint16_t)STEREO_GET(GROUND_SET, MIN_SUPPORT, v);
    c->blend_shift = (uint8_t)STEREO_GET(GROUND_SET, BLEND_SHIFT, v);
    c->hue_and_luma = (uint8_t)STEREO_GET(GROUND_SET, HUE_AND_LUMA, v);
    c->fallback_shift = (uint8_t)STEREO_GET(GROUND_SET, FALLBACK_SHIFT, v);
}

void pipeline_read_status(uint32_t base, pipeline_status_t *s)
{
    uint32_t v;
    s->frames = STEREO_ReadReg(base, STEREO_FRAME_COUNT_OFFSET);
    v = STEREO_ReadReg(base, STEREO_ERR_LEFT_OFFSET);
    s->left_errors = (uint16_t)STEREO_GET(ERR_LEFT, ERRORS, v);
    s->left_dropped = (uint16_t)STEREO_GET(ERR_LEFT, DROPPED, v);
    v = STEREO_ReadReg(base, STEREO_ERR_RIGHT_OFFSET);
    s->right_errors = (uint16_t)STEREO_GET(ERR_RIGHT, ERRORS, v);
    s->right_dropped = (uint16_t)STEREO_GET(ERR_RIGHT, DROPPED, v);
    v = STEREO_ReadReg(base, STEREO_ERR_MATCH_OFFSET);
    s->match_errors = (uint16_t)STEREO_GET(ERR_MATCH, ERRORS, v);
    s->match_dropped = (uint16_t)STEREO_GET(ERR_MATCH, DROPPED, v);
    s->edges = STEREO_ReadReg(base, STEREO_STAT_EDGES_OFFSET);
    s->sad_evals = STEREO_ReadReg(base, STEREO_STAT_SAD_OFFSET);
    s->matches = STEREO_ReadReg(base, STEREO_STAT_MATCHES_OFFSET);
    s->rejects = STEREO_ReadReg(base, STEREO_STAT_REJECTS_OFFSET);
    s->drops = STEREO_ReadReg(base, STEREO_STAT_DROPS_OFFSET);
    v = STEREO_ReadReg(base, STEREO_RESULT_LEVEL_OFFSET);
    s->fifo_level = (uint16_t)STEREO_GET(RESULT_LEVEL, LEVEL, v);
    s->fifo_overflow = (uint16_t)STEREO_GET(RESULT_LEVEL, OVERFLOW, v);
    v = STEREO_ReadReg(base, STEREO_GROUND_STATUS_OFFSET);
    s->left_ground_learned = (uint8_t)STEREO_GET(GROUND_STATUS, LEFT_LEARNED, v);
    s->left_hue_fallback = (uint8_t)STEREO_GET(GROUND_STATUS, LEFT_HUE_FALLBACK, v);
    s->right_ground_learned = (uint8_t)STEREO_GET(GROUND_STATUS, RIGHT_LEARNED, v);
    s->right_hue_fallback = (uint8_t)STEREO_GET(GROUND_STATUS, RIGHT_HUE_FALLBACK, v);
}

uint32_t pipeline_read_results(uint32_t base, pipeline_match_t *out, uint32_t max)
{
    uint32_t n = 0u;
    uint32_t level = STEREO_GET(RESULT_LEVEL, LEVEL, STEREO_ReadReg(base, STEREO_RESULT_LEVEL_OFFSET));
    if (out == NULL) {
        return 0u;
    }
    if (level > max) {
        level = max;
    }
    while (n < level) {
        uint32_t r = STEREO_ReadReg(base, STEREO_RESULT_OFFSET);
        if (STEREO_GET(RESULT, VALID, r) == 0u) {
            break;
        }
        out[n].x = (uint16_t)STEREO_GET(RESULT, X, r);
        out[n].y = (uint16_t)STEREO_GET(RESULT, Y, r);
        out[n].d = (uint8_t)STEREO_GET(RESULT, D, r);
        out[n].mark = (uint8_t)((STEREO_GET(RESULT, EOF, r) != 0u ? PIPELINE_MARK_EOF : 0u) |
                                (STEREO_GET(RESULT, ABORT, r) != 0u ? PIPELINE_MARK_ABORT : 0u));
        n++;
    }
    return n;
}

fw_status_t pipeline_configure_free_space(uint32_t base, uint16_t band_w, uint8_t run_r)
{
    uint32_t v;
    if (band_w < 1u || band_w > FIELD_MAX(FREE_CFG, BAND_W) || run_r < 1u) {
        return FW_ERR_PARAM;
    }
    v = STEREO_SET(FREE_CFG, BAND_W, band_w) | STEREO_SET(FREE_CFG, RUN_R, run_r);
    STEREO_WriteReg(base, STEREO_FREE_CFG_OFFSET, v);
    return STEREO_ReadReg(base, STEREO_FREE_CFG_OFFSET) == v ? FW_OK : FW_ERR_ID;
}

fw_status_t pipeline_read_free_space(uint32_t base, pipeline_free_space_t *fs)
{
    /* two bands per word: band 2k in EVEN, 2k + 1 in ODD (the same field layout in every word) */
    static const uint32_t left[PIPELINE_FREE_BANDS / 2u] = {
        STEREO_FREE_LEFT_0_OFFSET, STEREO_FREE_LEFT_1_OFFSET, STEREO_FREE_LEFT_2_OFFSET,
        STEREO_FREE_LEFT_3_OFFSET, STEREO_FREE_LEFT_4_OFFSET, STEREO_FREE_LEFT_5_OFFSET,
        STEREO_FREE_LEFT_6_OFFSET, STEREO_FREE_LEFT_7_OFFSET};
    static const uint32_t right[PIPELINE_FREE_BANDS / 2u] = {
        STEREO_FREE_RIGHT_0_OFFSET, STEREO_FREE_RIGHT_1_OFFSET, STEREO_FREE_RIGHT_2_OFFSET,
        STEREO_FREE_RIGHT_3_OFFSET, STEREO_FREE_RIGHT_4_OFFSET, STEREO_FREE_RIGHT_5_OFFSET,
        STEREO_FREE_RIGHT_6_OFFSET, STEREO_FREE_RIGHT_7_OFFSET};
    uint32_t k;
    if (fs == NULL) {
        return FW_ERR_PARAM;
    }
    for (k = 0u; k < ARRAY_SIZE(left); k++) {
        uint32_t v = STEREO_ReadReg(base, left[k]);
        fs->left[2u * k] = (uint16_t)STEREO_GET(FREE_LEFT_0, EVEN, v);
        fs->left[2u * k + 1u] = (uint16_t)STEREO_GET(FREE_LEFT_0, ODD, v);
        v = STEREO_ReadReg(base, right[k]);
        fs->right[2u * k] = (uint16_t)STEREO_GET(FREE_RIGHT_0, EVEN, v);
        fs->right[2u * k + 1u] = (uint16_t)STEREO_GET(FREE_RIGHT_0, ODD, v);
    }
    return FW_OK;
}

void pipeline_clear_errors(uint32_t base)
{
    STEREO_WriteReg(base, STEREO_CTRL_OFFSET, STEREO_SET(CTRL, CLEAR_ERRORS, 1u));
}

void pipeline_video_enable(uint32_t base, uint32_t on)
{
    STEREO_WriteReg(base, STEREO_VIDEO_OFFSET, STEREO_SET(VIDEO, VIDEO_ENABLE, on != 0u));
}

void pipeline_restart_video(uint32_t base)
{
    STEREO_WriteReg(base, STEREO_CTRL_OFFSET, STEREO_SET(CTRL, RESTART_VIDEO, 1u));
}

void pipeline_flush_results(uint32_t base)
{
    STEREO_WriteReg(base, STEREO_CTRL_OFFSET, STEREO_SET(CTRL, FLUSH_RESULTS, 1u));
}
