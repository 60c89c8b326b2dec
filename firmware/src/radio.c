/**
 * @file radio.c
 * Payload (layout in station/wire.py, offsets in radio_wire.h), CRC-16/CCITT-FALSE and
 * escaped XBee API frames (API mode 2).
 */
#include "radio.h"
#include "hal.h"

static void put_u16(uint8_t *p, uint16_t v)
{
    p[0] = (uint8_t)(v >> 8);
    p[1] = (uint8_t)(v & 0xFFu);
}

static void put_u32(uint8_t *p, uint32_t v)
{
    put_u16(p, (uint16_t)(v >> 16));
    put_u16(p + 2, (uint16_t)(v & 0xFFFFu));
}

uint16_t radio_crc16(const uint8_t *data, uint32_t len)
{
    uint16_t crc = RADIO_CRC_INIT;
    uint32_t i;
    uint32_t bit;
    for (i = 0u; i < len; i++) {
        crc = (uint16_t)(crc ^ ((uint16_t)data[i] << 8));
        for (bit = 0u; bit < 8u; bit++) {
            crc = (crc & 0x8000u) != 0u ? (uint16_t)((crc << 1) ^ RADIO_CRC_POLY)
                                        : (uint16_t)(crc << 1);
        }
    }
    return crc;
}

uint32_t radio_encode_payload(const radio_packet_t *pkt, const radio_health_t *health,
                              uint8_t *buf, uint32_t cap)
{
    static const radio_health_t none;
    uint32_t n;
    uint32_t i;
    if (pkt == NULL || buf == NULL || pkt->n_bands == 0u || pkt->n_bands > RADIO_MAX_BANDS ||
        pkt->width == 0u || cap < RADIO_HEADER_LEN + (uint32_t)pkt->n_bands + RADIO_CRC_LEN) {
        return 0u;
    }
    if (health == NULL) {
        health = &none;
    }
    buf[RADIO_OFF_TYPE] = RADIO_PAYLOAD_TYPE;
    buf[RADIO_OFF_SEQ] = pkt->seq;
    put_u16(&buf[RADIO_OFF_FRAME], pkt->frame);
    put_u32(&buf[RADIO_OFF_POSE_MS], pkt->pose_ms);
    /* two's complement by conversion to uint16_t: defined for every int16_t value */
    put_u16(&buf[RADIO_OFF_X_MM], (uint16_t)pkt->x_mm);
    put_u16(&buf[RADIO_OFF_Y_MM], (uint16_t)pkt->y_mm);
    put_u16(&buf[RADIO_OFF_THETA], pkt->theta);
    put_u16(&buf[RADIO_OFF_WIDTH], pkt->width);
    put_u16(&buf[RADIO_OFF_HEALTH_FRAMES], health->frames);
    put_u16(&buf[RADIO_OFF_HEALTH_PAIRS_OK], health->pairs_ok);
    put_u16(&buf[RADIO_OFF_HEALTH_MISPAIRED], health->mispaired);
    put_u16(&buf[RADIO_OFF_HEALTH_DROPS], health->drops);
    put_u16(&buf[RADIO_OFF_HEALTH_CAM_ERRORS0], health->cam_errors[0]);
    put_u16(&buf[RADIO_OFF_HEALTH_CAM_ERRORS1], health->cam_errors[1]);
    put_u16(&buf[RADIO_OFF_HEALTH_MATCHER_ERRORS], health->matcher_errors);
    put_u16(&buf[RADIO_OFF_HEALTH_FIFO_OVERFLOW], health->fifo_overflow);
    buf[RADIO_OFF_HEALTH_FLAGS] = health->flags;
    buf[RADIO_OFF_N_BANDS] = pkt->n_bands;
    n = RADIO_HEADER_LEN;
    for (i = 0u; i < pkt->n_bands; i++) {
        buf[n++] = pkt->bands[i];
    }
    put_u16(&buf[n], radio_crc16(buf, n));
    return n + RADIO_CRC_LEN;
}

uint32_t radio_escape(const uint8_t *src, uint32_t len, uint8_t *dst, uint32_t cap)
{
    uint32_t n = 0u;
    uint32_t i;
    for (i = 0u; i < len; i++) {
        uint8_t b = src[i];
        if (b == XBEE_START || b == XBEE_ESCAPE || b == XBEE_XON || b == XBEE_XOFF) {
            if (n + 2u > cap) {
                return 0u;
            }
            dst[n++] = XBEE_ESCAPE;
            dst[n++] = (uint8_t)(b ^ XBEE_ESCAPE_XOR);
        } else {
            if (n + 1u > cap) {
                return 0u;
            }
            dst[n++] = b;
        }
    }
    return n;
}

