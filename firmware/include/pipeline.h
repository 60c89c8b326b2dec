/**
 * @file pipeline.h
 * Stereo pipeline configuration and per-frame readout, through the generated stereo_regs.h.
 */
#ifndef PIPELINE_H
#define PIPELINE_H

#include <stdint.h>
#include "fw_status.h"
#include "stereo_regs.h"

/** Every run-time parameter of the pipeline: one member per register field of
 *  STEREO_CONFIG_FIELDS (generated from hdl/regmap.py), named as the field (meanings:
 *  docs/registers.md). */
#define PIPELINE_CONFIG_MEMBER(R, F, m, T) T m;
typedef struct {
    STEREO_CONFIG_FIELDS(PIPELINE_CONFIG_MEMBER)
} pipeline_config_t;

/** One record of the result FIFO: a matched obstacle-edge pixel, or (mark != 0) an
 *  end-of-frame marker (x, y, d = 0). */
typedef struct {
    uint16_t x;
    uint16_t y;
    uint8_t d;
    uint8_t mark;            /**< 0 a match; PIPELINE_MARK_EOF, | PIPELINE_MARK_ABORT */
} pipeline_match_t;

#define PIPELINE_MARK_EOF   0x01u /**< end of a frame's records */
#define PIPELINE_MARK_ABORT 0x02u /**< that frame was cut by a video restart: discard it */

/** Status snapshot. */
typedef struct {
    uint32_t frames;
    uint16_t left_errors, left_dropped;
    uint16_t right_errors, right_dropped;
    uint16_t match_errors, match_dropped;
    uint32_t edges, sad_evals, matches, rejects, drops;
    uint16_t fifo_level, fifo_overflow;
    uint8_t left_ground_learned, left_hue_fallback;    /**< GROUND_STATUS */
    uint8_t right_ground_learned, right_hue_fallback;
} pipeline_status_t;

/** The register block's reset values (from the generated header). */
void pipeline_default_config(pipeline_config_t *cfg);
/** Check the ID register (magic and map version). */
fw_status_t pipeline_check_id(uint32_t base);
/** Validate and write every parameter; reads each register back (FW_ERR_PARAM on a range
 *  error, nothing written; FW_ERR_ID if a read-back differs). */
fw_status_t pipeline_configure(uint32_t base, const pipeline_config_t *cfg);
/** Read every parameter register back into cfg. */
void pipeline_read_config(uint32_t base, pipeline_config_t *cfg);
void pipeline_read_status(uint32_t base, pipeline_status_t *st);
/** Pop up to `max` results; returns how many were stored. Stops at an empty FIFO. */
uint32_t pipeline_read_results(uint32_t base, pipeline_match_t *out, uint32_t max);
void pipeline_clear_errors(uint32_t base);
/** Enable (1) or disable (0, held in reset) the video path: cameras, pairing, pipeline. */
void pipeline_video_enable(uint32_t base, uint32_t on);
/** Restart the video path (CTRL.restart_video): it resumes at the next field start. */
void pipeline_restart_video(uint32_t base);
void pipeline_flush_results(uint32_t base);

#endif /* PIPELINE_H */
