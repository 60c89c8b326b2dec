/* Radio payload, API frame and per-band summary. */
#include "fwtest.h"
#include "radio.h"

#include <string.h>

static void test_crc_check_value(void)
{
    /* CRC-16/CCITT-FALSE catalogue check value */
    FWT_CHECK_EQ(radio_crc16((const uint8_t *)"123456789", 9), 0x29B1);
    FWT_CHECK_EQ(radio_crc16((const uint8_t *)"", 0), 0xFFFF);
}

static void test_payload_bytes(void)
{
    radio_packet_t p;
    radio_health_t h;
    uint8_t buf[RADIO_MAX_RF_DATA];
    static const uint8_t expect[] = { 0xA2, 0x12, 0x34, 0x56, 0x00, 0x01, 0xE2, 0x40,
                                      0xFF, 0xFE, 0x12, 0x34, 0xC0, 0x00, 0x02, 0xF0,
                                      0, 1, 0, 2, 0, 3, 0, 4, 0, 5, 0, 6, 0, 7, 0xFF, 0xFF, 0x0B,
                                      3, 0, 5, 63 };
    uint16_t crc;
    memset(&p, 0, sizeof p);
    p.seq = 0x12; p.frame = 0x3456; p.pose_ms = 123456u; p.x_mm = -2; p.y_mm = 0x1234;
    p.theta = 0xC000; p.width = 752; p.n_bands = 3; p.bands[0] = 0; p.bands[1] = 5;
    p.bands[2] = 63;
    h.frames = 1; h.pairs_ok = 2; h.mispaired = 3; h.drops = 4; h.cam_errors[0] = 5;
    h.cam_errors[1] = 6; h.matcher_errors = 7; h.fifo_overflow = 0xFFFF;
    h.flags = RADIO_HEALTH_LEFT_LOCKED | RADIO_HEALTH_RIGHT_LOCKED | RADIO_HEALTH_HUE_FALLBACK;
    FWT_CHECK_EQ(radio_encode_payload(&p, &h, buf, sizeof buf), sizeof expect + 2);
    FWT_CHECK(memcmp(buf, expect, sizeof expect) == 0);
    crc = radio_crc16(expect, sizeof expect);
    FWT_CHECK(buf[sizeof expect] == (crc >> 8) && buf[sizeof expect + 1] == (crc & 0xFF));
    /* NULL health: all zero */
    FWT_CHECK_EQ(radio_encode_payload(&p, NULL, buf, sizeof buf), sizeof expect + 2);
    FWT_CHECK(buf[RADIO_OFF_HEALTH_FRAMES + 1] == 0 && buf[RADIO_OFF_HEALTH_FLAGS] == 0);
    FWT_CHECK_EQ(radio_encode_payload(&p, &h, buf, sizeof expect + 1), 0);  /* does not fit */
    p.n_bands = 0;
    FWT_CHECK_EQ(radio_encode_payload(&p, &h, buf, sizeof buf), 0);
    p.n_bands = 65;
    FWT_CHECK_EQ(radio_encode_payload(&p, &h, buf, sizeof buf), 0);
    p.n_bands = 64; p.width = 0;
    FWT_CHECK_EQ(radio_encode_payload(&p, &h, buf, sizeof buf), 0);
    p.width = 1024;
    FWT_CHECK_EQ(radio_encode_payload(&p, &h, buf, sizeof buf), 100);
}

