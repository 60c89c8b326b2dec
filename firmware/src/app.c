/**
 * @file app.c
 * Start-up and the periodic radio report.
 */
#include "app.h"
#include "floor.h"
#include "floor_table.h"
#include "hal.h"
#include "stereo_regs.h"

/** GROUND.mode of hue classification (docs/registers.md). */
#define APP_GROUND_MODE_HUE 2u

#include <string.h>

/** The summary keeps room for the default min_support (radio.h RADIO_SUMMARY_MAX_SUPPORT). */
typedef char app_summary_holds_default_support[
    (RADIO_DEFAULT_MIN_SUPPORT <= RADIO_SUMMARY_MAX_SUPPORT) ? 1 : -1];

fw_status_t app_init_decoders(app_t *app, uint32_t iic_base, uint32_t iic_timeout_polls)
{
    static const uint8_t addrs[APP_N_DECODERS] = { ADV7180_ADDR_ALSB_LOW, ADV7180_ADDR_ALSB_HIGH };
    fw_status_t first = FW_OK;
    uint32_t i;
    fw_status_t st;
    if (app == NULL) {
        return FW_ERR_PARAM;
    }
    app->seq = 0u;
    app->summary_open = 0u;
    app->n_bands = RADIO_DEFAULT_BANDS;
    app->min_support = RADIO_DEFAULT_MIN_SUPPORT;
    app->width = APP_FIELD_WIDTH;
    st = iic_init(&app->iic, iic_base, iic_timeout_polls);
    if (st != FW_OK) {
        return st;
    }
    for (i = 0u; i < APP_N_DECODERS; i++) {
        st = adv7180_bind(&app->dec[i], &app->iic, addrs[i]);
        if (st == FW_OK) {
            st = adv7180_init(&app->dec[i]);
        }
        app->dec_status[i] = st;
        if (st != FW_OK && first == FW_OK) {
            first = st;
        }
    }
    return first;
}

fw_status_t app_retry_decoders(app_t *app)
{
    fw_status_t first = FW_OK;
    uint32_t i;
    if (app == NULL) {
        return FW_ERR_PARAM;
    }
    for (i = 0u; i < APP_N_DECODERS; i++) {
        if (app->dec_status[i] != FW_OK) {
            app->dec_status[i] = adv7180_init(&app->dec[i]);
        }
        if (app->dec_status[i] != FW_OK && first == FW_OK) {
            first = app->dec_status[i];
        }
    }
    return first;
}

fw_status_t app_init_pipeline(app_t *app, uint32_t regs_base)
{
    fw_status_t st;
    if (app == NULL) {
        return FW_ERR_PARAM;
    }
    app->regs_base = regs_base;
    app->lost_seen = 0u;
    st = pipeline_check_id(regs_base);
    if (st != FW_OK) {
        return st;
    }
    pipeline_default_config(&app->cfg);
    st = pipeline_configure(regs_base, &app->cfg);
    if (st != FW_OK) {
        return st;
    }
    app_floor_start(regs_base);
    pipeline_clear_errors(regs_base);
    pipeline_flush_results(regs_base);
    return FW_OK;
}

#if APP_FLOOR_LEARN
static struct {
    uint16_t y[APP_FLOOR_RECORDS];
    uint16_t d16[APP_FLOOR_RECORDS];
    int64_t work[2u * APP_FLOOR_RECORDS];
    uint32_t n;
    uint8_t full;
    floor_line_t rig, line;
    floor_params_t params;
} app_floor;

static floor_line_t floor_line_of(uint32_t word)
{
    floor_line_t l;
    uint32_t off = STEREO_GET(FLOOR_LINE, FLOOR_OFFSET, word);
    l.slope = (uint16_t)STEREO_GET(FLOOR_LINE, FLOOR_SLOPE, word);
    l.offset = (int32_t)off - ((off & 0x20000u) != 0u ? 0x40000 : 0);    /* 18-bit signed */
    return l;
}
#endif

