/**
 * @file main.c
 * Target entry point (the soft CPU: the SoC's RISC-V core, firmware/rv32, or a MicroBlaze):
 * start-up, then one radio report every 100 ms. Not part of the host library.
 *
 * Nothing here waits without a bound and no failure is silent: every period the firmware
 * retries what has not come up (the register block, the decoders' lock, the video path; a
 * decoder that did not take its configuration, flagged DECODER_FAULT, every
 * DECODER_RETRY_PERIODS periods), reads the health registers (app_read_health: decoder lock,
 * enable, camera and matcher errors, drops, overflow, a camera lost at any time in the period:
 * every step gathers the live loss bits, app_watch_health) and sends the radio report, so the
 * base station sees a module that is not running and why (flags: locked bits and the enabled
 * bit stay 0, the fault bits set).
 *
 * Two ways to the summary, chosen at build time: the records drained from the result FIFO
 * (app_collect), or, with FIRMWARE_BANDS_HW (the image for the SoC's own RISC-V core,
 * `make -C firmware rv32`), the SoC's per-band summary unit (bands_hw.h), whose summary of
 * each frame is merged once a frame: the core is too slow to read every record of a busy
 * row, the unit sees them all.
 */
#include "app.h"
#include "hal.h"
#include "stereo_regs.h"
#include "pose.h"
#include "rect_table.h"
#include "xbee.h"
#ifdef FIRMWARE_BANDS_HW
#include "bands_hw.h"
/** The summary keeps room for every disparity a band word of the unit brings
 *  (the build's RADIO_SUMMARY_MAX_SUPPORT, firmware/Makefile). */
typedef char main_summary_holds_the_units_slots[
    (BANDS_HW_SLOTS <= RADIO_SUMMARY_MAX_SUPPORT) ? 1 : -1];
#endif

#define REPORT_PERIOD_US 100000u
/** The result FIFO is drained whenever it holds records; when a drain found fewer than
 *  COLLECT_FEW, the CPU sleeps COLLECT_SLEEP_US first (the timer's WAIT). The FIFO holds 256
 *  records: far more than the pipeline's average rate fills in that sleep, so the records of
 *  a busy row wait in it while the CPU works through them. The period is measured with the
 *  timer, so a slow CPU keeps the 100 ms. */
#ifdef FIRMWARE_BANDS_HW
/** With the summary unit a step only looks for a published frame (its summary waits a whole
 *  frame time, 16.7 ms, in the unit) and sends a byte of the report (one every 87 us). */
#define COLLECT_SLEEP_US 100u
#else
#define COLLECT_SLEEP_US 25u
#endif
#define PERIOD_CYCLES (REPORT_PERIOD_US * (HAL_CPU_HZ / 1000000u))
/** A field lasts 16.7 ms: the report waits at most that much for the end of a frame. */
#define FRAME_WAIT_CYCLES (17000u * (HAL_CPU_HZ / 1000000u))
#define COLLECT_FEW 4u
/** app_start_video checks the lock once: it is checked again every period, and meanwhile
 *  the records of the frames that do come are drained. */
#define LOCK_POLLS 0u
#define DECODER_TRIES 2u
/** A decoder whose configuration still failed after those tries (the health flag
 *  DECODER_FAULT, app_read_health) is configured again every DECODER_RETRY_PERIODS periods,
 *  at the start of a period: a decoder that does not answer costs one IIC address byte, one
 *  that answers again its reset and table (app_retry_decoders), after which the flag clears.
 *  A build may give another period (-DDECODER_RETRY_PERIODS=n, 1..255), as the
 *  simulation's test of a missing decoder does to see retries in a short run. */
#ifndef DECODER_RETRY_PERIODS
#define DECODER_RETRY_PERIODS 20u
#endif
/** A radio module that did not answer its configuration is queried again (xbee_probe_query,
 *  between two reports) every RADIO_RETRY_PERIODS periods; its answer is looked for in every
 *  step, so the frame loop never waits for it. A build may give another period
 *  (-DRADIO_RETRY_PERIODS=n, at least 1: firmware/Makefile FIRMWARE_DEFS), as the simulation's
 *  test of a missing module does to see several retries in a short run. */
