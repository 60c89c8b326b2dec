/**
 * @file radio.h
 * Radio packets: XBee 802.15.4 API frames in API mode 2 (escaped), "TX Request, 16-bit
 * address" (API id 0x01), carrying pose with its timestamp, the SoC's health counters and a
 * per-column-band obstacle summary, protected by a CRC-16/CCITT-FALSE.
 *
 * The payload layout, its constants and the CRC parameters are defined once, in
 * station/wire.py, which generates radio_wire.h (offsets RADIO_OFF_*); the layout table is in
 * that file's docstring. tests/test_radio_firmware.py checks these encoders byte for byte
 * against station.radio, and tests/test_radio.py that radio_wire.h is current.
 *
 * Serialisation writes bytes one by one with shifts: the result does not depend on the
 * CPU's byte order (a MicroBlaze may be big- or little-endian).
 */
#ifndef RADIO_H
#define RADIO_H

#include <stdint.h>
#include "fw_status.h"
#include "radio_wire.h"

/** Largest escaped TX16 frame: the buffer size radio_encode_api_frame needs at most. */
#define RADIO_MAX_FRAME XBEE_MAX_ESCAPED_FRAME

/** SoC health since the last report (counts saturate at 65535). Filled in by app.c. */
typedef struct {
    uint16_t frames;
    uint16_t pairs_ok;
    uint16_t mispaired;
    uint16_t drops;
    uint16_t cam_errors[2];
    uint16_t matcher_errors;
    uint16_t fifo_overflow;
    uint8_t flags;  /**< RADIO_HEALTH_LEFT_LOCKED, _RIGHT_LOCKED, _PIPELINE_ENABLED, _HUE_FALLBACK,
                         _RECT_FAULT, _RADIO_FAULT, _DECODER_FAULT, _CAMERA_LOST (bit0 left
                         decoder locked and its camera not lost since the last report, bit1
                         right, bit2 pipeline enabled, bit3 hue fallback to luma, bit4
                         rectification not running, bit5 the XBee does not answer, bit6 a
                         decoder did not take its IIC configuration, bit7 a camera lost since
                         the last report, its locked bit clear; station/wire.py) */
    int16_t camera_skew_us;      /**< HEALTH_SKEW.us: right field start minus left of the last
                                      pair of field starts, microseconds (docs/camera.md) */
    uint16_t camera_skew_pairs;  /**< pairs of field starts measured since the last report
                                      (0: camera_skew_us is not new) */
} radio_health_t;

typedef struct {
    uint8_t seq;
    uint16_t frame;
    uint32_t pose_ms;    /**< time the pose was taken, ms (robot clock, wraps) */
    int16_t x_mm;
    int16_t y_mm;
    uint16_t theta;      /**< 65536 units per full turn */
    uint16_t width;      /**< image width in pixels */
    uint8_t n_bands;     /**< 1..64 */
    uint8_t bands[RADIO_MAX_BANDS];
} radio_packet_t;

/** CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, MSB first, no final XOR) of data. */
uint16_t radio_crc16(const uint8_t *data, uint32_t len);

/** Serialise the payload (health NULL = all zero) into buf, CRC last. Returns the length
 *  (RADIO_HEADER_LEN + n_bands + RADIO_CRC_LEN), 0 if it does not fit in cap or
 *  n_bands/width is out of range. */
uint32_t radio_encode_payload(const radio_packet_t *pkt, const radio_health_t *health,
                              uint8_t *buf, uint32_t cap);

/** Escape (API mode 2) src[0..len) into dst; 0x7E, 0x7D, 0x11, 0x13 become 0x7D, b ^ 0x20.
 *  Returns the escaped length, 0 if it does not fit in cap (or len is 0). */
uint32_t radio_escape(const uint8_t *src, uint32_t len, uint8_t *dst, uint32_t cap);

/** Any API frame (mode 2) around frame_data[0..len) (API id first). Returns the escaped
 *  frame length, 0 on error. */
