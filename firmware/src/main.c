/**
 * @file main.c
 * Target entry point (the soft CPU: the SoC's RISC-V core, firmware/rv32, or a MicroBlaze):
 * start-up, then one radio report every 100 ms. Not part of the host library.
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
/** The result FIFO is drained whenever it holds records; when a drain found fewer than
 *  COLLECT_FEW, the CPU sleeps COLLECT_SLEEP_US first (the timer's WAIT). The FIFO holds 256
 *  records: far more than the pipeline's average rate fills in that sleep, so the records of
 *  a busy row wait in it while the CPU works through them. The period is measured with the
 *  timer, so a slow CPU keeps the 100 ms. */
#define COLLECT_SLEEP_US 100u
#define COLLECT_FEW 16u
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
        uint32_t start;
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
        start = hal_ticks();
        do {
            if (app_collect(&app) < COLLECT_FEW) {
                hal_delay_us(COLLECT_SLEEP_US);
            }
        } while ((uint32_t)(hal_ticks() - start) < REPORT_PERIOD_US * (HAL_CPU_HZ / 1000000u));
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