#ifndef RADIO_RETRY_PERIODS
#define RADIO_RETRY_PERIODS 20u
#endif

static app_t app;
static pose_t pose;
static uint8_t frame_buf[RADIO_MAX_FRAME];
static radio_health_t health;
static uint32_t tx_len;         /**< the report being sent: frame_buf[tx_pos..tx_len) waits */
static uint32_t tx_pos;
static xbee_io_t radio_io;
static uint8_t radio_fault;     /**< RADIO_HEALTH_RADIO_FAULT until the module answers */
static xbee_probe_t radio_probe;
#ifdef FIRMWARE_BANDS_HW
static bands_hw_t bands;
static uint16_t bands_drops;    /**< DROPS.records at the last report */
#endif

/** One step of the period: the next byte of the report being sent, a drain of the result
 *  FIFO (or the merge of a frame the summary unit published), and a short sleep when there
 *  was little to do. Returns what was collected: records, or frames merged. */
static uint32_t step(void)
{
    uint32_t n;
    uint8_t b;
    /* a module that did not answer: its answer to the last query, if it came */
    if (radio_fault != 0u && radio_io.read(radio_io.ctx, &b) != 0 &&
        xbee_probe_feed(&radio_probe, b) != 0) {
        radio_fault = 0u;
    }
    /* the report goes out a byte at a time between drains: the UART takes a byte every
     * 87 us, far longer than the FIFO could wait */
    if (tx_pos < tx_len && hal_uart_put(frame_buf[tx_pos]) != 0) {
        tx_pos++;
    }
    /* a camera lost only for a moment between two reports is still reported (CAMERA_LOST) */
    app_watch_health(&app);
    n = app_collect(&app);
#ifdef FIRMWARE_BANDS_HW
    /* app_collect opened the summary; the unit's frames go into it */
    n = bands_hw_collect(&bands, &app.summary);
    if (n == 0u) {
        hal_delay_us(COLLECT_SLEEP_US);
    }
#else
    if (n < COLLECT_FEW) {
        hal_delay_us(COLLECT_SLEEP_US);
    }
#endif
    return n;
}

