/* Rectifier start-up: a build without it, a warp beyond its line buffer, a map that is not
 * the calibration's or no map at all, and the registers it sets when everything fits. */
#include "fwtest.h"
#include "hal.h"
#include "rectify.h"
#include "stereo_regs.h"

#include <string.h>

#define BASE STEREO_RECT_BASEADDR

#define LEFT STEREO_RECT_LEFT_BASEADDR

typedef struct {
    uint32_t regs[8];       /* CTRL, VALID_POS, VALID_SIZE, INFO, MAP_CHECK by offset / 4 */
    uint32_t writes;
    int absent;             /* no rectifier: the window reads 0 */
} sim_rect_t;

static sim_rect_t sim;      /* the right camera's rectifier, at BASE */
static sim_rect_t sim_left; /* the left camera's, at LEFT */

static sim_rect_t *window(sim_rect_t *right, uint32_t *addr)
{
    if (*addr >= LEFT) {
        *addr -= LEFT - BASE;
        return &sim_left;
    }
    return right;
}

static uint32_t rd(void *ctx, uint32_t addr)
{
    sim_rect_t *m = window(ctx, &addr);
    uint32_t k = (addr - BASE) / 4u;
    return m->absent || k >= 8u ? 0u : m->regs[k];
}

static void wr(void *ctx, uint32_t addr, uint32_t value)
{
    sim_rect_t *m = window(ctx, &addr);
    uint32_t k = (addr - BASE) / 4u;
    m->writes++;
    if (!m->absent && k < 3u) {
        m->regs[k] = value;
    }
}

/* a map that needs 7 rows less one, stride 32 words, 9 node rows, whose check is 0x12345678,
 * lo = -3, valid region 700 x 230 at (4, 2); the build: span 8 */
#define NEED(span, stride, rows) ((span) | (stride) << STEREO_RECT_INFO_STRIDE_LOG2_SHIFT | \
                                  (rows) << STEREO_RECT_INFO_NODE_ROWS_SHIFT)
static const rect_table_t table = { NEED(7u, 5u, 9u), 0x12345678u, 1u | (0x3Du << 8),
                                    4u | (2u << 16), 700u | (230u << 16) };

static void setup(void)
{
    memset(&sim, 0, sizeof sim);
    sim.regs[STEREO_RECT_INFO_OFFSET / 4u] = (8u << STEREO_RECT_INFO_SPAN_SHIFT) |
        (5u << STEREO_RECT_INFO_STRIDE_LOG2_SHIFT) | (9u << STEREO_RECT_INFO_NODE_ROWS_SHIFT) |
        STEREO_RECT_INFO_PRELOADED_MASK;
    sim.regs[STEREO_RECT_MAP_CHECK_OFFSET / 4u] = 0x12345678u;
    sim_left = sim;         /* the left camera's: the same build, its map checks 0x0BADCAFE */
    sim_left.regs[STEREO_RECT_MAP_CHECK_OFFSET / 4u] = 0x0BADCAFEu;
    hal_set_bus_hook(rd, wr, NULL, NULL, &sim);
}

static uint32_t left_reg(uint32_t offset)
{
    return sim_left.regs[offset / 4u];
}

static uint32_t reg(uint32_t offset)
{
    return sim.regs[offset / 4u];
}

static void test_enabled_when_everything_fits(void)
{
    setup();
    FWT_CHECK_EQ(rect_setup(BASE, &table), FW_OK);
    FWT_CHECK_EQ(reg(STEREO_RECT_CTRL_OFFSET), 1u | (0x3Du << 8));     /* lo = -3 */
    FWT_CHECK_EQ(reg(STEREO_RECT_VALID_POS_OFFSET), 4u | (2u << 16));
    FWT_CHECK_EQ(reg(STEREO_RECT_VALID_SIZE_OFFSET), 700u | (230u << 16));
    hal_set_bus_hook(NULL, NULL, NULL, NULL, NULL);
}

static void test_warp_beyond_the_build(void)
{
    rect_table_t t = table;
    setup();
    sim.regs[STEREO_RECT_CTRL_OFFSET / 4u] = 0u;
    t.need = NEED(10u, 5u, 9u);
    FWT_CHECK_EQ(rect_setup(BASE, &t), FW_ERR_RECT_WARP);
    FWT_CHECK_EQ(reg(STEREO_RECT_CTRL_OFFSET), 0u);                   /* left disabled */
    hal_set_bus_hook(NULL, NULL, NULL, NULL, NULL);
}

