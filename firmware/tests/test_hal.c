/* The HAL's timeouts: deadlines across the tick counter's wrap, and a register wait
 * (hal_wait_set, the UART's wait for room) against a bus whose reads take modelled time. */
#include "fwtest.h"
#include "hal.h"

/* the harness's clock: hal_ticks reads `now` (the delays' share taken out) */
static uint32_t now;
static uint32_t delays_share;

static uint32_t clock_ticks(void *ctx)
{
    (void)ctx;
    return now - delays_share;
}

static void clock_start(uint32_t start)
{
    hal_set_ticks_hook(NULL, NULL);
    delays_share = hal_ticks();
    now = start;
    hal_set_ticks_hook(clock_ticks, NULL);
}

/* a register that reads 0 until `ready_after` reads, then READY; each read costs READ_TICKS */
#define REG 0x40001000u
#define READY 0x4u
#define READ_TICKS 30u
static uint32_t reads;
static uint32_t ready_after;

static uint32_t bus_read(void *ctx, uint32_t addr)
{
    (void)ctx;
    now += READ_TICKS;
    if (addr != REG) {
        return 0u;
    }
    reads++;
    return reads > ready_after ? (READY | 0x1u) : 0x1u;
}

static void bus_start(uint32_t start, uint32_t ready)
{
    hal_set_bus_hook(bus_read, NULL, NULL, NULL, NULL);
    reads = 0u;
    ready_after = ready;
    clock_start(start);
}

static void bus_stop(void)
{
    hal_set_bus_hook(NULL, NULL, NULL, NULL, NULL);
    hal_set_ticks_hook(NULL, NULL);
}

static void test_deadline_across_the_wrap(void)
{
    uint32_t d;
    clock_start(0xFFFFFF00u);
    d = hal_deadline_us(10u);
    FWT_CHECK_EQ(d, 0xFFFFFF00u + 10u * HAL_TICKS_PER_US);
    FWT_CHECK(d < 0xFFFFFF00u);                     /* it wrapped */
    FWT_CHECK(!hal_expired(d));                     /* a plain now >= d would say expired */
    now = 0xFFFFFFFFu;
    FWT_CHECK(!hal_expired(d));
    now = 0u;
    FWT_CHECK(!hal_expired(d));
    now = d - 1u;
    FWT_CHECK(!hal_expired(d));
    now = d;
    FWT_CHECK(hal_expired(d));
    now = d + 1u;
    FWT_CHECK(hal_expired(d));
    now = d + 0x7FFFFFFFu;                          /* looked at long after */
    FWT_CHECK(hal_expired(d));
    hal_set_ticks_hook(NULL, NULL);
}

static void test_longest_timeout(void)
{
    /* 42 s at 50 MHz: just under half the counter's range */
    uint32_t us = 0x7FFFFFFFu / HAL_TICKS_PER_US;
    uint32_t d;
    clock_start(0x80000000u);
    d = hal_deadline_us(us);
    now = d - 1u;
    FWT_CHECK(!hal_expired(d));
    now = d;
    FWT_CHECK(hal_expired(d));
    hal_set_ticks_hook(NULL, NULL);
}

static void test_wait_that_completes_early(void)
{
    uint32_t t0;
    bus_start(0u - 200u, 5u);                       /* the counter wraps during the wait */
    t0 = hal_ticks();
    FWT_CHECK_EQ(hal_wait_set(REG, READY, HAL_UART_TX_TIMEOUT_US), FW_OK);
    FWT_CHECK_EQ(reads, 6u);
    FWT_CHECK_EQ(hal_ticks() - t0, 6u * READ_TICKS);
    bus_stop();
}

/* A bit that never comes: FW_ERR_TIMEOUT at the deadline, within one read after it, and
 * before the poll cap. */
static void check_never_completes(uint32_t start)
{
    uint32_t t0, elapsed;
    bus_start(start, 0xFFFFFFFFu);
    t0 = hal_ticks();
    FWT_CHECK_EQ(hal_wait_set(REG, READY, HAL_UART_TX_TIMEOUT_US), FW_ERR_TIMEOUT);
    elapsed = hal_ticks() - t0;
    FWT_CHECK(elapsed >= HAL_UART_TX_TIMEOUT_US * HAL_TICKS_PER_US);
    FWT_CHECK(elapsed <= HAL_UART_TX_TIMEOUT_US * HAL_TICKS_PER_US + READ_TICKS);
    FWT_CHECK(reads < HAL_POLL_CAP(HAL_UART_TX_TIMEOUT_US));
    bus_stop();
}

static void test_wait_that_never_completes(void)
{
    check_never_completes(1000u);
    check_never_completes(0u - 1000u);              /* the deadline lies past the wrap */
    check_never_completes(0x7FFFFFFFu);             /* and past the sign change */
}

static void test_stuck_clock_ends_at_the_poll_cap(void)
{
    /* reads that take no time: a clock standing still. The cap ends the wait */
    hal_set_bus_hook(bus_read, NULL, NULL, NULL, NULL);
    hal_set_ticks_hook(NULL, NULL);
    reads = 0u;
    ready_after = 0xFFFFFFFFu;
    FWT_CHECK_EQ(hal_wait_set(REG, READY, 100u), FW_ERR_TIMEOUT);
    FWT_CHECK_EQ(reads, HAL_POLL_CAP(100u));
    /* the cap takes at least the deadline on a core whose poll costs HAL_MIN_POLL_CYCLES */
    FWT_CHECK(HAL_POLL_CAP(100u) * HAL_MIN_POLL_CYCLES >= 100u * HAL_TICKS_PER_US);
    bus_stop();
}

void suite_hal(void)
{
    FWT_RUN(test_deadline_across_the_wrap);
    FWT_RUN(test_longest_timeout);
    FWT_RUN(test_wait_that_completes_early);
    FWT_RUN(test_wait_that_never_completes);
    FWT_RUN(test_stuck_clock_ends_at_the_poll_cap);
}