static void test_api_frame(void)
{
    uint8_t buf[RADIO_MAX_FRAME];
    uint8_t rf[RADIO_MAX_RF_DATA + 1];
    uint8_t esc[4];
    static const uint8_t special[] = { 0x7E, 0x7D, 0x11, 0x13 };
    uint32_t n, i;
    uint8_t sum = 0;
    n = radio_encode_api_frame((const uint8_t *)"Hi", 2, 0x1234, 1, buf, sizeof buf);
    FWT_CHECK_EQ(n, 11);
    FWT_CHECK(buf[0] == 0x7E && buf[1] == 0 && buf[2] == 7);
    FWT_CHECK(buf[3] == 0x01 && buf[4] == 1 && buf[5] == 0x12 && buf[6] == 0x34 && buf[7] == 0);
    FWT_CHECK(buf[8] == 'H' && buf[9] == 'i');
    for (i = 3; i < n; i++) {
        sum = (uint8_t)(sum + buf[i]);
    }
    FWT_CHECK_EQ(sum, 0xFF);
    /* escaping: every special byte becomes 0x7D, b ^ 0x20 */
    FWT_CHECK_EQ(radio_escape(special, 4, buf, sizeof buf), 8);
    FWT_CHECK(buf[0] == 0x7D && buf[1] == 0x5E && buf[2] == 0x7D && buf[3] == 0x5D &&
              buf[4] == 0x7D && buf[5] == 0x31 && buf[6] == 0x7D && buf[7] == 0x33);
    FWT_CHECK_EQ(radio_escape(special, 4, esc, 4), 0);            /* does not fit */
    /* a frame id of 0x7E and destination 0x7D11 are escaped too */
    n = radio_encode_api_frame((const uint8_t *)"A", 1, 0x7D11, 0x7E, buf, sizeof buf);
    FWT_CHECK_EQ(n, 10 + 3);
    for (i = 1; i < n; i++) {
        FWT_CHECK(buf[i] != 0x7E && buf[i] != 0x11 && buf[i] != 0x13);
    }
    memset(rf, 0xEE, sizeof rf);
    FWT_CHECK_EQ(radio_encode_api_frame(rf, 100, 1, 1, buf, sizeof buf), 109);
    FWT_CHECK_EQ(radio_encode_api_frame(rf, 101, 1, 1, buf, sizeof buf), 0);
    FWT_CHECK_EQ(radio_encode_api_frame(rf, 100, 1, 1, buf, 108), 0);
    memset(rf, 0x7E, sizeof rf);                                  /* worst case fits */
    FWT_CHECK(radio_encode_api_frame(rf, 100, 0x7E7E, 0x7E, buf, sizeof buf) > 200);
}

static void test_band_of_column(void)
{
    uint32_t w, n, x;
    static const uint16_t widths[] = { 64, 100, 741, 752, 1024 };
    static const uint8_t ns[] = { 1, 7, 32, 64 };
    int ok = 1;
    for (w = 0; w < 5; w++) {
        for (n = 0; n < 4; n++) {
            for (x = 0; x < widths[w]; x++) {
                uint32_t b = radio_band_of_column((uint16_t)x, widths[w], ns[n]);
                if (!(b * widths[w] / ns[n] <= x && x < (b + 1) * widths[w] / ns[n])) {
                    ok = 0;
                }
            }
        }
    }
    FWT_CHECK(ok);
}

static void test_summary_bands_and_floors(void)
{
    /* band boundaries as radio_band_of_column; every column's floor is its band's
     * min_support-th largest (0 before), 255 from the width on */
    static radio_summary_t s;
    static const uint16_t widths[] = { 64, 100, 741, 752, RADIO_MAX_WIDTH };
    static const uint8_t ns[] = { 1, 7, 32, 64 };
    uint32_t w, n, x, seed = 7u;
    int ok = 1;
    for (w = 0; w < 5; w++) {
        for (n = 0; n < 4; n++) {
            FWT_CHECK_EQ(radio_summary_init(&s, widths[w], ns[n], 2u), FW_OK);
            for (x = 0; x < 4u * widths[w]; x++) {
                seed = seed * 1103515245u + 12345u;
                radio_summary_add(&s, (uint16_t)((seed >> 8) % widths[w]), (uint8_t)(seed >> 24));
            }
            for (x = 0; x < RADIO_FLOOR_COLUMNS; x++) {
                uint32_t b = x < widths[w] ? radio_band_of_column((uint16_t)x, widths[w], ns[n]) : 0u;
                uint32_t want = x >= widths[w] ? 0xFFu : (s.count[b] == 2u ? s.top[b][1] : 0u);
                if (s.floor[x] != want) {
                    ok = 0;
                }
            }
        }
    }
    FWT_CHECK(ok);
    FWT_CHECK_EQ(radio_summary_init(&s, RADIO_MAX_WIDTH + 1u, 32, 3), FW_ERR_PARAM);
}

