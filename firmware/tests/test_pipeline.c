/* Pipeline configuration and readout through the generated header, on the register-block
 * model of sim_xiic.c. */
#include "app.h"
#include "fwtest.h"
#include "pipeline.h"
#include "sim_xiic.h"
#include "stereo_regs.h"

#include <string.h>

static sim_xiic_t sim;

static void setup(void)
{
    sim_init(&sim, STEREO_IIC_BASEADDR);
    sim_install(&sim);
}

static void test_id(void)
{
    setup();
    FWT_CHECK_EQ(pipeline_check_id(STEREO_BASEADDR), FW_OK);
    sim_uninstall(); /* empty bus reads 0xFFFFFFFF */
    FWT_CHECK_EQ(pipeline_check_id(STEREO_BASEADDR), FW_ERR_ID);
}

static void test_defaults_match_reset_values(void)
{
    pipeline_config_t c;
    setup();
    pipeline_default_config(&c);
    FWT_CHECK_EQ(pipeline_configure(STEREO_BASEADDR, &c), FW_OK);
    FWT_CHECK_EQ(sim.regfile[STEREO_GROUND_OFFSET / 4], STEREO_GROUND_RESET);
    FWT_CHECK_EQ(sim.regfile[STEREO_GROUND_REF_POS_OFFSET / 4], STEREO_GROUND_REF_POS_RESET);
    FWT_CHECK_EQ(sim.regfile[STEREO_GROUND_REF_SIZE_OFFSET / 4], STEREO_GROUND_REF_SIZE_RESET);
    FWT_CHECK_EQ(sim.regfile[STEREO_GROUND_INIT_OFFSET / 4], STEREO_GROUND_INIT_RESET);
    FWT_CHECK_EQ(sim.regfile[STEREO_SOBEL_OFFSET / 4], STEREO_SOBEL_RESET);
    FWT_CHECK_EQ(sim.regfile[STEREO_SOBEL_RIGHT_OFFSET / 4], STEREO_SOBEL_RIGHT_RESET);
    FWT_CHECK_EQ(sim.regfile[STEREO_MATCH_OFFSET / 4], STEREO_MATCH_RESET);
}

static void test_configure_roundtrip(void)
{
    pipeline_config_t c, r;
    setup();
    memset(&c, 0, sizeof c); /* padding too, for the memcmp */
    memset(&r, 0, sizeof r);
    pipeline_default_config(&c);
    c.mode = 1; c.k = 15; c.jnd_hue = 3; c.jnd_luma = 9; c.s_min = 200;
    c.ref_x = 2047; c.ref_y = 5; c.ref_w = 1024; c.ref_h = 7;
    c.hue_centre0 = 191; c.luma_centre0 = 255;
    c.edge_threshold = 2000; c.ratio = 15; c.nms = 1; c.right_threshold = 1234;
    c.d_min = 3; c.d_max = 63; c.uniqueness = 255; c.candidate_mode = 1; c.widen = 2;
    c.camera_mode_drop = 1; c.sign = 1;
    FWT_CHECK_EQ(pipeline_configure(STEREO_BASEADDR, &c), FW_OK);
    pipeline_read_config(STEREO_BASEADDR, &r);
    FWT_CHECK(memcmp(&c, &r, sizeof c) == 0);
    /* exact bit positions, from the map */
    FWT_CHECK_EQ(sim.regfile[STEREO_MATCH_OFFSET / 4], 0x1DFF3F03u);
}

static void test_configure_rejects_bad_values(void)
{
    pipeline_config_t c;
    setup();
    pipeline_default_config(&c);
    c.d_min = 40; c.d_max = 20;
    FWT_CHECK_EQ(pipeline_configure(STEREO_BASEADDR, &c), FW_ERR_PARAM);
    FWT_CHECK_EQ(sim.regfile[STEREO_MATCH_OFFSET / 4], 0u); /* nothing written */
    c.d_min = 100; c.d_max = 100 + STEREO_MATCH_SPAN; /* a window of 65 disparities */
    FWT_CHECK_EQ(pipeline_configure(STEREO_BASEADDR, &c), FW_ERR_PARAM);
    c.d_max = 100 + STEREO_MATCH_SPAN - 1;            /* 64: the widest window */
    FWT_CHECK_EQ(pipeline_configure(STEREO_BASEADDR, &c), FW_OK);
    FWT_CHECK_EQ(STEREO_GET(MATCH, D_MAX, sim.regfile[STEREO_MATCH_OFFSET / 4]), 163u);
    setup();
    pipeline_default_config(&c);
    c.mode = 3;
    FWT_CHECK_EQ(pipeline_configure(STEREO_BASEADDR, &c), FW_ERR_PARAM);
    pipeline_default_config(&c);
    c.hue_centre0 = 192;
    FWT_CHECK_EQ(pipeline_configure(STEREO_BASEADDR, &c), FW_ERR_PARAM);
    pipeline_default_config(&c);
    c.ref_w = 2048;
    FWT_CHECK_EQ(pipeline_configure(STEREO_BASEADDR, &c), FW_ERR_PARAM);
}

