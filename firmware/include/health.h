/**
 * @file health.h
 * Health of the video path (HEALTH_* registers, docs/registers.md), reported every period.
 *
 * radio_health_t is owned by radio.h (the radio engineer's encoder takes it); until that header
 * defines it, it is declared here, guarded by RADIO_HEALTH_DEFINED.
 */
#ifndef HEALTH_H
#define HEALTH_H

#include <stdint.h>

#ifndef RADIO_HEALTH_DEFINED
#define RADIO_HEALTH_DEFINED
/** Counts since the last report, saturating at 0xFFFF. */
typedef struct {
    uint16_t frames;         /**< frames the matcher finished */
    uint16_t pairs_ok;       /**< pairs of two well-formed frames */
    uint16_t mispaired;      /**< pairs abandoned: a frame was malformed */
    uint16_t drops;          /**< frames without partner dropped by the pairing */
    uint16_t cam_errors[2];  /**< BT.656 malformed lines, left and right */
    uint16_t matcher_errors; /**< matcher malformed-stream errors */
    uint16_t fifo_overflow;  /**< camera FIFO overflow pixels (both) + result FIFO overflow */
    uint8_t flags;           /**< RADIO_HEALTH_* bits */
} radio_health_t;
#endif

#define RADIO_HEALTH_LEFT_LOCKED  0x01u /**< left decoder locked (ADV7180 STATUS1 and stream) */
#define RADIO_HEALTH_RIGHT_LOCKED 0x02u /**< right decoder locked */
#define RADIO_HEALTH_ENABLED      0x04u /**< video path enabled */
#define RADIO_HEALTH_HUE_FALLBACK 0x08u /**< ground model falls back to luminance */

/** Raw 16-bit counter values at the last report (the hardware counters wrap or saturate). */
typedef struct {
    uint16_t frames, pairs_ok, mispaired, drops, cam_errors[2], matcher_errors, overflow[2],
        result_overflow;
} health_snapshot_t;

#endif /* HEALTH_H */