int main(void)
{
    static const xbee_config_t radio_cfg = { XBEE_ROBOT_ADDR, XBEE_STATION_ADDR, XBEE_PAN_ID };
    fw_status_t st_dec, st_pipe, st_video = FW_ERR_NO_LOCK;
    uint8_t rect_fault = 0u;        /* RADIO_HEALTH_RECT_FAULT when the rectifier is not on */
    uint8_t decoders_locked = 0u;
    uint8_t decoder_tries = 0u;
    uint8_t decoder_wait = 0u;      /* periods since the last retry of a decoder */
    uint8_t radio_wait = 0u;
    uint32_t start;
    /* the radio module: API mode 2 at 115200 baud. A failure keeps the pipeline running and
     * the reports going out at 115200 (a module in transparent mode may still pass them on),
     * flagged RADIO_FAULT until the module answers a query */
    xbee_uart_io(&radio_io);
    if (xbee_configure(&radio_io, &radio_cfg, NULL) != FW_OK) {
        radio_fault = RADIO_HEALTH_RADIO_FAULT;
        radio_io.set_baud(radio_io.ctx, XBEE_LINK_BAUD);
    }
    st_dec = app_init_decoders(&app, STEREO_IIC_BASEADDR, 0u);
    st_pipe = app_init_pipeline(&app, STEREO_BASEADDR);
#if RECT_TABLE_PRESENT
    /* the calibration's rectification: its maps in the bitstream, checked, then enabled; a
     * build that cannot take it is reported in every health record (RECT_FAULT) */
#if RECT_LEFT_TABLE_PRESENT
    if (rect_setup_both(STEREO_RECT_BASEADDR, &rect_table, STEREO_RECT_LEFT_BASEADDR,
                        &rect_left_table) != FW_OK) {
#else
    if (rect_setup(STEREO_RECT_BASEADDR, &rect_table) != FW_OK) {
#endif
        rect_fault = RADIO_HEALTH_RECT_FAULT;
    }
#endif
    (void)app_collect(&app);        /* the summary's band boundaries, before any record */
#ifdef FIRMWARE_BANDS_HW
    (void)bands_hw_init(&bands, BANDS_HW_BASEADDR, app.width, app.n_bands);
#endif
    start = hal_ticks();
    for (;;) {
        /* a decoder not configured, once the register block answers: again in each period
         * of the start-up's tries below, then every DECODER_RETRY_PERIODS periods */
        if (st_pipe == FW_OK && st_dec != FW_OK &&
            (!decoders_locked || ++decoder_wait >= DECODER_RETRY_PERIODS)) {
            decoder_wait = 0u;
            st_dec = app_retry_decoders(&app);
        }
        if (st_pipe != FW_OK) {
            st_pipe = app_init_pipeline(&app, STEREO_BASEADDR);      /* wrong bitstream? */
        } else if (st_video != FW_OK) {
            if (!decoders_locked) {
                /* ADV7180 STATUS1, over IIC: once, then the streams' lock (HEALTH_STATUS). A
                 * decoder that does not answer is retried DECODER_TRIES periods, then the
                 * video path starts without it (it runs on its power-up defaults, or its
                 * stream never locks: the health flags show which) */
                decoders_locked = (uint8_t)((st_dec == FW_OK && app_check_lock(&app) == FW_OK) ||
                                            ++decoder_tries >= DECODER_TRIES);
            }
            if (decoders_locked) {
                st_video = app_start_video(&app, LOCK_POLLS);
            }
        }
        do {
            step();
        } while ((uint32_t)(hal_ticks() - start) < PERIOD_CYCLES);
        start += PERIOD_CYCLES;
#ifdef FIRMWARE_BANDS_HW
        /* the report right after the end of the frame in progress (its summary merged), at
         * most FRAME_WAIT_US later */
        while (step() == 0u && (uint32_t)(hal_ticks() - start) < FRAME_WAIT_CYCLES) {
        }
#else
        /* the report's work in the vertical blanking, when no records come: after the end
         * of the frame in progress (FRAME_COUNT steps), at most FRAME_WAIT_US later */
        {
            uint32_t frame = STEREO_ReadReg(STEREO_BASEADDR, STEREO_FRAME_COUNT_OFFSET);
            while (STEREO_ReadReg(STEREO_BASEADDR, STEREO_FRAME_COUNT_OFFSET) == frame &&
                   (uint32_t)(hal_ticks() - start) < FRAME_WAIT_CYCLES) {
                step();
            }
        }
#endif
        /* flags 0 (not locked, not enabled) when the register block does not answer */
        if (app_read_health(&app, &health) != FW_OK) {
            health.flags = 0u;
        }
#ifdef FIRMWARE_BANDS_HW
        {
            /* records the summary unit lost count as overflow */
            uint16_t drops = (uint16_t)Xil_In32(BANDS_HW_BASEADDR + BANDS_HW_DROPS_OFFSET);
            health.fifo_overflow = (uint16_t)(health.fifo_overflow + (uint16_t)(drops - bands_drops));
            bands_drops = drops;
        }
#endif
        health.flags |= (uint8_t)(rect_fault | radio_fault);
        /* the motion controller's pose (pose.h); the last good one if it is being updated */
        (void)pose_read(POSE_BASEADDR, &pose);
        if (tx_pos >= tx_len) {         /* the last report is out */
            if (radio_fault != 0u && ++radio_wait >= RADIO_RETRY_PERIODS) {
                radio_wait = 0u;        /* 8 bytes: under a millisecond at 115200 baud */
                xbee_probe_query(frame_buf);
                (void)hal_uart_write(frame_buf, XBEE_PROBE_QUERY_LEN);
            }
            tx_len = app_build_report(&app, pose.x_mm, pose.y_mm, pose.theta, pose.t_ms,
                                      &health, frame_buf, sizeof frame_buf);
            tx_pos = 0u;
        }
        if ((uint32_t)(hal_ticks() - start) >= PERIOD_CYCLES) {
            start = hal_ticks();        /* fell a period behind: start afresh */
        }
    }
}