static uint32_t record(uint32_t x, uint32_t y, uint32_t d)
{
    return STEREO_SET(RESULT, X, x) | STEREO_SET(RESULT, Y, y) | STEREO_SET(RESULT, D, d) |
           STEREO_SET(RESULT, VALID, 1u);
}

static void test_set_window_keeps_the_other_match_fields(void)
{
    pipeline_config_t c;
    setup();
    pipeline_default_config(&c);
    c.uniqueness = 77; c.widen = 1;
    FWT_CHECK_EQ(pipeline_configure(STEREO_BASEADDR, &c), FW_OK);
    FWT_CHECK_EQ(pipeline_set_window(STEREO_BASEADDR, 117u, 180u), FW_OK);  /* near window */
    pipeline_read_config(STEREO_BASEADDR, &c);
    FWT_CHECK_EQ(c.d_min, 117u);
    FWT_CHECK_EQ(c.d_max, 180u);
    FWT_CHECK_EQ(c.uniqueness, 77u);
    FWT_CHECK_EQ(c.widen, 1u);
    FWT_CHECK_EQ(pipeline_set_window(STEREO_BASEADDR, 0u, 64u), FW_ERR_PARAM); /* 65 wide */
    FWT_CHECK_EQ(pipeline_set_window(STEREO_BASEADDR, 9u, 8u), FW_ERR_PARAM);
    pipeline_read_config(STEREO_BASEADDR, &c);
    FWT_CHECK_EQ(c.d_min, 117u);                                             /* unchanged */
    FWT_CHECK_EQ(pipeline_set_window(STEREO_BASEADDR, 0u, 63u), FW_OK);    /* far window */
    FWT_CHECK_EQ(sim.regfile[STEREO_MATCH_OFFSET / 4] & 0xFFFFu, 0x3F00u);
}

static uint32_t record_ext(uint32_t d16, uint32_t conf)
{
    return STEREO_SET(RESULT_EXT, D16, d16) | STEREO_SET(RESULT_EXT, CONF, conf);
}