/* Brute force: the min_support-th largest disparity of the band. */
static uint8_t reference_band(const uint16_t *xs, const uint8_t *ds, uint32_t n, uint32_t band,
                              uint16_t width, uint8_t nb, uint8_t k)
{
    uint8_t best = 0;
    uint32_t d;
    for (d = 255; d >= 1; d--) {
        uint32_t i, c = 0;
        for (i = 0; i < n; i++) {
            if (xs[i] < width && ds[i] >= d && radio_band_of_column(xs[i], width, nb) == band) {
                c++;
            }
        }
        if (c >= k) {
            best = (uint8_t)d;
            break;
        }
    }
    return best;
}

static void test_summary_matches_reference(void)
{
    static radio_summary_t s;
    uint16_t xs[600];
    uint8_t ds[600];
    uint8_t bands[RADIO_MAX_BANDS];
    uint32_t seed = 12345u, i, b, k;
    int ok = 1;
    for (i = 0; i < 600; i++) {
        seed = seed * 1103515245u + 12345u;
        xs[i] = (uint16_t)((seed >> 8) % 800u);   /* some beyond the width */
        seed = seed * 1103515245u + 12345u;
        ds[i] = (uint8_t)((seed >> 8) % 64u);     /* some zero */
    }
    for (k = 1; k <= RADIO_MAX_MIN_SUPPORT; k++) {
        FWT_CHECK_EQ(radio_summary_init(&s, 752, 32, (uint8_t)k), FW_OK);
        for (i = 0; i < 600; i++) {
            radio_summary_add(&s, xs[i], ds[i]);
        }
        radio_summary_finish(&s, bands);
        for (b = 0; b < 32; b++) {
            if (bands[b] != reference_band(xs, ds, 600, b, 752, 32, (uint8_t)k)) {
                ok = 0;
            }
        }
    }
    FWT_CHECK(ok);
}

static void test_summary_outliers_and_params(void)
{
    static radio_summary_t s;
    uint8_t bands[RADIO_MAX_BANDS];
    FWT_CHECK_EQ(radio_summary_init(&s, 752, 32, 3), FW_OK);
    radio_summary_add(&s, 1, 20); radio_summary_add(&s, 2, 21); radio_summary_add(&s, 3, 22);
    radio_summary_add(&s, 6, 60); radio_summary_add(&s, 7, 60);      /* two outliers */
    radio_summary_add(&s, 30, 40); radio_summary_add(&s, 31, 40);    /* band 1: too few */
    radio_summary_finish(&s, bands);
    FWT_CHECK_EQ(bands[0], 22);
    FWT_CHECK_EQ(bands[1], 0);
    FWT_CHECK_EQ(radio_summary_init(&s, 752, 0, 3), FW_ERR_PARAM);
    FWT_CHECK_EQ(radio_summary_init(&s, 752, 65, 3), FW_ERR_PARAM);
    FWT_CHECK_EQ(radio_summary_init(&s, 752, 32, 0), FW_ERR_PARAM);
    FWT_CHECK_EQ(radio_summary_init(&s, 752, 32, 9), FW_ERR_PARAM);
    FWT_CHECK_EQ(radio_summary_init(&s, 16, 32, 3), FW_ERR_PARAM);
}

static void test_link_budget(void)
{
    /* 115200 baud 8N1: 11520 bytes/s, 1152 bytes per 100 ms; default packet 68 + 9 bytes */
    FWT_CHECK(RADIO_HEADER_LEN + RADIO_DEFAULT_BANDS + RADIO_CRC_LEN == 68u);
    FWT_CHECK(RADIO_HEADER_LEN + RADIO_MAX_BANDS + RADIO_CRC_LEN <= RADIO_MAX_RF_DATA);
    FWT_CHECK(RADIO_MAX_FRAME <= 1152u / 5u);  /* even fully escaped: < 20 % of the line */
}

void suite_radio(void)
{
    FWT_RUN(test_crc_check_value);
    FWT_RUN(test_payload_bytes);
    FWT_RUN(test_api_frame);
    FWT_RUN(test_band_of_column);
    FWT_RUN(test_summary_bands_and_floors);
    FWT_RUN(test_summary_matches_reference);
    FWT_RUN(test_summary_outliers_and_params);
    FWT_RUN(test_link_budget);
}
