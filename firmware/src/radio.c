/**
 * @file radio.c
 * XBee API frames and the obstacle payload (layout in radio.h and station/radio.py).
 */
#include "radio.h"
#include "hal.h"

static uint32_t put_u16(uint8_t *p, uint16_t v)
{
    p[0] = (uint8_t)(v >> 8);
    p[1] = (uint8_t)(v & 0xFFu);
    return 2u;
}

uint32_t radio_encode_payload(const radio_packet_t *pkt, uint8_t *buf, uint32_t cap)
{
    uint32_t n = 0u;
    uint32_t i;
    if (pkt == NULL || buf == NULL || pkt->n_bands == 0u || pkt->n_bands > RADIO_MAX_BANDS ||
        pkt->width == 0u || cap < RADIO_HEADER_LEN + (uint32_t)pkt->n_bands) {
        return 0u;
    }
    buf[n++] = RADIO_PAYLOAD_TYPE;
    buf[n++] = pkt->seq;
    n += put_u16(&buf[n], pkt->frame);
    /* two's complement by conversion to uint16_t: defined for every int16_t value */
    n += put_u16(&buf[n], (uint16_t)pkt->x_mm);
    n += put_u16(&buf[n], (uint16_t)pkt->y_mm);
    n += put_u16(&buf[n], pkt->theta);
    n += put_u16(&buf[n], pkt->width);
    buf[n++] = pkt->n_bands;
    for (i = 0u; i < pkt->n_bands; i++) {
        buf[n++] = pkt->bands[i];
    }
    return n;
}

uint32_t radio_encode_api_frame(const uint8_t *rf_data, uint32_t rf_len, uint16_t dest,
                                uint8_t frame_id, uint8_t *buf, uint32_t cap)
{
    uint32_t n = 0u;
    uint32_t i;
    uint32_t length = 5u + rf_len; /* API id, frame id, dest (2), options, RF data */
    uint8_t sum = 0u;
    if (buf == NULL || (rf_data == NULL && rf_len != 0u) || rf_len > RADIO_MAX_RF_DATA ||
        cap < rf_len + RADIO_API_OVERHEAD) {
        return 0u;
    }
    buf[n++] = 0x7Eu;
    n += put_u16(&buf[n], (uint16_t)length);
    buf[n++] = RADIO_API_TX16;
    buf[n++] = frame_id;
    n += put_u16(&buf[n], dest);
    buf[n++] = 0x00u; /* options: ACK enabled, no broadcast PAN */
    for (i = 0u; i < rf_len; i++) {
        buf[n++] = rf_data[i];
    }
    for (i = 3u; i < n; i++) {
        sum = (uint8_t)(sum + buf[i]);
    }
    buf[n++] = (uint8_t)(0xFFu - sum);
    return n;
}

uint8_t radio_band_of_column(uint16_t x, uint16_t width, uint8_t n_bands)
{
    /* the i with i*width/n <= x < (i+1)*width/n (integer division) */
    return (uint8_t)((((uint32_t)x + 1u) * n_bands - 1u) / width);
}

fw_status_t radio_summary_init(radio_summary_t *s, uint16_t width, uint8_t n_bands,
                               uint8_t min_support)
{
    uint32_t i;
    if (s == NULL || n_bands == 0u || n_bands > RADIO_MAX_BANDS || width < n_bands ||
        min_support == 0u || min_support > RADIO_MAX_MIN_SUPPORT) {
        return FW_ERR_PARAM;
    }
    s->width = width;
    s->n_bands = n_bands;
    s->min_support = min_support;
    for (i = 0u; i < RADIO_MAX_BANDS; i++) {
        s->count[i] = 0u;
    }
    return FW_OK;
}

void radio_summary_add(radio_summary_t *s, uint16_t x, uint8_t d)
{
    uint8_t b;
    uint8_t *top;
    uint32_t n;
    uint32_t j;
    if (x >= s->width || d == 0u) {
        return;
    }
    b = radio_band_of_column(x, s->width, s->n_bands);
    top = s->top[b];
    n = s->count[b];
    if (n == s->min_support) {
        if (d <= top[n - 1u]) {
            return;                 /* not among the min_support largest */
        }
        n--;                        /* drop the smallest kept */
    }
    /* insertion into the descending list */
    j = n;
    while (j > 0u && top[j - 1u] < d) {
        top[j] = top[j - 1u];
        j--;
    }
    top[j] = d;
    s->count[b] = (uint8_t)(n + 1u);
}

void radio_summary_finish(const radio_summary_t *s, uint8_t *bands)
{
    uint32_t i;
    for (i = 0u; i < s->n_bands; i++) {
        bands[i] = s->count[i] >= s->min_support ? s->top[i][s->min_support - 1u] : 0u;
    }
}