static void test_results_and_status(void)
{
    pipeline_match_t m[8];
    pipeline_status_t st;
    setup();
    sim.result_fifo[0] = record(1023, 1023, 255);
    sim.result_ext[0] = record_ext(4095u, 255u);     /* every field at its widest */
    sim.result_fifo[1] = record(5, 6, 7);
    sim.result_ext[1] = record_ext(7u * 16u - 8u, 17u);
    sim.result_fifo[2] = record(0, 0, 1);
    sim.result_ext[2] = record_ext(1u * 16u + 8u, 200u);
    sim.result_n = 3;
    sim.regfile[STEREO_FRAME_COUNT_OFFSET / 4] = 77;
    sim.regfile[STEREO_ERR_LEFT_OFFSET / 4] = 0x00020001u;
    sim.regfile[STEREO_STAT_MATCHES_OFFSET / 4] = 3;
    pipeline_read_status(STEREO_BASEADDR, &st);
    FWT_CHECK_EQ(st.frames, 77);
    FWT_CHECK_EQ(st.left_errors, 1);
    FWT_CHECK_EQ(st.left_dropped, 2);
    FWT_CHECK_EQ(st.matches, 3);
    FWT_CHECK_EQ(st.fifo_level, 3);
    FWT_CHECK_EQ(pipeline_read_results(STEREO_BASEADDR, m, 2), 2);
    FWT_CHECK(m[0].x == 1023 && m[0].y == 1023 && m[0].d == 255 && m[0].mark == 0u);
    FWT_CHECK(m[0].d16 == 4095u && m[0].conf == 255u);
    FWT_CHECK(m[1].x == 5 && m[1].y == 6 && m[1].d == 7);
    FWT_CHECK(m[1].d16 == 7u * 16u - 8u && m[1].conf == 17u);   /* its own second half */
    FWT_CHECK_EQ(pipeline_read_results(STEREO_BASEADDR, m, 8), 1);
    FWT_CHECK(m[0].x == 0 && m[0].d == 1 && m[0].d16 == 24u && m[0].conf == 200u);
    FWT_CHECK_EQ(pipeline_read_results(STEREO_BASEADDR, m, 8), 0);
    /* markers: RESULT_EXT is 0 for them */
    sim.result_fifo[3] = STEREO_SET(RESULT, EOF, 1u) | STEREO_SET(RESULT, VALID, 1u);
    sim.result_ext[3] = 0u;
    sim.result_fifo[4] = record(9, 8, 3);
    sim.result_ext[4] = record_ext(3u * 16u + 1u, 99u);
    sim.result_n = 5;
    FWT_CHECK_EQ(pipeline_read_results(STEREO_BASEADDR, m, 8), 2);
    FWT_CHECK(m[0].mark == PIPELINE_MARK_EOF && m[0].d16 == 0u && m[0].conf == 0u);
    FWT_CHECK(m[1].mark == 0u && m[1].d16 == 49u && m[1].conf == 99u);
    sim.result_n = 7;
    pipeline_flush_results(STEREO_BASEADDR);
    FWT_CHECK_EQ(pipeline_read_results(STEREO_BASEADDR, m, 8), 0);
}

static void test_health_counts_since_last_read(void)
{
    static app_t app;
    radio_health_t h;
    setup();
    memset(&app, 0, sizeof app);
    FWT_CHECK_EQ(app_init_pipeline(&app, STEREO_BASEADDR), FW_OK);
    sim.regfile[STEREO_FRAME_COUNT_OFFSET / 4] = 10;
    sim.regfile[STEREO_HEALTH_PAIRS_OFFSET / 4] = 9u | 1u << 16;
    sim.regfile[STEREO_HEALTH_CAMERA_OFFSET / 4] = 3u | 4u << 16;
    sim.regfile[STEREO_HEALTH_DROPS_OFFSET / 4] = 2u | 5u << 16;
    sim.regfile[STEREO_HEALTH_OVERFLOW_OFFSET / 4] = 7u;
    sim.regfile[STEREO_HEALTH_STATUS_OFFSET / 4] = 0x7u;
    FWT_CHECK_EQ(app_read_health(&app, &h), FW_OK);
    FWT_CHECK(h.frames == 10 && h.pairs_ok == 9 && h.mispaired == 1 && h.drops == 2);
    FWT_CHECK(h.cam_errors[0] == 3 && h.cam_errors[1] == 4 && h.matcher_errors == 5);
    FWT_CHECK(h.fifo_overflow == 7 && h.flags == 0x7u);
    FWT_CHECK(h.camera_skew_us == 0 && h.camera_skew_pairs == 0);
    /* the capture skew: the last pair's, signed, and the pairs measured since the last read */
    sim.regfile[STEREO_HEALTH_SKEW_OFFSET / 4] = 0xFFF5u | 3u << 16;      /* -11 us, 3 pairs */
    FWT_CHECK_EQ(app_read_health(&app, &h), FW_OK);
    FWT_CHECK(h.camera_skew_us == -11 && h.camera_skew_pairs == 3);
    sim.regfile[STEREO_HEALTH_SKEW_OFFSET / 4] = 250u | 4u << 16;
    FWT_CHECK_EQ(app_read_health(&app, &h), FW_OK);
    FWT_CHECK(h.camera_skew_us == 250 && h.camera_skew_pairs == 1);
    /* differences since the last read, across a wrap of the 16-bit counter */
    sim.regfile[STEREO_HEALTH_PAIRS_OFFSET / 4] = 2u | 1u << 16;
    app.health_last.pairs_ok = 0xFFF0u;
    sim.regfile[STEREO_HEALTH_STATUS_OFFSET / 4] = 0x1u;
    FWT_CHECK_EQ(app_read_health(&app, &h), FW_OK);
    FWT_CHECK(h.frames == 0 && h.pairs_ok == 0x12 && h.mispaired == 0 && h.flags == 0x1u);
    /* in hue mode, either camera in hue fallback (GROUND_STATUS) raises the radio flag */
    sim.regfile[STEREO_GROUND_OFFSET / 4] = STEREO_SET(GROUND, MODE, 2u);
    sim.regfile[STEREO_GROUND_STATUS_OFFSET / 4] = STEREO_GROUND_STATUS_RIGHT_HUE_FALLBACK_MASK;
    FWT_CHECK_EQ(app_read_health(&app, &h), FW_OK);
    FWT_CHECK(h.flags == (0x1u | RADIO_HEALTH_HUE_FALLBACK));
    /* in the other modes the model's fallback status means nothing */
    sim.regfile[STEREO_GROUND_OFFSET / 4] = STEREO_SET(GROUND, MODE, 0u);
    FWT_CHECK_EQ(app_read_health(&app, &h), FW_OK);
    FWT_CHECK(h.flags == 0x1u);
    sim.regfile[STEREO_GROUND_OFFSET / 4] = STEREO_SET(GROUND, MODE, 2u);
    sim.regfile[STEREO_GROUND_STATUS_OFFSET / 4] = STEREO_GROUND_STATUS_LEFT_LEARNED_MASK
                                                  | STEREO_GROUND_STATUS_RIGHT_LEARNED_MASK;
    FWT_CHECK_EQ(app_read_health(&app, &h), FW_OK);
    FWT_CHECK(h.flags == 0x1u);
    FWT_CHECK_EQ(app_read_health(&app, NULL), FW_ERR_PARAM);
    sim_uninstall();
    FWT_CHECK_EQ(app_read_health(&app, &h), FW_ERR_ID);
}

