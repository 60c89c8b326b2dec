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

/** One record of the result FIFO (RESULT, then RESULT_EXT): a matched obstacle-edge pixel,
 *  or (mark != 0) an end-of-frame marker (x, y, d, d16, conf = 0). */
typedef struct {
    uint16_t x;
    uint16_t y;
    uint8_t d;
    uint8_t mark;            /**< a match: 0, or PIPELINE_MARK_FLOOR; a marker:
                                  PIPELINE_MARK_EOF, | PIPELINE_MARK_ABORT */
    uint16_t d16;            /**< subpixel disparity, 1/16 px: 16 d + offset (-8..8) */
    uint8_t conf;            /**< confidence 0..255 */
} pipeline_match_t;

#define PIPELINE_MARK_EOF   0x01u /**< end of a frame's records */
#define PIPELINE_MARK_ABORT 0x02u /**< that frame was cut by a video restart: discard it */
#define PIPELINE_MARK_FLOOR 0x04u /**< a match on the floor (RESULT.floor): not an obstacle */

/** Status snapshot. */
typedef struct {
    uint32_t frames;
    uint16_t left_errors, left_dropped;
    uint16_t right_errors, right_dropped;
    uint16_t match_errors, match_dropped;
    uint32_t edges, evaluations, matches, rejects, drops;
    uint16_t fifo_level, fifo_overflow;
    uint8_t left_ground_learned, left_hue_fallback;    /**< GROUND_STATUS */
    uint8_t right_ground_learned, right_hue_fallback;
} pipeline_status_t;

/** Free space per column band (FREE_CFG, FREE_LEFT_k, FREE_RIGHT_k; golden/freespace.py):
 *  per band, the image row of the lowest obstacle run, scanning up from the bottom row. */
#define PIPELINE_FREE_BANDS 16u
#define PIPELINE_FREE_NONE  0xFFFFu /**< the band has no obstacle run, or lies past the image */

typedef struct {
    uint16_t left[PIPELINE_FREE_BANDS];  /**< left camera, band 0 (x from 0) first */
    uint16_t right[PIPELINE_FREE_BANDS]; /**< right camera */
} pipeline_free_space_t;

/** The register block's reset values (from the generated header). */
void pipeline_default_config(pipeline_config_t *cfg);
/** Check the ID register (magic and map version). */
fw_status_t pipeline_check_id(uint32_t base);
/** Validate and write every parameter; reads each register back (FW_ERR_PARAM on a range
 *  error, nothing written; FW_ERR_ID if a read-back differs). */
fw_status_t pipeline_configure(uint32_t base, const pipeline_config_t *cfg);
/** Set the matcher's disparity window only (MATCH.d_min / d_max; the other MATCH fields are
 *  kept): d_min <= d_max, d_max - d_min < STEREO_MATCH_SPAN (64), else FW_ERR_PARAM and
 *  nothing is written. The matcher latches the window at a frame's start, so a write at any
 *  time applies from the next frame on: a robot alternates a far window (0..63: 1.14 m and
 *  beyond on the default rig) and a near one (117..180: 0.40 m to 0.62 m) between frames,
 *  tagging each frame's records with the window it was written for. Reads MATCH back
 *  (FW_ERR_ID when it differs). */
fw_status_t pipeline_set_window(uint32_t base, uint8_t d_min, uint8_t d_max);
/** Read every parameter register back into cfg. */
void pipeline_read_config(uint32_t base, pipeline_config_t *cfg);
void pipeline_read_status(uint32_t base, pipeline_status_t *st);
/** Pop up to `max` results (each a RESULT read, then a RESULT_EXT read for its second
 *  half); returns how many were stored. Stops at an empty FIFO. */
uint32_t pipeline_read_results(uint32_t base, pipeline_match_t *out, uint32_t max);
/** Write FREE_CFG: band_w columns per band (1..2047), obstacle runs of run_r rows (1..255).
 *  FW_ERR_PARAM (nothing written) out of range; FW_ERR_ID if the read-back differs. */
fw_status_t pipeline_configure_free_space(uint32_t base, uint16_t band_w, uint8_t run_r);
/** Read both cameras' free space of the last frame (16 + 16 rows, PIPELINE_FREE_NONE where a
 *  band has none). Call it once a frame's end-of-frame marker has been read: the registers
 *  change only in the 16 cycles after each frame of the front ends, which come before the
 *  matcher's marker of that frame. FW_ERR_PARAM on NULL. */
fw_status_t pipeline_read_free_space(uint32_t base, pipeline_free_space_t *fs);
void pipeline_clear_errors(uint32_t base);
/** Enable (1) or disable (0, held in reset) the video path: cameras, pairing, pipeline. */
void pipeline_video_enable(uint32_t base, uint32_t on);
/** Restart the video path (CTRL.restart_video): it resumes at the next field start. */
void pipeline_restart_video(uint32_t base);
void pipeline_flush_results(uint32_t base);

#endif /* PIPELINE_H */
