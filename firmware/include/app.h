/**
 * @file app.h
 * Firmware application: start-up (decoders, pipeline) and the per-period radio report.
 * Host builds export these for the co-simulation (build/firmware/libfirmware.so).
 */
#ifndef APP_H
#define APP_H

#include <stdint.h>
#include "adv7180.h"
#include "health.h"
#include "iic.h"
#include "pipeline.h"
#include "radio.h"

#define APP_N_DECODERS 2u
/** Frame geometry: one NTSC field of the ADV7180 (BT.656, 720 x 240); the register reset
 *  values place the ground reference region for it (hdl/regmap.py REF_WIDTH, REF_HEIGHT;
 *  tests/test_regs.py checks they agree). */
#define APP_FIELD_WIDTH  720u
#define APP_FIELD_HEIGHT 240u
#define APP_RADIO_DEST 0x0001u /**< base station's 16-bit XBee address */

typedef struct {
    uint32_t regs_base;
    iic_dev_t iic;
    adv7180_t dec[APP_N_DECODERS];
    fw_status_t dec_status[APP_N_DECODERS]; /**< result of each decoder's start-up */
    pipeline_config_t cfg;
    uint8_t seq;
    uint8_t n_bands;
    uint8_t min_support;
    uint16_t width;
    uint32_t results_read;  /**< results summarised into the last report */
    uint8_t summary_open;   /**< summary holds results collected since the last report */
    radio_summary_t summary;
    health_snapshot_t health_last; /**< counters at the last app_read_health */
} app_t;

/** Reset the IIC controller and start both decoders (0x20 then 0x21; the second is set up
 *  even if the first fails). Returns the first error, FW_OK if both started. */
fw_status_t app_init_decoders(app_t *app, uint32_t iic_base, uint32_t iic_timeout_polls);

/** Start again the decoders whose start-up failed (after app_init_decoders), leaving the
 *  rest of the application's state (report sequence, summary) as it is. Returns the first
 *  error, FW_OK when both have started. */
fw_status_t app_retry_decoders(app_t *app);

/** Check the register block's ID and write the default configuration, the floor decision's
 *  included (app_floor_start). */
fw_status_t app_init_pipeline(app_t *app, uint32_t regs_base);

/** The floor decision (docs/floor.md). At start-up the rig's floor line (FLOOR_LINE's reset
 *  value: the nominal rig seen in one NTSC field) with the default tolerance, enabled: the
 *  SoC flags every record on the floor (RESULT.floor) and no floor point enters the radio
 *  summary. With APP_FLOOR_LEARN (host builds; a target build needs memory for a frame's
 *  records, APP_FLOOR_RECORDS of them at 20 bytes each) the line is learned from each frame's
 *  records (floor_learn, within the rig's line's reach) and written for the frames after it:
 *  the SoC loads it at the end of the frame in progress (golden.floor.FloorModel, lag 2). */
#ifndef APP_FLOOR_LEARN
#ifdef HAL_TARGET
#define APP_FLOOR_LEARN 0
#else
#define APP_FLOOR_LEARN 1
#endif
#endif
#ifndef APP_FLOOR_RECORDS
#define APP_FLOOR_RECORDS 8192u
#endif
/** The learning's steepest slope (1/256 px a row): a field's rows are two of the frame's, so
 *  its floor line is twice as steep as golden.floor.FloorParams' frames allow. */
#define APP_FLOOR_SLOPE_MAX 320u
void app_floor_start(uint32_t regs_base);
/** A rig of another geometry (a calibration, another frame size): its floor line (slope in
 *  1/256 px a row, 0..1023; offset in 1/256 px, 18 bits signed) replaces the nominal rig's, in
 *  FLOOR_LINE and as the learning's start and prior. FW_ERR_PARAM outside the fields. */
fw_status_t app_floor_rig(uint32_t regs_base, uint16_t slope, int32_t offset);
/** One record of the frame being read (learning only; beyond APP_FLOOR_RECORDS a frame is
 *  not learned from). */
void app_floor_add(uint16_t y, uint16_t d16);
/** A frame's end-of-frame marker (abort: a cut frame, not learned from): learn the line from
 *  its records and write it (FLOOR_LINE) when it changed. Returns 1 when a new line was
 *  written, 0 otherwise. */
int app_floor_end(uint32_t regs_base, int abort);

/** Drain the result FIFO into the running per-band summary: the records it held when the
 *  call began (RESULT_LEVEL), at most APP_COLLECT_MAX, one RESULT read each (and RESULT_EXT
 *  with APP_FLOOR_LEARN); floor points (RESULT.floor) stay out of the summary, end-of-frame
 *  markers end a frame of the floor's learning. Call it often: at 60 frames/s a report period spans 6
 *  frames, more results than the FIFO holds. Returns the number of results read. */
#define APP_COLLECT_MAX 4096u
/** Built with FIRMWARE_BANDS_HW (the SoC's summary unit takes the records, bands_hw.h), it
 *  only opens the summary, for bands_hw_collect to merge into, and returns 0. */
uint32_t app_collect(app_t *app);

/** Collect, close the summary of everything collected since the last report, build the API
 *  frame into buf (at least RADIO_MAX_FRAME bytes), send it with hal_uart_write, start a new
 *  summary. Returns the frame length, 0 on error. */
uint32_t app_report(app_t *app, int16_t x_mm, int16_t y_mm, uint16_t theta, uint32_t pose_ms,
                    const radio_health_t *health, uint8_t *buf, uint32_t cap);

/** app_report without the sending: the API frame in buf (the sequence number advances);
 *  returns its length, 0 on error. For a caller that sends it a byte at a time
 *  (hal_uart_put) while it goes on draining the result FIFO. */
uint32_t app_build_report(app_t *app, int16_t x_mm, int16_t y_mm, uint16_t theta,
                          uint32_t pose_ms, const radio_health_t *health, uint8_t *buf,
                          uint32_t cap);

/** Read each decoder's lock (ADV7180 STATUS1: IN_LOCK and FSC_LOCK) over IIC. Returns
 *  FW_OK when both are locked, FW_ERR_NO_LOCK when one is not, or the IIC error. */
fw_status_t app_check_lock(app_t *app);

/** Enable the video path and wait, at most `polls` times APP_LOCK_POLL_US, until both camera
 *  streams are locked (HEALTH_STATUS); FW_ERR_NO_LOCK (path left enabled) on time-out. */
fw_status_t app_start_video(app_t *app, uint32_t polls);

#define APP_LOCK_POLL_US 50u

/** Restart the video path (CTRL.restart_video) and re-base the health counts (the restart
 *  clears the video path's counters). */
void app_restart_video(app_t *app);

/** Read the HEALTH_* registers and fill h with the counts since the previous call (16-bit
 *  differences, so a wrapped counter still counts right; a saturated one stops counting) and
 *  the flags. Returns FW_ERR_PARAM on NULL pointers, FW_ERR_ID if the register block does not
 *  answer (ID check), FW_OK otherwise. */
fw_status_t app_read_health(app_t *app, radio_health_t *h);

#endif /* APP_H */
