/* IIC driver against the simulated AXI IIC controller. */
#include "fwtest.h"
#include "hal.h"
#include "iic.h"
#include "sim_xiic.h"
#include "stereo_regs.h"
#include "xiic_l.h"

static sim_xiic_t sim;
static iic_dev_t iic;

static void setup(void)
{
    sim_init(&sim, STEREO_IIC_BASEADDR);
    sim_install(&sim);
    iic_init(&iic, STEREO_IIC_BASEADDR, 200u);
}

static void test_init_enables_controller(void)
{
    setup();
    FWT_CHECK_EQ(sim.cr, XIIC_CR_ENABLE_DEVICE_MASK);
    FWT_CHECK_EQ(sim.rfd, 15);
    FWT_CHECK_EQ(iic.timeout_polls, 200);
    FWT_CHECK_EQ(iic_init(NULL, 0u, 0u), FW_ERR_PARAM);
    iic_init(&iic, STEREO_IIC_BASEADDR, 0u);
    FWT_CHECK_EQ(iic.timeout_polls, IIC_DEFAULT_TIMEOUT_POLLS);
}

static void test_write_then_read(void)
{
    sim_dev_t *d;
    uint8_t v = 0u;
    setup();
    d = sim_add_dev(&sim, 0x42);
    FWT_CHECK_EQ(iic_write_reg8(&iic, 0x42, 0x10, 0xA5), FW_OK);
    FWT_CHECK_EQ(d->regs[0x10], 0xA5);
    FWT_CHECK_EQ(d->writes, 1);
    d->regs[0x33] = 0x5A;
    FWT_CHECK_EQ(iic_read_reg8(&iic, 0x42, 0x33, &v), FW_OK);
    FWT_CHECK_EQ(v, 0x5A);
    FWT_CHECK_EQ(sim.bus_busy, 0);
    FWT_CHECK_EQ(iic.errors, 0);
}

static void test_burst_read(void)
{
    sim_dev_t *d;
    uint8_t buf[4] = { 0 };
    setup();
    d = sim_add_dev(&sim, 0x10);
    d->regs[5] = 1; d->regs[6] = 2; d->regs[7] = 3; d->regs[8] = 4;
    FWT_CHECK_EQ(iic_read_regs(&iic, 0x10, 5, buf, 4), FW_OK);
    FWT_CHECK(buf[0] == 1 && buf[1] == 2 && buf[2] == 3 && buf[3] == 4);
    FWT_CHECK_EQ(iic_read_regs(&iic, 0x10, 5, buf, 0), FW_ERR_PARAM);
    FWT_CHECK_EQ(iic_read_regs(&iic, 0x10, 5, buf, 17), FW_ERR_PARAM);
    FWT_CHECK_EQ(iic_write_reg8(&iic, 0x80, 0, 0), FW_ERR_PARAM);
}

static void test_absent_device_nacks(void)
{
    uint8_t v = 0u;
    setup();
    FWT_CHECK_EQ(iic_write_reg8(&iic, 0x33, 0x00, 0x00), FW_ERR_NACK);
    FWT_CHECK_EQ(iic_read_reg8(&iic, 0x33, 0x00, &v), FW_ERR_NACK);
    FWT_CHECK_EQ(iic.errors, 2);
    FWT_CHECK(iic.polls < 200u);
    /* the controller is usable again afterwards */
    sim_add_dev(&sim, 0x34);
    FWT_CHECK_EQ(iic_write_reg8(&iic, 0x34, 0x01, 0x02), FW_OK);
}

static void test_nacking_device(void)
{
    sim_dev_t *d;
    setup();
    d = sim_add_dev(&sim, 0x20);
    d->nack = 1;
    FWT_CHECK_EQ(iic_write_reg8(&iic, 0x20, 0x00, 0x00), FW_ERR_NACK);
    FWT_CHECK_EQ(d->writes, 0);
}

static void test_held_scl_times_out(void)
{
    sim_dev_t *d;
    uint8_t v = 0u;
    uint32_t before;
    setup();
    d = sim_add_dev(&sim, 0x21);
    d->hold_scl = 1;
    before = sim.accesses;
    FWT_CHECK_EQ(iic_write_reg8(&iic, 0x21, 0x00, 0x00), FW_ERR_TIMEOUT);
    /* bounded: a poll is at most two register reads, plus set-up and recovery */
    FWT_CHECK(sim.accesses - before <= 2u * 200u + 20u);
    /* the bus stays stuck: the next transfer gives up before starting */
    FWT_CHECK_EQ(iic_read_reg8(&iic, 0x21, 0x00, &v), FW_ERR_BUS_BUSY);
    FWT_CHECK_EQ(iic.errors, 2);
}

