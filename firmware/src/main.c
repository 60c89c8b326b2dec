/**
 * @file main.c
 * Target entry point (MicroBlaze): start-up, then one radio report every 100 ms.
 * Not part of the host library; the host build only compiles it to keep it honest.
 *
 * Nothing here waits without a bound and no failure is silent: every period the firmware
 * retries what has not come up (the register block, the decoders' lock, the video path),
 * reads the health registers (app_read_health: decoder lock, enable, camera and matcher
 * errors, drops, overflow) and sends the radio report, so the base station sees a module that
 * is not running and why (flags: locked bits and the enabled bit stay 0).
 */
#include "app.h"
#include "hal.h"
#include "stereo_regs.h"
#include "pose.h"
#include "xbee.h"

#define REPORT_PERIOD_US 100000u
/** Drain the result FIFO every 1 ms: it holds 256 records, well above what the motorcycle
 *  pair gives in a millisecond on average (``python -m sim system --scene motorcycle``). */
#define COLLECT_PERIOD_US 1000u
#define LOCK_POLLS 40u           /**< app_start_video: 40 x 50 us, about 2 fields */

static app_t app;
static pose_t pose;
static uint8_t frame_buf[RADIO_MAX_FRAME];
static radio_health_t health;

int main(void)
{
    static const xbee_config_t radio_cfg = { XBEE_ROBOT_ADDR, XBEE_STATION_ADDR, XBEE_PAN_ID };
    xbee_io_t radio_io;
    fw_status_t st_dec, st_pipe, st_video = FW_ERR_NO_LOCK;
    /* the radio module: API mode 2 at 115200 baud (a failure leaves the reports unheard but
     * the pipeline running) */
    xbee_uart_io(&radio_io);
    (void)xbee_configure(&radio_io, &radio_cfg, NULL);
    st_dec = app_init_decoders(&app, STEREO_IIC_BASEADDR, 0u);
    st_pipe = app_init_pipeline(&app, STEREO_BASEADDR);
    for (;;) {
        uint32_t i;
        if (st_pipe != FW_OK) {
            st_pipe = app_init_pipeline(&app, STEREO_BASEADDR);      /* wrong bitstream? */
        } else if (st_video != FW_OK) {
            if (st_dec != FW_OK) {
                st_dec = app_init_decoders(&app, STEREO_IIC_BASEADDR, 0u);
            }
            if (st_dec == FW_OK && app_check_lock(&app) == FW_OK) {  /* ADV7180 STATUS1 */
                st_video = app_start_video(&app, LOCK_POLLS);
            }
        }
        for (i = 0u; i < REPORT_PERIOD_US / COLLECT_PERIOD_US; i++) {
            (void)app_collect(&app);
            hal_delay_us(COLLECT_PERIOD_US);
        }
        /* flags 0 (not locked, not enabled) when the register block does not answer */
        if (app_read_health(&app, &health) != FW_OK) {
            health.flags = 0u;
        }
        /* the motion controller's pose (pose.h); the last good one if it is being updated */
        (void)pose_read(POSE_BASEADDR, &pose);
        (void)app_report(&app, pose.x_mm, pose.y_mm, pose.theta, pose.t_ms, &health, frame_buf,
                         sizeof frame_buf);
    }
}
