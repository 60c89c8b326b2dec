/* ADV7180 driver: ID, reset, init table, lock, error paths, two decoders on one bus. */
#include "adv7180.h"
#include "app.h"
#include "fwtest.h"
#include "hal.h"
#include "sim_xiic.h"
#include "stereo_regs.h"

static sim_xiic_t sim;
static iic_dev_t iic;

static void setup(void)
{
    sim_init(&sim, STEREO_IIC_BASEADDR);
    sim_install(&sim);
    iic_init(&iic, STEREO_IIC_BASEADDR, 500u);
}

/* The device's registers equal the init table (last write wins), and only table registers
 * were written after the reset. */
static int matches_table(const sim_dev_t *d)
{
    uint8_t expect[256];
    uint8_t in_table[256] = { 0 };
    uint32_t i;
    for (i = 0u; i < adv7180_ntsc_init_len; i++) {
        expect[adv7180_ntsc_init[i].reg] = adv7180_ntsc_init[i].val;
        in_table[adv7180_ntsc_init[i].reg] = 1u;
    }
    for (i = 0u; i < 256u; i++) {
        if (in_table[i] != d->written[i] || (in_table[i] && d->regs[i] != expect[i])) {
            printf("  register 0x%02X: written %d value 0x%02X\n", (unsigned)i, d->written[i],
                   d->regs[i]);
            return 0;
        }
    }
    return d->writes == adv7180_ntsc_init_len;
}

static void test_bind_checks_address(void)
{
    adv7180_t dec;
    setup();
    FWT_CHECK_EQ(adv7180_bind(&dec, &iic, 0x22), FW_ERR_PARAM);
    FWT_CHECK_EQ(adv7180_bind(&dec, &iic, 0x20), FW_OK);
    FWT_CHECK_EQ(adv7180_bind(&dec, NULL, 0x20), FW_ERR_PARAM);
}

static void test_init_writes_table(void)
{
    adv7180_t dec;
    sim_dev_t *d;
    uint8_t locked = 0u;
    setup();
    d = sim_add_adv7180(&sim, 0x20);
    adv7180_bind(&dec, &iic, 0x20);
    FWT_CHECK_EQ(adv7180_init(&dec), FW_OK);
    FWT_CHECK(matches_table(d));
    FWT_CHECK_EQ(dec.failed_entry, -1);
    FWT_CHECK(sim.delays_us >= ADV7180_RESET_POLL_US); /* waited after the reset */
    FWT_CHECK_EQ(adv7180_lock_status(&dec, &locked), FW_OK);
    FWT_CHECK_EQ(locked, 1);
    d->regs[0x10] = 0x02; /* lost lock */
    FWT_CHECK_EQ(adv7180_lock_status(&dec, &locked), FW_OK);
    FWT_CHECK_EQ(locked, 0);
    FWT_CHECK_EQ(dec.status1, 0x02);
}

static void test_wrong_id(void)
{
    adv7180_t dec;
    sim_dev_t *d;
    setup();
    d = sim_add_adv7180(&sim, 0x21);
    d->regs[0x11] = 0x41; /* an ADV7182 */
    adv7180_bind(&dec, &iic, 0x21);
    FWT_CHECK_EQ(adv7180_init(&dec), FW_ERR_ID);
    FWT_CHECK_EQ(d->writes, 0);
}

static void test_reset_never_ends(void)
{
    adv7180_t dec;
    sim_dev_t *d;
    setup();
    d = sim_add_adv7180(&sim, 0x20);
    d->busy_after_reset = 1000;
    adv7180_bind(&dec, &iic, 0x20);
    FWT_CHECK_EQ(adv7180_init(&dec), FW_ERR_TIMEOUT);
    /* only the delays take time here: the deadline passes after its number of polls */
    FWT_CHECK_EQ(sim.delays_us, ADV7180_RESET_TIMEOUT_US);
}

static void test_reset_wait_counts_the_bus_time(void)
{
    /* each bus access costs 5 us, a poll's IIC read about 0.1 ms: the deadline passes after
     * fewer polls than with free reads, within one poll of it */
    adv7180_t dec;
    sim_dev_t *d;
    uint32_t t0, elapsed;
    setup();
    d = sim_add_adv7180(&sim, 0x20);
    d->busy_after_reset = 1000;
    adv7180_bind(&dec, &iic, 0x20);
    sim_clock(&sim, 5u * HAL_TICKS_PER_US, 0u - 1000u);
    t0 = hal_ticks();
    FWT_CHECK_EQ(adv7180_reset(&dec), FW_ERR_TIMEOUT);
    elapsed = hal_ticks() - t0;
    FWT_CHECK(sim.delays_us < ADV7180_RESET_TIMEOUT_US);
    FWT_CHECK(elapsed >= ADV7180_RESET_TIMEOUT_US * HAL_TICKS_PER_US);
    FWT_CHECK(elapsed <= (ADV7180_RESET_TIMEOUT_US + 2u * ADV7180_RESET_POLL_US) * HAL_TICKS_PER_US);
    sim_uninstall();
}

