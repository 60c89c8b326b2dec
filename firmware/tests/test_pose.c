/* Pose block: sequence-locked snapshot, torn updates retried, saturation, bounds. */
#include "fwtest.h"
#include "hal.h"
#include "pose.h"

#include <string.h>

typedef struct {
    uint32_t regs[6];
    uint32_t reads;
    uint32_t tear_every;   /* the writer updates after every Nth read (0 = never) */
    uint32_t tear_at;      /* ... or once, after this read */
    uint32_t busy;         /* SEQ stays odd */
} sim_pose_t;

static sim_pose_t sim;

static uint32_t rd(void *ctx, uint32_t addr)
{
    sim_pose_t *m = ctx;
    uint32_t v = m->regs[(addr - POSE_BASEADDR) / 4u];
    m->reads++;
    if ((m->tear_every && m->reads % m->tear_every == 0u) || m->reads == m->tear_at) {
        m->regs[0] += 2u;                               /* a whole update happened */
        m->regs[1] += 10u;
    }
    if (m->busy && addr == POSE_BASEADDR) {
        v |= 1u;
    }
    return v;
}

static void setup(void)
{
    memset(&sim, 0, sizeof sim);
    sim.regs[0] = 42u;
    sim.regs[1] = (uint32_t)-1500;
    sim.regs[2] = 40000u;                                 /* beyond int16: saturates */
    sim.regs[3] = 0x12344000u;                            /* only bits 15:0 count */
    sim.regs[4] = 123456u;
    sim.regs[5] = POSE_STATUS_VALID | POSE_STATUS_COMPASS;
    hal_set_bus_hook(rd, NULL, NULL, NULL, &sim);
}

static void test_snapshot(void)
{
    pose_t p;
    setup();
    FWT_CHECK_EQ(pose_read(POSE_BASEADDR, &p), FW_OK);
    FWT_CHECK_EQ(p.x_mm, -1500);
    FWT_CHECK_EQ(p.y_mm, 32767);
    FWT_CHECK_EQ(p.theta, 0x4000);
    FWT_CHECK_EQ(p.t_ms, 123456);
    FWT_CHECK_EQ(sim.reads, 7);
    hal_set_bus_hook(NULL, NULL, NULL, NULL, NULL);
}

static void test_torn_update_is_retried(void)
{
    pose_t p;
    setup();
    sim.tear_at = 4u;                 /* an update in the middle of the first snapshot */
    FWT_CHECK_EQ(pose_read(POSE_BASEADDR, &p), FW_OK);
    FWT_CHECK_EQ(sim.reads, 14);      /* read twice */
    FWT_CHECK_EQ(p.x_mm, -1490);      /* the new value, not a mix */
    setup();
    sim.tear_every = 3u;              /* always torn: bounded */
    FWT_CHECK_EQ(pose_read(POSE_BASEADDR, &p), FW_ERR_TIMEOUT);
    FWT_CHECK(sim.reads <= 7u * POSE_MAX_TRIES);
    setup();
    sim.busy = 1u;
    FWT_CHECK_EQ(pose_read(POSE_BASEADDR, &p), FW_ERR_TIMEOUT);
    FWT_CHECK_EQ(sim.reads, POSE_MAX_TRIES);
    hal_set_bus_hook(NULL, NULL, NULL, NULL, NULL);
}

static void test_invalid_pose(void)
{
    pose_t p;
    setup();
    sim.regs[5] = 0u;
    p.x_mm = 7;
    FWT_CHECK_EQ(pose_read(POSE_BASEADDR, &p), FW_ERR_NO_LOCK);
    FWT_CHECK_EQ(p.x_mm, 7);          /* untouched */
    FWT_CHECK_EQ(pose_read(POSE_BASEADDR, NULL), FW_ERR_PARAM);
    hal_set_bus_hook(NULL, NULL, NULL, NULL, NULL);
}

void suite_pose(void)
{
    FWT_RUN(test_snapshot);
    FWT_RUN(test_torn_update_is_retried);
    FWT_RUN(test_invalid_pose);
}