void app_floor_start(uint32_t regs_base)
{
    STEREO_WriteReg(regs_base, STEREO_FLOOR_LINE_OFFSET, FLOOR_TABLE_LINE);
    STEREO_WriteReg(regs_base, STEREO_FLOOR_OFFSET,
                    STEREO_FLOOR_RESET | STEREO_SET(FLOOR, FLOOR_ENABLE, 1u));
#if APP_FLOOR_LEARN
    app_floor.n = 0u;
    app_floor.full = 0u;
    app_floor.rig = floor_line_of(FLOOR_TABLE_LINE);
    app_floor.line = app_floor.rig;
    floor_default_params(&app_floor.params);
    app_floor.params.slope_max = APP_FLOOR_SLOPE_MAX;
#endif
}

fw_status_t app_floor_rig(uint32_t regs_base, uint16_t slope, int32_t offset)
{
    if (slope > 1023u || offset < -131072 || offset > 131071) {
        return FW_ERR_PARAM;
    }
    STEREO_WriteReg(regs_base, STEREO_FLOOR_LINE_OFFSET,
                    STEREO_SET(FLOOR_LINE, FLOOR_SLOPE, slope) |
                    STEREO_SET(FLOOR_LINE, FLOOR_OFFSET, (uint32_t)offset));
#if APP_FLOOR_LEARN
    app_floor.rig.slope = slope;
    app_floor.rig.offset = offset;
    app_floor.line = app_floor.rig;
    app_floor.n = 0u;
    app_floor.full = 0u;
#endif
    return FW_OK;
}

void app_floor_add(uint16_t y, uint16_t d16)
{
#if APP_FLOOR_LEARN
    if (app_floor.n < APP_FLOOR_RECORDS) {
        app_floor.y[app_floor.n] = y;
        app_floor.d16[app_floor.n] = d16;
        app_floor.n++;
    } else {
        app_floor.full = 1u;
    }
#else
    (void)y; (void)d16;
#endif
}

int app_floor_end(uint32_t regs_base, int abort)
{
#if APP_FLOOR_LEARN
    int changed = 0;
    if (!abort && !app_floor.full &&
        floor_learn(app_floor.y, app_floor.d16, app_floor.n, &app_floor.params, &app_floor.rig,
                    &app_floor.line, 1, app_floor.work) == 1) {
        STEREO_WriteReg(regs_base, STEREO_FLOOR_LINE_OFFSET,
                        STEREO_SET(FLOOR_LINE, FLOOR_SLOPE, app_floor.line.slope) |
                        STEREO_SET(FLOOR_LINE, FLOOR_OFFSET, (uint32_t)app_floor.line.offset));
        changed = 1;
    }
    app_floor.n = 0u;
    app_floor.full = 0u;
    return changed;
#else
    (void)regs_base; (void)abort;
    return 0;
#endif
}

static fw_status_t app_open_summary(app_t *app)
{
    fw_status_t st = FW_OK;
    radio_summary_t *s = &app->summary;
    if (!app->summary_open) {
        /* the band boundaries take a divide each: placed again only when they change */
        if (s->width == app->width && s->n_bands == app->n_bands &&
            s->min_support == app->min_support && s->n_bands != 0u &&
            s->start[s->n_bands] == s->width) {
            radio_summary_clear(s);
        } else {
            st = radio_summary_init(s, app->width, app->n_bands, app->min_support);
        }
        app->summary_open = (uint8_t)(st == FW_OK);
        app->results_read = 0u;
    }
    return st;
}

