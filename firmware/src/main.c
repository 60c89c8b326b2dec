/**
 * @file main.c
 * Target entry point (MicroBlaze MCS): start-up, then one radio report every 100 ms.
 * Not part of the host library; the host build only compiles it to keep it honest.
 */
#include "app.h"
#include "hal.h"
#include "stereo_regs.h"
#include "pose.h"
#include "xbee.h"

#define REPORT_PERIOD_US 100000u
#define COLLECT_PERIOD_US 2000u  /**< drain the result FIFO every 2 ms (it holds 512 records) */

static app_t app;
static pose_t pose;
static uint8_t frame_buf[RADIO_MAX_FRAME];

int main(void)
{
    static const xbee_config_t radio_cfg = { XBEE_ROBOT_ADDR, XBEE_STATION_ADDR, XBEE_PAN_ID };
    xbee_io_t radio_io;
    /* the radio module: API mode 2 at 115200 baud (a failure leaves the reports unheard but
     * the pipeline running) */
    xbee_mcs_io(&radio_io);
    (void)xbee_configure(&radio_io, &radio_cfg, NULL);
    /* decoders first; a failed decoder is reported in app.dec_status and the pipeline
     * still runs on whatever the other camera provides */
    (void)app_init_decoders(&app, STEREO_IIC_BASEADDR, 0u);
    if (app_init_pipeline(&app, STEREO_BASEADDR) != FW_OK) {
        for (;;) {
            hal_delay_us(REPORT_PERIOD_US); /* wrong bitstream: stay silent */
        }
    }
    for (;;) {
        uint32_t i;
        for (i = 0u; i < REPORT_PERIOD_US / COLLECT_PERIOD_US; i++) {
            (void)app_collect(&app);
            hal_delay_us(COLLECT_PERIOD_US);
        }
        /* the motion controller's pose (pose.h); the last good one if it is being updated */
        (void)pose_read(POSE_BASEADDR, &pose);
        (void)app_report(&app, pose.x_mm, pose.y_mm, pose.theta, frame_buf, sizeof frame_buf);
    }
}