uint32_t radio_encode_frame(const uint8_t *frame_data, uint32_t len, uint8_t *buf,
                            uint32_t cap);

/** Wrap rf_data (<= 100 bytes) in an escaped TX16 frame (options 0). Returns the frame
 *  length (rf_len + 9 plus one byte per escaped byte), 0 on error. */
uint32_t radio_encode_api_frame(const uint8_t *rf_data, uint32_t rf_len, uint16_t dest,
                                uint8_t frame_id, uint8_t *buf, uint32_t cap);

/**
 * Per-band obstacle summary: the nearest obstacle disparity of a band is the largest d such
 * that at least min_support matches in the band have a disparity >= d, i.e. the
 * min_support-th largest disparity (0 if fewer matches). Band i covers columns
 * [i*width/n, (i+1)*width/n). Memory: min_support largest disparities per band, kept sorted.
 *
 * Adding a match costs a few instructions and no multiply or divide, so that a slow CPU
 * without a divider (a RISC-V rv32ic core) keeps up with the result FIFO: every column has a
 * floor, the disparity a match must exceed to change its band (the band's min_support-th
 * largest once it has that many, else 0), and most matches fail that one test. Only a match
 * that passes finds its band, walking the band boundaries (start, placed by
 * radio_summary_init with one divide per band) from the band of the previous one, and
 * raises the floor of the band's columns when the band's min_support-th largest rises.
 * Columns from width on have the floor 255, so they, like d = 0, are ignored by the same test.
 */
#define RADIO_MAX_WIDTH 1024u       /**< widest image: RESULT.x has 10 bits */
/** Columns with a floor byte: an NTSC field is 720 wide, a WVGA sensor's 752; the matches of
 *  wider images' last columns take the slower path (their band's list decides). A build that
 *  never calls radio_summary_add (the image that reads the SoC's summary unit, bands_hw.h)
 *  defines it as 1 and spares the bytes. */
#ifndef RADIO_FLOOR_COLUMNS
#define RADIO_FLOOR_COLUMNS 768u
#endif
/** The largest min_support a summary keeps room for (top's second dimension). The image that
 *  merges the SoC's summary unit (bands_hw.h) can only use min_support <= BANDS_HW_SLOTS, so it
 *  defines it as that and spares the other slots of every band. */
#ifndef RADIO_SUMMARY_MAX_SUPPORT
#define RADIO_SUMMARY_MAX_SUPPORT RADIO_MAX_MIN_SUPPORT
#endif

typedef struct {
    uint16_t width;
    uint8_t n_bands;
    uint8_t min_support;
    uint8_t count[RADIO_MAX_BANDS];
    uint8_t top[RADIO_MAX_BANDS][RADIO_SUMMARY_MAX_SUPPORT]; /**< descending */
    uint16_t start[RADIO_MAX_BANDS + 1u]; /**< first column of each band; start[n_bands] = width */
    uint8_t band;                         /**< band of the last match kept: where a walk starts */
    uint8_t floor[RADIO_FLOOR_COLUMNS];   /**< per column: a match must exceed it to count */
} radio_summary_t;

fw_status_t radio_summary_init(radio_summary_t *s, uint16_t width, uint8_t n_bands,
                               uint8_t min_support);
/** Start again with no match, keeping the geometry radio_summary_init set (no divide). */
void radio_summary_clear(radio_summary_t *s);
/** Add one match; x >= width or d == 0 are ignored. width at most RADIO_MAX_WIDTH. */
void radio_summary_add(radio_summary_t *s, uint16_t x, uint8_t d);
/** Write the n_bands results into bands. */
void radio_summary_finish(const radio_summary_t *s, uint8_t *bands);
/** Band of column x. */
uint8_t radio_band_of_column(uint16_t x, uint16_t width, uint8_t n_bands);

#endif /* RADIO_H */