static void test_nack_and_stuck(void)
{
    adv7180_t dec;
    sim_dev_t *d;
    setup();
    d = sim_add_adv7180(&sim, 0x20);
    d->nack = 1;
    adv7180_bind(&dec, &iic, 0x20);
    FWT_CHECK_EQ(adv7180_init(&dec), FW_ERR_NACK);
    setup();
    d = sim_add_adv7180(&sim, 0x20);
    d->hold_scl = 1;
    adv7180_bind(&dec, &iic, 0x20);
    FWT_CHECK_EQ(adv7180_init(&dec), FW_ERR_TIMEOUT);
}

static void test_two_decoders(void)
{
    static app_t app;
    sim_dev_t *a, *b;
    setup();
    a = sim_add_adv7180(&sim, 0x20);
    b = sim_add_adv7180(&sim, 0x21);
    FWT_CHECK_EQ(app_init_decoders(&app, STEREO_IIC_BASEADDR, 500u), FW_OK);
    FWT_CHECK(matches_table(a));
    FWT_CHECK(matches_table(b));
    /* the second decoder is still set up when the first one is missing */
    setup();
    b = sim_add_adv7180(&sim, 0x21);
    FWT_CHECK_EQ(app_init_decoders(&app, STEREO_IIC_BASEADDR, 500u), FW_ERR_NACK);
    FWT_CHECK_EQ(app.dec_status[0], FW_ERR_NACK);
    FWT_CHECK_EQ(app.dec_status[1], FW_OK);
    FWT_CHECK(matches_table(b));
}

/* A decoder that does not answer at start-up: every health record carries DECODER_FAULT,
 * however the video path looks, while its retries fail; the retry that configures it clears
 * the flag and leaves the other decoder alone. */
static void test_decoder_fault_flag_until_a_retry_succeeds(void)
{
    static app_t app;
    radio_health_t h;
    sim_dev_t *a, *b;
    uint32_t a_writes;
    setup();
    a = sim_add_adv7180(&sim, 0x20);
    b = sim_add_adv7180(&sim, 0x21);
    b->nack = 1;
    FWT_CHECK_EQ(app_init_decoders(&app, STEREO_IIC_BASEADDR, 500u), FW_ERR_NACK);
    FWT_CHECK_EQ(app_init_pipeline(&app, STEREO_BASEADDR), FW_OK);
    FWT_CHECK(matches_table(a));
    a_writes = a->writes;
    sim.regfile[STEREO_HEALTH_STATUS_OFFSET / 4] = 0x7u;    /* both streams locked, enabled */
    FWT_CHECK_EQ(app_read_health(&app, &h), FW_OK);
    FWT_CHECK_EQ(h.flags, 0x7u | RADIO_HEALTH_DECODER_FAULT);
    FWT_CHECK_EQ(app_retry_decoders(&app), FW_ERR_NACK);     /* still not there */
    sim.regfile[STEREO_HEALTH_STATUS_OFFSET / 4] = 0x0u;
    FWT_CHECK_EQ(app_read_health(&app, &h), FW_OK);
    FWT_CHECK_EQ(h.flags, RADIO_HEALTH_DECODER_FAULT);
    b->nack = 0;                                             /* it answers now */
    FWT_CHECK_EQ(app_retry_decoders(&app), FW_OK);
    FWT_CHECK(matches_table(b));
    FWT_CHECK_EQ(a->writes, a_writes);                       /* the left one untouched */
    FWT_CHECK_EQ(app.dec_status[0], FW_OK);
    FWT_CHECK_EQ(app.dec_status[1], FW_OK);
    FWT_CHECK_EQ(app_read_health(&app, &h), FW_OK);
    FWT_CHECK_EQ(h.flags, 0x0u);
    /* the left decoder missing is flagged the same */
    setup();
    b = sim_add_adv7180(&sim, 0x21);
    FWT_CHECK_EQ(app_init_decoders(&app, STEREO_IIC_BASEADDR, 500u), FW_ERR_NACK);
    FWT_CHECK_EQ(app_init_pipeline(&app, STEREO_BASEADDR), FW_OK);
    FWT_CHECK_EQ(app_read_health(&app, &h), FW_OK);
    FWT_CHECK_EQ(h.flags, RADIO_HEALTH_DECODER_FAULT);
    sim_uninstall();
}

static void test_table_stops_at_first_error(void)
{
    /* a device that stops answering after 5 table writes: the driver stops at entry 5 */
    adv7180_t dec;
    sim_dev_t *d;
    setup();
    d = sim_add_adv7180(&sim, 0x20);
    d->fail_after = 5u;
    adv7180_bind(&dec, &iic, 0x20);
    FWT_CHECK_EQ(adv7180_init(&dec), FW_ERR_NACK);
    FWT_CHECK_EQ(dec.failed_entry, 5);
    FWT_CHECK_EQ(d->writes, 5);
    FWT_CHECK(adv7180_ntsc_init_len >= 10u);
}

void suite_adv7180(void)
{
    FWT_RUN(test_bind_checks_address);
    FWT_RUN(test_init_writes_table);
    FWT_RUN(test_wrong_id);
    FWT_RUN(test_reset_never_ends);
    FWT_RUN(test_reset_wait_counts_the_bus_time);
    FWT_RUN(test_nack_and_stuck);
    FWT_RUN(test_two_decoders);
    FWT_RUN(test_decoder_fault_flag_until_a_retry_succeeds);
    FWT_RUN(test_table_stops_at_first_error);
}