#ifdef FIRMWARE_BANDS_HW
uint32_t app_collect(app_t *app)
{
    /* the SoC's summary unit takes the records (bands_hw.h): the caller merges its frames
     * into the summary opened here */
    if (app != NULL) {
        (void)app_open_summary(app);
    }
    return 0u;
}
#else
uint32_t app_collect(app_t *app)
{
    uint32_t total = 0u;
    uint32_t misses = 0u;
    uint32_t level;
    uint32_t base;
    radio_summary_t *summary;
    if (app == NULL || app_open_summary(app) != FW_OK) {
        return 0u;
    }
    /* locals: the summary's byte stores could alias app's members, which would be reloaded */
    base = app->regs_base;
    summary = &app->summary;
    /* bounded: what the FIFO held when the call began, at most APP_COLLECT_MAX records; one
     * RESULT read a record (the summary needs x, d and the marker bits only, so the second
     * half in RESULT_EXT is skipped) */
    level = STEREO_GET(RESULT_LEVEL, LEVEL, STEREO_ReadReg(base, STEREO_RESULT_LEVEL_OFFSET));
    if (level > APP_COLLECT_MAX) {
        level = APP_COLLECT_MAX;
    }
    while (total < level) {
        uint32_t r = STEREO_ReadReg(base, STEREO_RESULT_OFFSET);
        if ((r & STEREO_RESULT_VALID_MASK) != 0u) {
            total++;
            if ((r & STEREO_RESULT_EOF_MASK) != 0u) {
                (void)app_floor_end(base, (r & STEREO_RESULT_ABORT_MASK) != 0u);
                continue;
            }
#if APP_FLOOR_LEARN
            app_floor_add((uint16_t)STEREO_GET(RESULT, Y, r),
                          (uint16_t)STEREO_GET(RESULT_EXT, D16,
                                               STEREO_ReadReg(base, STEREO_RESULT_EXT_OFFSET)));
#endif
            if ((r & STEREO_RESULT_FLOOR_MASK) == 0u) {     /* floor points are no obstacles */
                radio_summary_add(summary, (uint16_t)STEREO_GET(RESULT, X, r),
                                  (uint8_t)STEREO_GET(RESULT, D, r));
            }
        } else if (++misses > 1u) {
            /* a read in the cycle right after a RESULT read finds no whole record: once more */
            break;
        }
    }
    app->results_read += total;
    return total;
}
#endif

uint32_t app_report(app_t *app, int16_t x_mm, int16_t y_mm, uint16_t theta, uint32_t pose_ms,
                    const radio_health_t *health, uint8_t *buf, uint32_t cap)
{
    uint32_t len = app_build_report(app, x_mm, y_mm, theta, pose_ms, health, buf, cap);
    if (len == 0u) {
        return 0u;
    }
    return hal_uart_write(buf, len) == FW_OK ? len : 0u;
}

uint32_t app_build_report(app_t *app, int16_t x_mm, int16_t y_mm, uint16_t theta,
                          uint32_t pose_ms, const radio_health_t *health, uint8_t *buf,
                          uint32_t cap)
{
    radio_packet_t pkt;
    uint8_t rf[RADIO_MAX_RF_DATA];
    uint32_t rf_len;
    uint32_t len;
    if (app == NULL || buf == NULL) {
        return 0u;
    }
    (void)app_collect(app);
    if (!app->summary_open) {
        return 0u;
    }
    pkt.seq = app->seq;
    pkt.frame = (uint16_t)(STEREO_ReadReg(app->regs_base, STEREO_FRAME_COUNT_OFFSET) & 0xFFFFu);
    pkt.pose_ms = pose_ms;
    pkt.x_mm = x_mm;
    pkt.y_mm = y_mm;
    pkt.theta = theta;
    pkt.width = app->width;
    pkt.n_bands = app->n_bands;
    radio_summary_finish(&app->summary, pkt.bands);
    app->summary_open = 0u;   /* the next collect starts a new summary */
    rf_len = radio_encode_payload(&pkt, health, rf, sizeof rf);
    len = radio_encode_api_frame(rf, rf_len, APP_RADIO_DEST, (uint8_t)(app->seq % 255u + 1u), buf, cap);
    if (rf_len == 0u || len == 0u) {
        return 0u;
    }
    app->seq = (uint8_t)(app->seq + 1u);
    return len;
}