uint32_t radio_encode_frame(const uint8_t *frame_data, uint32_t len, uint8_t *buf,
                            uint32_t cap)
{
    uint8_t hdr[2];
    uint8_t ck;
    uint8_t sum = 0u;
    uint32_t n;
    uint32_t m;
    uint32_t i;
    if (frame_data == NULL || buf == NULL || len == 0u || len > 0xFFFFu || cap < 1u) {
        return 0u;
    }
    for (i = 0u; i < len; i++) {
        sum = (uint8_t)(sum + frame_data[i]);
    }
    ck = (uint8_t)(0xFFu - sum);
    put_u16(hdr, (uint16_t)len);
    buf[0] = XBEE_START;
    n = 1u;
    m = radio_escape(hdr, 2u, &buf[n], cap - n);
    if (m == 0u) {
        return 0u;
    }
    n += m;
    m = radio_escape(frame_data, len, &buf[n], cap - n);
    if (m == 0u) {
        return 0u;
    }
    n += m;
    m = radio_escape(&ck, 1u, &buf[n], cap - n);
    if (m == 0u) {
        return 0u;
    }
    return n + m;
}

uint32_t radio_encode_api_frame(const uint8_t *rf_data, uint32_t rf_len, uint16_t dest,
                                uint8_t frame_id, uint8_t *buf, uint32_t cap)
{
    uint8_t data[XBEE_API_OVERHEAD - 4u + RADIO_MAX_RF_DATA]; /* TX16 header + RF data */
    uint32_t i;
    if ((rf_data == NULL && rf_len != 0u) || rf_len > RADIO_MAX_RF_DATA) {
        return 0u;
    }
    data[0] = XBEE_API_TX16;
    data[1] = frame_id;
    put_u16(&data[2], dest);
    data[4] = 0x00u; /* options: ACK enabled, no broadcast PAN */
    for (i = 0u; i < rf_len; i++) {
        data[5u + i] = rf_data[i];
    }
    return radio_encode_frame(data, 5u + rf_len, buf, cap);
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
        width > RADIO_MAX_WIDTH || min_support == 0u ||
        min_support > RADIO_SUMMARY_MAX_SUPPORT) {
        return FW_ERR_PARAM;
    }
    s->width = width;
    s->n_bands = n_bands;
    s->min_support = min_support;
    s->band = 0u;
    for (i = 0u; i < RADIO_MAX_BANDS; i++) {
        s->count[i] = 0u;
    }
    /* band i: columns [i*width/n, (i+1)*width/n), as radio_band_of_column */
    for (i = 0u; i <= n_bands; i++) {
        s->start[i] = (uint16_t)(i * width / n_bands);
    }
    for (i = 0u; i < RADIO_FLOOR_COLUMNS; i++) {
        s->floor[i] = i < width ? 0u : 0xFFu;
    }
    return FW_OK;
}

void radio_summary_clear(radio_summary_t *s)
{
    uint32_t i;
    for (i = 0u; i < s->n_bands; i++) {
        s->count[i] = 0u;
    }
    for (i = 0u; i < s->width && i < RADIO_FLOOR_COLUMNS; i++) {
        s->floor[i] = 0u;
    }
}

/* Insert d (above its column's floor) into the descending list of the band of column x. */
static void summary_insert(radio_summary_t *s, uint32_t x, uint8_t d)
{
    uint32_t b = s->band;
    uint32_t k = s->min_support;
    uint8_t *top;
    uint32_t n;
    uint32_t j;
    /* start[0] = 0 <= x < width = start[n_bands]: both walks stop inside the bands */
    while (x >= s->start[b + 1u]) {
        b++;
    }
    while (x < s->start[b]) {
        b--;
    }
    s->band = (uint8_t)b;
    top = s->top[b];
    n = s->count[b];
    if (n == k) {
        if (d <= top[k - 1u]) {
            return;                 /* not among the min_support largest */
        }
        n--;                        /* drop the smallest kept */
    }
    j = n;
    while (j > 0u && top[j - 1u] < d) {
        top[j] = top[j - 1u];
        j--;
    }
    top[j] = d;
    n++;
    s->count[b] = (uint8_t)n;
    if (n == k) {                   /* the band's floor: its min_support-th largest */
        for (j = s->start[b]; j < s->start[b + 1u] && j < RADIO_FLOOR_COLUMNS; j++) {
            s->floor[j] = top[k - 1u];
        }
    }
}

void radio_summary_add(radio_summary_t *s, uint16_t x, uint8_t d)
{
    if (x < RADIO_FLOOR_COLUMNS) {
        if (d > s->floor[x]) {      /* never for d = 0 or x >= width */
            summary_insert(s, x, d);
        }
    } else if (x < s->width && d != 0u) {
        summary_insert(s, x, d);
    }
}

void radio_summary_finish(const radio_summary_t *s, uint8_t *bands)
{
    uint32_t i;
    for (i = 0u; i < s->n_bands; i++) {
        bands[i] = s->count[i] >= s->min_support ? s->top[i][s->min_support - 1u] : 0u;
    }
}
