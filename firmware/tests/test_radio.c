/* Radio payload, API frame and per-band summary. */
#include "fwtest.h"
#include "radio.h"

#include <string.h>

static void test_payload_bytes(void)
{
    radio_packet_t p;
    uint8_t buf[RADIO_MAX_RF_DATA];
    static const uint8_t expect[] = { 0xA1, 0x12, 0x34, 0x56, 0xFF, 0xFE, 0x12, 0x34, 0xC0,
                                      0x00, 0x02, 0xF0, 3, 0, 5, 63 };
    memset(&p, 0, sizeof p);
    p.seq = 0x12; p.frame = 0x3456; p.x_mm = -2; p.y_mm = 0x1234; p.theta = 0xC000;
    p.width = 752; p.n_bands = 3; p.bands[0] = 0; p.bands[1] = 5; p.bands[2] = 63;
    FWT_CHECK_EQ(radio_encode_payload(&p, buf, sizeof buf), sizeof expect);
    FWT_CHECK(memcmp(buf, expect, sizeof expect) == 0);
    FWT_CHECK_EQ(radio_encode_payload(&p, buf, 15), 0);  /* does not fit */
    p.n_bands = 0;
    FWT_CHECK_EQ(radio_encode_payload(&p, buf, sizeof buf), 0);
    p.n_bands = 65;
    FWT_CHECK_EQ(radio_encode_payload(&p, buf, sizeof buf), 0);
    p.n_bands = 64; p.width = 0;
    FWT_CHECK_EQ(radio_encode_payload(&p, buf, sizeof buf), 0);
    p.width = 1024;
    FWT_CHECK_EQ(radio_encode_payload(&p, buf, sizeof buf), 77);
}

static void test_api_frame(void)
{
    uint8_t buf[RADIO_MAX_FRAME];
    uint8_t rf[RADIO_MAX_RF_DATA + 1];
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
    memset(rf, 0xEE, sizeof rf);
    FWT_CHECK_EQ(radio_encode_api_frame(rf, 100, 1, 1, buf, sizeof buf), 109);
    FWT_CHECK_EQ(radio_encode_api_frame(rf, 101, 1, 1, buf, sizeof buf), 0);
    FWT_CHECK_EQ(radio_encode_api_frame(rf, 100, 1, 1, buf, 108), 0);
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
    /* 115200 baud 8N1: 11520 bytes/s, 1152 bytes per 100 ms */
    FWT_CHECK(RADIO_HEADER_LEN + RADIO_DEFAULT_BANDS + RADIO_API_OVERHEAD == 54u);
    FWT_CHECK(RADIO_HEADER_LEN + RADIO_MAX_BANDS + RADIO_API_OVERHEAD <= 1152u / 10u);
    FWT_CHECK(RADIO_HEADER_LEN + RADIO_MAX_BANDS <= RADIO_MAX_RF_DATA);
}

void suite_radio(void)
{
    FWT_RUN(test_payload_bytes);
    FWT_RUN(test_api_frame);
    FWT_RUN(test_band_of_column);
    FWT_RUN(test_summary_matches_reference);
    FWT_RUN(test_summary_outliers_and_params);
    FWT_RUN(test_link_budget);
}