fw_status_t app_check_lock(app_t *app)
{
    uint32_t i;
    if (app == NULL) {
        return FW_ERR_PARAM;
    }
    for (i = 0u; i < APP_N_DECODERS; i++) {
        uint8_t locked = 0u;
        fw_status_t st = app->dec_status[i];
        if (st == FW_OK) {
            st = adv7180_lock_status(&app->dec[i], &locked);
        }
        if (st != FW_OK) {
            return st;
        }
        if (!locked) {
            return FW_ERR_NO_LOCK;
        }
    }
    return FW_OK;
}

fw_status_t app_start_video(app_t *app, uint32_t polls)
{
    const uint32_t both = STEREO_HEALTH_STATUS_LEFT_LOCKED_MASK | STEREO_HEALTH_STATUS_RIGHT_LOCKED_MASK;
    uint32_t n;
    if (app == NULL) {
        return FW_ERR_PARAM;
    }
    pipeline_video_enable(app->regs_base, 1u);
    for (n = 0u; n <= polls; n++) {
        if ((STEREO_ReadReg(app->regs_base, STEREO_HEALTH_STATUS_OFFSET) & both) == both) {
            return FW_OK;
        }
        hal_delay_us(APP_LOCK_POLL_US);
    }
    return FW_ERR_NO_LOCK;
}

void app_restart_video(app_t *app)
{
    uint16_t result_overflow;
    if (app == NULL) {
        return;
    }
    pipeline_restart_video(app->regs_base);
    result_overflow = app->health_last.result_overflow;   /* the register block keeps it */
    memset(&app->health_last, 0, sizeof app->health_last);
    app->health_last.result_overflow = result_overflow;
}

static uint16_t field16(uint32_t value, uint32_t shift)
{
    return (uint16_t)((value >> shift) & 0xFFFFu);
}

static uint16_t since(uint16_t now, uint16_t *last)
{
    uint16_t d = (uint16_t)(now - *last);
    *last = now;
    return d;
}

/** HEALTH_STATUS's loss bits, and how far above its lock bits they lie (the same for both
 *  cameras): a lost camera's lock bit is cleared with one shift. */
#define APP_LOST_MASK (STEREO_HEALTH_STATUS_LEFT_LOST_MASK | STEREO_HEALTH_STATUS_RIGHT_LOST_MASK)
#define APP_LOST_TO_LOCKED (STEREO_HEALTH_STATUS_LEFT_LOST_SHIFT - STEREO_HEALTH_STATUS_LEFT_LOCKED_SHIFT)
typedef char app_lost_bits_pair_with_locked[
    (STEREO_HEALTH_STATUS_RIGHT_LOST_SHIFT - STEREO_HEALTH_STATUS_RIGHT_LOCKED_SHIFT
     == APP_LOST_TO_LOCKED) ? 1 : -1];

void app_watch_health(app_t *app)
{
    app->lost_seen |= (uint8_t)(STEREO_ReadReg(app->regs_base, STEREO_HEALTH_STATUS_OFFSET)
                                & APP_LOST_MASK);
}