static void test_camera_loss_is_reported_once_with_its_side(void)
{
    static app_t app;
    radio_health_t h;
    const uint32_t on = STEREO_HEALTH_STATUS_LEFT_LOCKED_MASK | STEREO_HEALTH_STATUS_RIGHT_LOCKED_MASK
                      | STEREO_HEALTH_STATUS_ENABLED_MASK;
    const uint8_t ok = RADIO_HEALTH_LEFT_LOCKED | RADIO_HEALTH_RIGHT_LOCKED
                     | RADIO_HEALTH_PIPELINE_ENABLED;
    uint32_t *status = &sim.regfile[STEREO_HEALTH_STATUS_OFFSET / 4];
    setup();
    memset(&app, 0xA5, sizeof app);         /* app_init_pipeline starts with no loss seen */
    FWT_CHECK_EQ(app_init_pipeline(&app, STEREO_BASEADDR), FW_OK);
    app.dec_status[0] = app.dec_status[1] = FW_OK;
    *status = on;
    FWT_CHECK_EQ(app_read_health(&app, &h), FW_OK);
    FWT_CHECK_EQ(h.flags, ok);
    /* lost at the read: the stream's lock bit stays set through a loss, the report's does not */
    *status = on | STEREO_HEALTH_STATUS_LEFT_LOST_MASK;
    FWT_CHECK_EQ(app_read_health(&app, &h), FW_OK);
    FWT_CHECK_EQ(h.flags, (ok & ~RADIO_HEALTH_LEFT_LOCKED) | RADIO_HEALTH_CAMERA_LOST);
    /* back before the next read: that report is clean */
    *status = on;
    FWT_CHECK_EQ(app_read_health(&app, &h), FW_OK);
    FWT_CHECK_EQ(h.flags, ok);
    /* lost and back between two reports, seen by a watch meanwhile: reported once */
    app_watch_health(&app);
    *status = on | STEREO_HEALTH_STATUS_RIGHT_LOST_MASK;
    app_watch_health(&app);
    *status = on;
    app_watch_health(&app);
    FWT_CHECK_EQ(app_read_health(&app, &h), FW_OK);
    FWT_CHECK_EQ(h.flags, (ok & ~RADIO_HEALTH_RIGHT_LOCKED) | RADIO_HEALTH_CAMERA_LOST);
    FWT_CHECK_EQ(app_read_health(&app, &h), FW_OK);
    FWT_CHECK_EQ(h.flags, ok);
    /* both sides, one of them seen only by the watch */
    *status = on | STEREO_HEALTH_STATUS_LEFT_LOST_MASK;
    app_watch_health(&app);
    *status = on | STEREO_HEALTH_STATUS_RIGHT_LOST_MASK;
    FWT_CHECK_EQ(app_read_health(&app, &h), FW_OK);
    FWT_CHECK_EQ(h.flags, RADIO_HEALTH_PIPELINE_ENABLED | RADIO_HEALTH_CAMERA_LOST);
    /* a video restart clears the loss watch and the lock bits alike; a loss seen before it
     * in the period is still reported */
    *status = on | STEREO_HEALTH_STATUS_LEFT_LOST_MASK;
    app_watch_health(&app);
    app_restart_video(&app);
    *status = STEREO_HEALTH_STATUS_ENABLED_MASK;
    FWT_CHECK_EQ(app_read_health(&app, &h), FW_OK);
    FWT_CHECK_EQ(h.flags, RADIO_HEALTH_PIPELINE_ENABLED | RADIO_HEALTH_CAMERA_LOST);
    FWT_CHECK_EQ(app_read_health(&app, &h), FW_OK);
    FWT_CHECK_EQ(h.flags, RADIO_HEALTH_PIPELINE_ENABLED);
}

