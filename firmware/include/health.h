/**
 * @file health.h
 * Health of the video path (HEALTH_* registers, docs/registers.md), reported every period in
 * the radio packet's radio_health_t (radio.h, flag bits RADIO_HEALTH_* in radio_wire.h).
 */
#ifndef HEALTH_H
#define HEALTH_H

#include <stdint.h>
#include "radio.h"

/** Raw 16-bit counter values at the last report (the hardware counters wrap or saturate). */
typedef struct {
    uint16_t frames, pairs_ok, mispaired, drops, cam_errors[2], matcher_errors, overflow[2],
        result_overflow, skew_pairs;
} health_snapshot_t;

#endif /* HEALTH_H */