fw_status_t app_read_health(app_t *app, radio_health_t *h)
{
    uint32_t cam, ovf, pairs, drops, status, level, errm, frames, ground, skew, lost;
    uint32_t overflow;
    health_snapshot_t *l;
    if (app == NULL || h == NULL) {
        return FW_ERR_PARAM;
    }
    if (pipeline_check_id(app->regs_base) != FW_OK) {
        return FW_ERR_ID;
    }
    l = &app->health_last;
    frames = STEREO_ReadReg(app->regs_base, STEREO_FRAME_COUNT_OFFSET);
    cam = STEREO_ReadReg(app->regs_base, STEREO_HEALTH_CAMERA_OFFSET);
    ovf = STEREO_ReadReg(app->regs_base, STEREO_HEALTH_OVERFLOW_OFFSET);
    pairs = STEREO_ReadReg(app->regs_base, STEREO_HEALTH_PAIRS_OFFSET);
    drops = STEREO_ReadReg(app->regs_base, STEREO_HEALTH_DROPS_OFFSET);
    status = STEREO_ReadReg(app->regs_base, STEREO_HEALTH_STATUS_OFFSET);
    level = STEREO_ReadReg(app->regs_base, STEREO_RESULT_LEVEL_OFFSET);
    errm = STEREO_ReadReg(app->regs_base, STEREO_ERR_MATCH_OFFSET);
    ground = STEREO_ReadReg(app->regs_base, STEREO_GROUND_STATUS_OFFSET);
    skew = STEREO_ReadReg(app->regs_base, STEREO_HEALTH_SKEW_OFFSET);
    /* the ground model reports hue fallback in every mode; it means something only in hue mode */
    if (STEREO_GET(GROUND, MODE, STEREO_ReadReg(app->regs_base, STEREO_GROUND_OFFSET)) != APP_GROUND_MODE_HUE) {
        ground = 0u;
    }
    (void)errm;
    h->frames = since(field16(frames, 0u), &l->frames);
    h->pairs_ok = since(field16(pairs, STEREO_HEALTH_PAIRS_PAIRS_OK_SHIFT), &l->pairs_ok);
    h->mispaired = since(field16(pairs, STEREO_HEALTH_PAIRS_MISPAIRED_SHIFT), &l->mispaired);
    h->drops = since(field16(drops, STEREO_HEALTH_DROPS_FRAMES_SHIFT), &l->drops);
    h->cam_errors[0] = since(field16(cam, STEREO_HEALTH_CAMERA_LEFT_ERRORS_SHIFT),
                             &l->cam_errors[0]);
    h->cam_errors[1] = since(field16(cam, STEREO_HEALTH_CAMERA_RIGHT_ERRORS_SHIFT),
                             &l->cam_errors[1]);
    h->matcher_errors = since(field16(drops, STEREO_HEALTH_DROPS_MATCH_ERRORS_SHIFT),
                              &l->matcher_errors);
    overflow = (uint32_t)since(field16(ovf, STEREO_HEALTH_OVERFLOW_LEFT_SHIFT), &l->overflow[0])
             + since(field16(ovf, STEREO_HEALTH_OVERFLOW_RIGHT_SHIFT), &l->overflow[1])
             + since(field16(level, STEREO_RESULT_LEVEL_OVERFLOW_SHIFT), &l->result_overflow);
    h->fifo_overflow = (uint16_t)(overflow > 0xFFFFu ? 0xFFFFu : overflow);
    h->camera_skew_us = (int16_t)field16(skew, STEREO_HEALTH_SKEW_US_SHIFT);
    h->camera_skew_pairs = since(field16(skew, STEREO_HEALTH_SKEW_PAIRS_SHIFT), &l->skew_pairs);
    /* a camera lost at any time since the last report (sticky: the loss bits gathered by
     * app_watch_health, and the ones now) is reported lost and not locked */
    lost = (app->lost_seen | status) & APP_LOST_MASK;
    app->lost_seen = 0u;
    status &= ~(lost >> APP_LOST_TO_LOCKED);
    /* FW_OK is 0: the OR of the two decoders' start-up results is an error if either is */
    h->flags = (uint8_t)(((status & STEREO_HEALTH_STATUS_LEFT_LOCKED_MASK) ? RADIO_HEALTH_LEFT_LOCKED : 0u)
             | ((status & STEREO_HEALTH_STATUS_RIGHT_LOCKED_MASK) ? RADIO_HEALTH_RIGHT_LOCKED : 0u)
             | ((status & STEREO_HEALTH_STATUS_ENABLED_MASK) ? RADIO_HEALTH_PIPELINE_ENABLED : 0u)
             | ((ground & (STEREO_GROUND_STATUS_LEFT_HUE_FALLBACK_MASK
                           | STEREO_GROUND_STATUS_RIGHT_HUE_FALLBACK_MASK)) ? RADIO_HEALTH_HUE_FALLBACK : 0u)
             | ((app->dec_status[0] | app->dec_status[1]) != FW_OK ? RADIO_HEALTH_DECODER_FAULT : 0u)
             | (lost != 0u ? RADIO_HEALTH_CAMERA_LOST : 0u));
    return FW_OK;
}