static void test_start_video_is_bounded(void)
{
    static app_t app;
    setup();
    memset(&app, 0, sizeof app);
    FWT_CHECK_EQ(app_init_pipeline(&app, STEREO_BASEADDR), FW_OK);
    sim.regfile[STEREO_HEALTH_STATUS_OFFSET / 4] = 0x1u;        /* right never locks */
    FWT_CHECK_EQ(app_start_video(&app, 5u), FW_ERR_NO_LOCK);
    FWT_CHECK_EQ(sim.regfile[STEREO_VIDEO_OFFSET / 4], 1u);     /* enabled */
    sim.regfile[STEREO_HEALTH_STATUS_OFFSET / 4] = 0x3u;
    FWT_CHECK_EQ(app_start_video(&app, 5u), FW_OK);
}

static void test_report_builds_frame(void)
{
    static app_t app;
    uint8_t buf[RADIO_MAX_FRAME];
    uint32_t n, i;
    uint8_t sum = 0;
    setup();
    FWT_CHECK_EQ(app_init_pipeline(&app, STEREO_BASEADDR), FW_OK);
    app.width = 752; app.n_bands = 32; app.min_support = 3; app.seq = 0;
    for (i = 0; i < 5; i++) {
        sim.result_fifo[sim.result_n++] = record(10 + i, 100, 20 + i); /* band 0 */
    }
    sim.regfile[STEREO_FRAME_COUNT_OFFSET / 4] = 0x12345;
    n = app_report(&app, -5, 7, 0x4000, 1234u, NULL, buf, sizeof buf);
    FWT_CHECK_EQ(n, RADIO_HEADER_LEN + 32 + RADIO_CRC_LEN + XBEE_API_OVERHEAD); /* no byte escaped */
    FWT_CHECK_EQ(sim.uart_n, n);
    FWT_CHECK_EQ(buf[0], 0x7E);
    FWT_CHECK_EQ(buf[8], RADIO_PAYLOAD_TYPE);
    FWT_CHECK_EQ(buf[10], 0x23); /* frame counter low 16 bits, big-endian */
    FWT_CHECK_EQ(buf[11], 0x45);
    FWT_CHECK_EQ(buf[8 + RADIO_HEADER_LEN], 22); /* 3rd largest of 20..24 */
    FWT_CHECK_EQ(app.results_read, 5);
    for (i = 3; i < n; i++) {
        sum = (uint8_t)(sum + buf[i]);
    }
    FWT_CHECK_EQ(sum, 0xFF);
    FWT_CHECK_EQ(app.seq, 1);
}