static void test_map_not_the_calibrations(void)
{
    rect_table_t t = table;
    setup();
    t.map_check ^= 1u;
    FWT_CHECK_EQ(rect_setup(BASE, &t), FW_ERR_RECT_MAP);
    FWT_CHECK_EQ(reg(STEREO_RECT_CTRL_OFFSET), 0u);
    t = table;
    t.need = NEED(7u, 6u, 9u);                 /* a map of another frame width */
    FWT_CHECK_EQ(rect_setup(BASE, &t), FW_ERR_RECT_MAP);
    t.need = NEED(7u, 5u, 10u);                /* of a taller frame */
    FWT_CHECK_EQ(rect_setup(BASE, &t), FW_ERR_RECT_MAP);
    hal_set_bus_hook(NULL, NULL, NULL, NULL, NULL);
}

static void test_no_map_in_the_bitstream(void)
{
    /* a calibration's map whose check word is 0 against an empty map memory, which also
     * checks 0: only RECT_INFO's preloaded bit tells them apart */
    rect_table_t t = table;
    setup();
    t.map_check = 0u;
    sim.regs[STEREO_RECT_MAP_CHECK_OFFSET / 4u] = 0u;
    FWT_CHECK_EQ(rect_setup(BASE, &t), FW_OK);
    sim.regs[STEREO_RECT_CTRL_OFFSET / 4u] = 0u;
    sim.regs[STEREO_RECT_INFO_OFFSET / 4u] &= ~STEREO_RECT_INFO_PRELOADED_MASK;
    FWT_CHECK_EQ(rect_setup(BASE, &t), FW_ERR_RECT_MAP);
    FWT_CHECK_EQ(reg(STEREO_RECT_CTRL_OFFSET), 0u);
    hal_set_bus_hook(NULL, NULL, NULL, NULL, NULL);
}

static void test_build_without_rectifier(void)
{
    setup();
    sim.absent = 1;
    FWT_CHECK_EQ(rect_setup(BASE, &table), FW_ERR_RECT_ABSENT);
    hal_set_bus_hook(NULL, NULL, NULL, NULL, NULL);
    FWT_CHECK_EQ(rect_setup(BASE, &table), FW_ERR_RECT_ABSENT);       /* empty host bus */
}

static void test_both_cameras(void)
{
    /* both enabled when both fit; the left's map not the calibration's, or the right's warp
     * beyond its buffer: both stay disabled, whichever was checked first */
    rect_table_t left = table;
    rect_table_t t = table;
    left.map_check = 0x0BADCAFEu;
    left.ctrl = 1u | (0x3Bu << 8);                                      /* lo = -5 */
    setup();
    FWT_CHECK_EQ(rect_setup_both(BASE, &table, LEFT, &left), FW_OK);
    FWT_CHECK_EQ(reg(STEREO_RECT_CTRL_OFFSET), 1u | (0x3Du << 8));
    FWT_CHECK_EQ(left_reg(STEREO_RECT_CTRL_OFFSET), 1u | (0x3Bu << 8));
    FWT_CHECK_EQ(left_reg(STEREO_RECT_VALID_SIZE_OFFSET), 700u | (230u << 16));
    setup();
    FWT_CHECK_EQ(rect_setup_both(BASE, &table, LEFT, &table), FW_ERR_RECT_MAP);
    FWT_CHECK_EQ(reg(STEREO_RECT_CTRL_OFFSET), 0u);
    FWT_CHECK_EQ(left_reg(STEREO_RECT_CTRL_OFFSET), 0u);
    setup();
    t.need = NEED(10u, 5u, 9u);
    FWT_CHECK_EQ(rect_setup_both(BASE, &t, LEFT, &left), FW_ERR_RECT_WARP);
    FWT_CHECK_EQ(reg(STEREO_RECT_CTRL_OFFSET), 0u);
    FWT_CHECK_EQ(left_reg(STEREO_RECT_CTRL_OFFSET), 0u);                /* enabled, undone */
    setup();
    sim_left.absent = 1;                                /* a build with the right one only */
    FWT_CHECK_EQ(rect_setup_both(BASE, &table, LEFT, &left), FW_ERR_RECT_ABSENT);
    FWT_CHECK_EQ(reg(STEREO_RECT_CTRL_OFFSET), 0u);
    hal_set_bus_hook(NULL, NULL, NULL, NULL, NULL);
}

void suite_rectify(void)
{
    FWT_RUN(test_enabled_when_everything_fits);
    FWT_RUN(test_warp_beyond_the_build);
    FWT_RUN(test_map_not_the_calibrations);
    FWT_RUN(test_no_map_in_the_bitstream);
    FWT_RUN(test_build_without_rectifier);
    FWT_RUN(test_both_cameras);
}