#ifndef HAL_TARGET
#include <stddef.h>

/** Host builds only: offset and size of every field the ctypes mirrors (sim/system/cosim/fwlib.py)
 *  declare, by "struct.field" name, so that check_layout compares them field by field. */
typedef struct {
    const char *name;
    uint32_t offset;
    uint32_t size;
} fw_field_t;

#define FW_FIELD(T, F) { #T "." #F, (uint32_t)offsetof(T, F), (uint32_t)sizeof(((T *)0)->F) }

static const fw_field_t fw_fields[] = {
#define CONFIG_FW_FIELD(R, F, m, T) FW_FIELD(pipeline_config_t, m),
    STEREO_CONFIG_FIELDS(CONFIG_FW_FIELD)
#undef CONFIG_FW_FIELD
    FW_FIELD(pipeline_match_t, x), FW_FIELD(pipeline_match_t, y), FW_FIELD(pipeline_match_t, d),
    FW_FIELD(pipeline_match_t, mark), FW_FIELD(pipeline_match_t, d16),
    FW_FIELD(pipeline_match_t, conf),
    FW_FIELD(radio_health_t, frames), FW_FIELD(radio_health_t, pairs_ok),
    FW_FIELD(radio_health_t, mispaired), FW_FIELD(radio_health_t, drops),
    FW_FIELD(radio_health_t, cam_errors), FW_FIELD(radio_health_t, matcher_errors),
    FW_FIELD(radio_health_t, fifo_overflow), FW_FIELD(radio_health_t, flags),
    FW_FIELD(radio_health_t, camera_skew_us), FW_FIELD(radio_health_t, camera_skew_pairs),
    FW_FIELD(health_snapshot_t, frames), FW_FIELD(health_snapshot_t, pairs_ok),
    FW_FIELD(health_snapshot_t, mispaired), FW_FIELD(health_snapshot_t, drops),
    FW_FIELD(health_snapshot_t, cam_errors), FW_FIELD(health_snapshot_t, matcher_errors),
    FW_FIELD(health_snapshot_t, overflow), FW_FIELD(health_snapshot_t, result_overflow),
    FW_FIELD(health_snapshot_t, skew_pairs),
    FW_FIELD(app_t, regs_base), FW_FIELD(app_t, iic), FW_FIELD(app_t, dec),
    FW_FIELD(app_t, dec_status), FW_FIELD(app_t, cfg), FW_FIELD(app_t, seq),
    FW_FIELD(app_t, n_bands), FW_FIELD(app_t, min_support), FW_FIELD(app_t, width),
    FW_FIELD(app_t, results_read), FW_FIELD(app_t, summary_open), FW_FIELD(app_t, summary),
    FW_FIELD(app_t, health_last), FW_FIELD(app_t, lost_seen),
};

/** The offset of "struct.field" and its size in *size; -1 for an unknown name. */
int32_t fw_field_offset(const char *name, uint32_t *size);
int32_t fw_field_offset(const char *name, uint32_t *size)
{
    uint32_t i;
    for (i = 0u; i < ARRAY_SIZE(fw_fields); i++) {
        if (strcmp(fw_fields[i].name, name) == 0) {
            *size = fw_fields[i].size;
            return (int32_t)fw_fields[i].offset;
        }
    }
    return -1;
}

/** Host builds only: sizeof(app_t), for the co-simulation's ctypes mirror. */
uint32_t app_sizeof(void);
uint32_t app_sizeof(void)
{
    return (uint32_t)sizeof(app_t);
}
#endif