static void test_collect_across_frames(void)
{
    /* results collected in several drains end up in one report */
    static app_t app;
    uint8_t buf[RADIO_MAX_FRAME];
    uint32_t i;
    setup();
    FWT_CHECK_EQ(app_init_pipeline(&app, STEREO_BASEADDR), FW_OK);
    app.width = 752; app.n_bands = 32; app.min_support = 3; app.summary_open = 0;
    for (i = 0; i < 2; i++) {
        sim.result_fifo[sim.result_n++] = record(30, 10, 40);   /* band 1 */
    }
    FWT_CHECK_EQ(app_collect(&app), 2);
    sim.result_fifo[sim.result_n++] = record(31, 11, 41);
    FWT_CHECK_EQ(app_collect(&app), 1);
    FWT_CHECK_EQ(app_report(&app, 0, 0, 0, 0u, NULL, buf, sizeof buf), RADIO_HEADER_LEN + 32 + RADIO_CRC_LEN + XBEE_API_OVERHEAD);
    FWT_CHECK_EQ(buf[8 + RADIO_HEADER_LEN + 1], 40);   /* 3rd largest of 41, 40, 40 */
    FWT_CHECK_EQ(app.results_read, 3);
    /* the next report starts empty */
    FWT_CHECK_EQ(app_report(&app, 0, 0, 0, 0u, NULL, buf, sizeof buf), RADIO_HEADER_LEN + 32 + RADIO_CRC_LEN + XBEE_API_OVERHEAD);
    FWT_CHECK_EQ(buf[8 + RADIO_HEADER_LEN + 1], 0);
}

/** line16(y) of a FLOOR_LINE word */
static int32_t line16_of(uint32_t word, int32_t y)
{
    int32_t off = (int32_t)STEREO_GET(FLOOR_LINE, FLOOR_OFFSET, word);
    off -= (off & 0x20000) ? 0x40000 : 0;
    return ((int32_t)STEREO_GET(FLOOR_LINE, FLOOR_SLOPE, word) * y + off) >> 4;
}

static void test_floor_points_stay_out_and_the_line_is_learned(void)
{
    /* start-up: the rig's line, enabled; floor points (RESULT.floor) never reach the summary;
     * a frame's records on a line 3 px above the rig's: the line learned from them is written */
    static app_t app;
    uint8_t buf[RADIO_MAX_FRAME];
    uint32_t i, n = 0u;
    int32_t y;
    setup();
    FWT_CHECK_EQ(app_init_pipeline(&app, STEREO_BASEADDR), FW_OK);
    FWT_CHECK_EQ(sim.regfile[STEREO_FLOOR_LINE_OFFSET / 4], STEREO_FLOOR_LINE_RESET);
    FWT_CHECK_EQ(sim.regfile[STEREO_FLOOR_OFFSET / 4],
                 STEREO_FLOOR_RESET | STEREO_FLOOR_FLOOR_ENABLE_MASK);
    app.width = 752; app.n_bands = 32; app.min_support = 1; app.summary_open = 0;
    for (y = 60; y < 240; y++) {
        int32_t d16 = line16_of(STEREO_FLOOR_LINE_RESET, y) + 48;
        sim.result_ext[sim.result_n] = record_ext((uint32_t)d16, 9u);
        sim.result_fifo[sim.result_n++] = record(5u, (uint32_t)y, (uint32_t)(d16 >> 4)) |
                                          STEREO_SET(RESULT, FLOOR, 1u);            /* band 0 */
        n++;
    }
    sim.result_fifo[sim.result_n++] = record(30u, 100u, 7u);                       /* band 1 */
    sim.result_fifo[sim.result_n++] = STEREO_SET(RESULT, EOF, 1u) | STEREO_SET(RESULT, VALID, 1u);
    FWT_CHECK_EQ(app_collect(&app), n + 2u);
    FWT_CHECK(sim.regfile[STEREO_FLOOR_LINE_OFFSET / 4] != STEREO_FLOOR_LINE_RESET);
#if APP_FLOOR_LEARN
    for (y = 60; y < 240; y += 30) {
        int32_t d = line16_of(sim.regfile[STEREO_FLOOR_LINE_OFFSET / 4], y) -
                    (line16_of(STEREO_FLOOR_LINE_RESET, y) + 48);
        FWT_CHECK(d >= -32 && d <= 32);     /* within 2 px of the records */
    }
#endif
    FWT_CHECK_EQ(app_report(&app, 0, 0, 0, 0u, NULL, buf, sizeof buf),
                 RADIO_HEADER_LEN + 32 + RADIO_CRC_LEN + XBEE_API_OVERHEAD);
    FWT_CHECK_EQ(buf[8 + RADIO_HEADER_LEN], 0);      /* band 0: floor points only */
    FWT_CHECK_EQ(buf[8 + RADIO_HEADER_LEN + 1], 7);
    /* an aborted frame is not learned from */
    i = sim.regfile[STEREO_FLOOR_LINE_OFFSET / 4];
    sim.result_n = sim.result_head = 0u;
    for (y = 60; y < 240; y++) {
        sim.result_ext[sim.result_n] = record_ext(16u * 40u, 9u);
        sim.result_fifo[sim.result_n++] = record(5u, (uint32_t)y, 40u);
    }
    sim.result_fifo[sim.result_n++] = STEREO_SET(RESULT, EOF, 1u) | STEREO_SET(RESULT, ABORT, 1u) |
                                      STEREO_SET(RESULT, VALID, 1u);
    (void)app_collect(&app);
    FWT_CHECK_EQ(sim.regfile[STEREO_FLOOR_LINE_OFFSET / 4], i);
}

