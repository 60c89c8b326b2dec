/**
 * @file radio.h
 * Radio packets: XBee 802.15.4 API "TX Request, 16-bit address" frames (API id 0x01)
 * carrying pose and a per-column-band obstacle summary. The payload layout (version 1,
 * big-endian) is defined in station/radio.py, the one definition the base station uses;
 * tests/test_radio_firmware.py cross-checks these encoders against it.
 *
 *   off size field
 *   0   1    0xA1 payload type/version
 *   1   1    seq (u8, wraps)
 *   2   2    frame counter (u16)
 *   4   2    x_mm (i16)
 *   6   2    y_mm (i16)
 *   8   2    theta (u16, 65536 per turn)
 *   10  2    image width (u16)
 *   12  1    n_bands (1..64)
 *   13  n    nearest obstacle disparity per band (u8, 0 = none)
 *
 * Serialisation writes bytes one by one with shifts: the result does not depend on the
 * CPU's byte order (a MicroBlaze may be big- or little-endian).
 */
#ifndef RADIO_H
#define RADIO_H

#include <stdint.h>
#include "fw_status.h"

#define RADIO_PAYLOAD_TYPE      0xA1u
#define RADIO_HEADER_LEN        13u
#define RADIO_MAX_BANDS         64u
#define RADIO_DEFAULT_BANDS     32u
#define RADIO_MAX_RF_DATA       100u
#define RADIO_API_TX16          0x01u
#define RADIO_API_OVERHEAD      9u    /**< 0x7E, length (2), API id, frame id, dest (2), options, checksum */
#define RADIO_MAX_FRAME         (RADIO_MAX_RF_DATA + RADIO_API_OVERHEAD)
#define RADIO_DEFAULT_MIN_SUPPORT 3u
#define RADIO_MAX_MIN_SUPPORT   8u

typedef struct {
    uint8_t seq;
    uint16_t frame;
    int16_t x_mm;
    int16_t y_mm;
    uint16_t theta;      /**< 65536 units per full turn */
    uint16_t width;      /**< image width in pixels */
    uint8_t n_bands;     /**< 1..64 */
    uint8_t bands[RADIO_MAX_BANDS];
} radio_packet_t;

/** Serialise the payload into buf. Returns the length (13 + n_bands), 0 if it does not fit
 *  in cap or n_bands/width is out of range. */
uint32_t radio_encode_payload(const radio_packet_t *pkt, uint8_t *buf, uint32_t cap);

/** Wrap rf_data (<= 100 bytes) in an API frame (options 0). Returns the frame length
 *  (rf_len + 9), 0 on error. */
uint32_t radio_encode_api_frame(const uint8_t *rf_data, uint32_t rf_len, uint16_t dest,
                                uint8_t frame_id, uint8_t *buf, uint32_t cap);

/**
 * Per-band obstacle summary: the nearest obstacle disparity of a band is the largest d such
 * that at least min_support matches in the band have a disparity >= d, i.e. the
 * min_support-th largest disparity (0 if fewer matches). Band i covers columns
 * [i*width/n, (i+1)*width/n). Memory: min_support largest disparities per band, kept sorted.
 */
typedef struct {
    uint16_t width;
    uint8_t n_bands;
    uint8_t min_support;
    uint8_t count[RADIO_MAX_BANDS];
    uint8_t top[RADIO_MAX_BANDS][RADIO_MAX_MIN_SUPPORT]; /**< descending */
} radio_summary_t;

fw_status_t radio_summary_init(radio_summary_t *s, uint16_t width, uint8_t n_bands,
                               uint8_t min_support);
/** Add one match; x >= width or d == 0 are ignored. */
void radio_summary_add(radio_summary_t *s, uint16_t x, uint8_t d);
/** Write the n_bands results into bands. */
void radio_summary_finish(const radio_summary_t *s, uint8_t *bands);
/** Band of column x. */
uint8_t radio_band_of_column(uint16_t x, uint16_t width, uint8_t n_bands);

#endif /* RADIO_H */
