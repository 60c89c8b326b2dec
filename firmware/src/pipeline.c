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
#define DEFAULT_OF(R, F, m, T) cfg->m = (T)STEREO_##R##_##F##_RESET;
    STEREO_CONFIG_FIELDS(DEFAULT_OF)
#undef DEFAULT_OF
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
    int ok = 1;
    /* every field within its width, then the rules between fields */
#define FITS(R, F, m, T) ok = ok && (uint32_t)c->m <= FIELD_MAX(R, F);
    STEREO_CONFIG_FIELDS(FITS)
#undef FITS
    return ok && c->mode <= 2u && c->hue_centre0 <= 191u && c->y_lo <= c->y_hi &&
           c->d_min <= c->d_max && (uint32_t)(c->d_max - c->d_min) < STEREO_MATCH_SPAN;
}

/** The value of parameter register `offset` for configuration c. */
static uint32_t register_value(uint32_t offset, const pipeline_config_t *c)
{
    uint32_t v = 0u;
#define FIELD_OF(R, F, m, T) if (offset == STEREO_##R##_OFFSET) { v |= STEREO_SET(R, F, c->m); }
    STEREO_CONFIG_FIELDS(FIELD_OF)
#undef FIELD_OF
    return v;
}

#define OFFSET_OF(R) STEREO_##R##_OFFSET,
static const uint32_t config_regs[STEREO_CONFIG_NREGS] = { STEREO_CONFIG_REGS(OFFSET_OF) };
#undef OFFSET_OF

fw_status_t pipeline_configure(uint32_t base, const pipeline_config_t *c)
{
    uint32_t i;
    if (c == NULL || !config_valid(c)) {
        return FW_ERR_PARAM;
    }
    for (i = 0u; i < ARRAY_SIZE(config_regs); i++) {
        STEREO_WriteReg(base, config_regs[i], register_value(config_regs[i], c));
    }
    for (i = 0u; i < ARRAY_SIZE(config_regs); i++) {
        if (STEREO_ReadReg(base, config_regs[i]) != register_value(config_regs[i], c)) {
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
    uint32_t values[STEREO_CONFIG_NREGS];
    uint32_t i;
    for (i = 0u; i < ARRAY_SIZE(config_regs); i++) {
        values[i] = STEREO_ReadReg(base, config_regs[i]);
    }
#define READ_OF(R, F, m, T) \
    for (i = 0u; i < ARRAY_SIZE(config_regs); i++) { \
        if (config_regs[i] == STEREO_##R##_OFFSET) { c->m = (T)STEREO_GET(R, F, values[i]); } \
    }
    STEREO_CONFIG_FIELDS(READ_OF)
#undef READ_OF
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
    s->evaluations = STEREO_ReadReg(base, STEREO_STAT_EVALUATIONS_OFFSET);
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
                                (STEREO_GET(RESULT, ABORT, r) != 0u ? PIPELINE_MARK_ABORT : 0u) |
                                (STEREO_GET(RESULT, FLOOR, r) != 0u ? PIPELINE_MARK_FLOOR : 0u));
        /* the record's second half, which the RESULT read latched: before the next RESULT */
        r = STEREO_ReadReg(base, STEREO_RESULT_EXT_OFFSET);
        out[n].d16 = (uint16_t)STEREO_GET(RESULT_EXT, D16, r);
        out[n].conf = (uint8_t)STEREO_GET(RESULT_EXT, CONF, r);
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