static void test_free_space(void)
{
    pipeline_free_space_t fs;
    uint32_t k;
    setup();
    FWT_CHECK_EQ(pipeline_configure_free_space(STEREO_BASEADDR, 0u, 4u), FW_ERR_PARAM);
    FWT_CHECK_EQ(pipeline_configure_free_space(STEREO_BASEADDR, 2048u, 4u), FW_ERR_PARAM);
    FWT_CHECK_EQ(pipeline_configure_free_space(STEREO_BASEADDR, 45u, 0u), FW_ERR_PARAM);
    FWT_CHECK_EQ(sim.regfile[STEREO_FREE_CFG_OFFSET / 4], 0u);     /* nothing written */
    FWT_CHECK_EQ(pipeline_configure_free_space(STEREO_BASEADDR, 2047u, 255u), FW_OK);
    FWT_CHECK_EQ(sim.regfile[STEREO_FREE_CFG_OFFSET / 4], 0x00FF07FFu);
    FWT_CHECK_EQ(pipeline_configure_free_space(STEREO_BASEADDR, STEREO_FREE_CFG_BAND_W_RESET,
                                               STEREO_FREE_CFG_RUN_R_RESET), FW_OK);
    FWT_CHECK_EQ(sim.regfile[STEREO_FREE_CFG_OFFSET / 4], STEREO_FREE_CFG_RESET);
    /* left band b at row 100 + b, right band b at 200 + b; bands 14, 15 of the right: none */
    for (k = 0u; k < 8u; k++) {
        sim.regfile[STEREO_FREE_LEFT_0_OFFSET / 4 + k] = (100u + 2u * k) | (101u + 2u * k) << 16;
        sim.regfile[STEREO_FREE_RIGHT_0_OFFSET / 4 + k] = (200u + 2u * k) | (201u + 2u * k) << 16;
    }
    sim.regfile[STEREO_FREE_RIGHT_7_OFFSET / 4] = 0xFFFFFFFFu;
    FWT_CHECK_EQ(pipeline_read_free_space(STEREO_BASEADDR, NULL), FW_ERR_PARAM);
    FWT_CHECK_EQ(pipeline_read_free_space(STEREO_BASEADDR, &fs), FW_OK);
    for (k = 0u; k < PIPELINE_FREE_BANDS; k++) {
        FWT_CHECK_EQ(fs.left[k], 100u + k);
        FWT_CHECK_EQ(fs.right[k], k < 14u ? 200u + k : PIPELINE_FREE_NONE);
    }
}

void suite_pipeline(void)
{
    FWT_RUN(test_id);
    FWT_RUN(test_health_counts_since_last_read);
    FWT_RUN(test_camera_loss_is_reported_once_with_its_side);
    FWT_RUN(test_start_video_is_bounded);
    FWT_RUN(test_defaults_match_reset_values);
    FWT_RUN(test_configure_roundtrip);
    FWT_RUN(test_configure_rejects_bad_values);
    FWT_RUN(test_set_window_keeps_the_other_match_fields);
    FWT_RUN(test_results_and_status);
    FWT_RUN(test_report_builds_frame);
    FWT_RUN(test_collect_across_frames);
    FWT_RUN(test_free_space);
    FWT_RUN(test_floor_points_stay_out_and_the_line_is_learned);
}