/* A modelled poll cost: 25 core cycles a bus access (0.5 us at 50 MHz). */
#define ACCESS_TICKS 25u
#define DEADLINE_TICKS (IIC_TIMEOUT_US * HAL_TICKS_PER_US)
/* what a call does besides its polls: set-up, the TX FIFO words, the recovery */
#define OVERHEAD_TICKS (20u * ACCESS_TICKS)

/* A transfer whose end never comes fails at the deadline, with the clock started at `start`:
 * not before it, and within one poll plus the call's overhead after it. */
static void check_held_scl_at_deadline(uint32_t start)
{
    sim_dev_t *d;
    uint8_t v = 0u;
    uint32_t t0, elapsed;
    sim_init(&sim, STEREO_IIC_BASEADDR);
    sim_install(&sim);
    iic_init(&iic, STEREO_IIC_BASEADDR, 0u);
    d = sim_add_dev(&sim, 0x21);
    d->hold_scl = 1;
    sim_clock(&sim, ACCESS_TICKS, start);
    t0 = hal_ticks();
    FWT_CHECK_EQ(t0, start);
    FWT_CHECK_EQ(iic_write_reg8(&iic, 0x21, 0x00, 0x00), FW_ERR_TIMEOUT);
    elapsed = hal_ticks() - t0;
    FWT_CHECK(elapsed >= DEADLINE_TICKS);
    FWT_CHECK(elapsed <= DEADLINE_TICKS + OVERHEAD_TICKS);
    FWT_CHECK(iic.polls < iic.timeout_polls);        /* the deadline ended it, not the cap */
    /* the bus stays busy: the next transfer waits for it until the deadline too */
    t0 = hal_ticks();
    FWT_CHECK_EQ(iic_read_reg8(&iic, 0x21, 0x00, &v), FW_ERR_BUS_BUSY);
    elapsed = hal_ticks() - t0;
    FWT_CHECK(elapsed >= DEADLINE_TICKS);
    FWT_CHECK(elapsed <= DEADLINE_TICKS + OVERHEAD_TICKS);
    sim_uninstall();
}

static void test_wait_ends_at_the_deadline(void)
{
    check_held_scl_at_deadline(1000u);
}

static void test_deadline_across_the_tick_counters_wrap(void)
{
    /* the deadline lies past 2^32: a plain comparison would end the wait at once */
    check_held_scl_at_deadline(0u - DEADLINE_TICKS / 2u);
    check_held_scl_at_deadline(0u - 1u);
}

static void test_transfer_ends_before_the_deadline(void)
{
    sim_dev_t *d;
    uint8_t buf[4] = { 0 };
    uint32_t t0;
    setup();
    iic_init(&iic, STEREO_IIC_BASEADDR, 0u);
    d = sim_add_dev(&sim, 0x10);
    d->regs[3] = 0x77;
    sim_clock(&sim, ACCESS_TICKS, 0u - 100u);       /* the counter wraps during the transfer */
    t0 = hal_ticks();
    FWT_CHECK_EQ(iic_read_regs(&iic, 0x10, 3, buf, 4), FW_OK);
    FWT_CHECK_EQ(buf[0], 0x77);
    FWT_CHECK(hal_ticks() - t0 < DEADLINE_TICKS / 10u);
    FWT_CHECK_EQ(iic.errors, 0);
    sim_uninstall();
}

static void test_no_hook_never_hangs(void)
{
    /* an empty bus reads all ones: BUS_BUSY set forever -> bounded BUS_BUSY */
    sim_uninstall();
    iic_init(&iic, STEREO_IIC_BASEADDR, 50u);
    FWT_CHECK_EQ(iic_write_reg8(&iic, 0x20, 0, 0), FW_ERR_BUS_BUSY);
}

static void test_status_strings(void)
{
    FWT_CHECK(fw_status_str(FW_ERR_TIMEOUT)[0] == 'T');
    FWT_CHECK(fw_status_str(-100)[0] == 'U');
}

void suite_iic(void)
{
    FWT_RUN(test_init_enables_controller);
    FWT_RUN(test_write_then_read);
    FWT_RUN(test_burst_read);
    FWT_RUN(test_absent_device_nacks);
    FWT_RUN(test_nacking_device);
    FWT_RUN(test_held_scl_times_out);
    FWT_RUN(test_wait_ends_at_the_deadline);
    FWT_RUN(test_deadline_across_the_tick_counters_wrap);
    FWT_RUN(test_transfer_ends_before_the_deadline);
    FWT_RUN(test_no_hook_never_hangs);
    FWT_RUN(test_status_strings);
}
