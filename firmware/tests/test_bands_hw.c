/* The per-band summary unit's reader (bands_hw.c) against radio_summary_add on the same
 * records, through a model of the unit's registers on the host bus hook. */
#include "fwtest.h"
#include "bands_hw.h"
#include "hal.h"

#include <string.h>

#define BASE BANDS_HW_BASEADDR

typedef struct {
    uint32_t cfg;
    int ignore_cfg;             /* no unit: CFG reads 0 */
    uint16_t frames;
    uint32_t flags;             /* STATUS bits besides frames */
    uint32_t top[RADIO_MAX_BANDS];
    uint32_t next[RADIO_MAX_BANDS];     /* published at the bump_at-th TOP read */
    uint32_t next_flags;
    int32_t bump_at;
    uint32_t top_reads;
} fake_unit_t;

static uint32_t fake_read(void *ctx, uint32_t addr)
{
    fake_unit_t *u = (fake_unit_t *)ctx;
    uint32_t off = addr - BASE;
    if (off == BANDS_HW_CFG_OFFSET) {
        return u->cfg;
    }
    if (off == BANDS_HW_STATUS_OFFSET) {
        return u->frames | BANDS_HW_STATUS_BUILT | u->flags;
    }
    if (off >= BANDS_HW_TOP_OFFSET && off < BANDS_HW_TOP_OFFSET + 4u * RADIO_MAX_BANDS) {
        uint32_t w = u->top[(off - BANDS_HW_TOP_OFFSET) / 4u];
        u->top_reads++;
        if (u->bump_at >= 0 && u->top_reads == (uint32_t)u->bump_at) {
            memcpy(u->top, u->next, sizeof u->top);
            u->flags = u->next_flags;
            u->frames++;
        }
        return w;
    }
    return 0u;
}

static void fake_write(void *ctx, uint32_t addr, uint32_t value)
{
    fake_unit_t *u = (fake_unit_t *)ctx;
    if (addr - BASE == BANDS_HW_CFG_OFFSET && !u->ignore_cfg) {
        u->cfg = value;
    }
}

static uint32_t rng_state;
static uint32_t rnd(uint32_t n)
{
    rng_state = rng_state * 1103515245u + 12345u;
    return (rng_state >> 8) % n;
}

typedef struct {
    uint32_t n;
    uint16_t x[600];
    uint8_t d[600];
} frame_t;

static void make_frame(frame_t *f, uint16_t width, int ties)
{
    uint32_t i;
    f->n = rnd(600);
    for (i = 0u; i < f->n; i++) {
        f->x[i] = (uint16_t)rnd(width + 20u);          /* some past the frame: ignored */
        f->d[i] = (uint8_t)(ties ? rnd(4u) : rnd(256u));     /* some 0: ignored */
    }
}

/* The unit's words of one frame: per band its BANDS_HW_SLOTS largest, descending. */
static void unit_words(const frame_t *f, uint16_t width, uint8_t n_bands, uint32_t *words)
{
    radio_summary_t t;
    uint32_t i, b, j;
    FWT_CHECK_EQ(radio_summary_init(&t, width, n_bands, BANDS_HW_SLOTS), FW_OK);
    for (i = 0u; i < f->n; i++) {
        radio_summary_add(&t, f->x[i], f->d[i]);
    }
    for (b = 0u; b < n_bands; b++) {
        words[b] = 0u;
        for (j = 0u; j < t.count[b]; j++) {
            words[b] |= (uint32_t)t.top[b][j] << (8u * j);
        }
    }
}

static void add_records(radio_summary_t *s, const frame_t *f)
{
    uint32_t i;
    for (i = 0u; i < f->n; i++) {
        radio_summary_add(s, f->x[i], f->d[i]);
    }
}

static frame_t frames[8];

/* Merging frames one by one gives the report of all their records, every min_support the
 * unit keeps; a frame published while its predecessor is read is the one merged. */
static void test_merge_equals_records(void)
{
    static const uint16_t widths[] = { 720, 720, 100, 64, 33 };
    static const uint8_t bands[] = { 32, 64, 7, 64, 1 };
    uint32_t c, k, ms;
    for (c = 0u; c < ARRAY_SIZE(widths); c++) {
        for (ms = 1u; ms <= BANDS_HW_SLOTS; ms++) {
            fake_unit_t u;
            bands_hw_t hw;
            radio_summary_t got, want;
            uint8_t bg[RADIO_MAX_BANDS], bw[RADIO_MAX_BANDS];
            rng_state = 7u * c + ms;
            memset(&u, 0, sizeof u);
            u.bump_at = -1;
            u.frames = 40000u + (uint16_t)c;      /* wraps during the run */
            hal_set_bus_hook(fake_read, fake_write, NULL, NULL, &u);
            FWT_CHECK_EQ(bands_hw_init(&hw, BASE, widths[c], bands[c]), FW_OK);
            FWT_CHECK_EQ(u.cfg, (uint32_t)widths[c] | (uint32_t)bands[c] << 16);
            FWT_CHECK_EQ(radio_summary_init(&got, widths[c], bands[c], (uint8_t)ms), FW_OK);
            FWT_CHECK_EQ(radio_summary_init(&want, widths[c], bands[c], (uint8_t)ms), FW_OK);
            FWT_CHECK_EQ(bands_hw_collect(&hw, &got), 0u);         /* nothing new yet */
            for (k = 0u; k < ARRAY_SIZE(frames); k++) {
                make_frame(&frames[k], widths[c], (int)(k % 3u == 1u));
            }
            for (k = 0u; k < ARRAY_SIZE(frames); k++) {
                if (k == 5u) {
                    /* frame 6 is published during the reads of frame 5: frame 5 is missed */
                    unit_words(&frames[k], widths[c], bands[c], u.top);
                    u.frames++;
                    unit_words(&frames[k + 1u], widths[c], bands[c], u.next);
                    u.next_flags = BANDS_HW_STATUS_LOST;
                    u.top_reads = 0u;
                    u.bump_at = 1 + bands[c] / 2;
                    FWT_CHECK_EQ(bands_hw_collect(&hw, &got), 1u);
                    add_records(&want, &frames[k + 1u]);
                    u.bump_at = -1;
                    k++;
                    continue;
                }
                unit_words(&frames[k], widths[c], bands[c], u.top);
                u.frames++;
                u.flags = 0u;
                FWT_CHECK_EQ(bands_hw_collect(&hw, &got), 1u);
                FWT_CHECK_EQ(bands_hw_collect(&hw, &got), 0u);     /* merged once */
                add_records(&want, &frames[k]);
            }
            radio_summary_finish(&got, bg);
            radio_summary_finish(&want, bw);
            FWT_CHECK(memcmp(bg, bw, bands[c]) == 0);
            FWT_CHECK_EQ(hw.merged, 7u);
            FWT_CHECK_EQ(hw.missed, 1u);
            FWT_CHECK_EQ(hw.lost, 1u);
        }
    }
    hal_set_bus_hook(NULL, NULL, NULL, NULL, NULL);
}

static void test_missed_frames_and_bad_arguments(void)
{
    fake_unit_t u;
    bands_hw_t hw;
    radio_summary_t s;
    memset(&u, 0, sizeof u);
    u.bump_at = -1;
    hal_set_bus_hook(fake_read, fake_write, NULL, NULL, &u);
    FWT_CHECK_EQ(bands_hw_init(&hw, BASE, 720, 0), FW_ERR_PARAM);
    FWT_CHECK_EQ(bands_hw_init(&hw, BASE, 720, RADIO_MAX_BANDS + 1u), FW_ERR_PARAM);
    FWT_CHECK_EQ(bands_hw_init(&hw, BASE, 31, 32), FW_ERR_PARAM);
    FWT_CHECK_EQ(bands_hw_init(&hw, BASE, 1025, 32), FW_ERR_PARAM);
    FWT_CHECK_EQ(u.cfg, 0u);                  /* nothing written */
    u.ignore_cfg = 1;
    FWT_CHECK_EQ(bands_hw_init(&hw, BASE, 720, 32), FW_ERR_ID);
    u.ignore_cfg = 0;
    FWT_CHECK_EQ(bands_hw_init(&hw, BASE, 720, 32), FW_OK);
    /* a summary of another geometry, or a min_support the unit does not keep: nothing */
    FWT_CHECK_EQ(radio_summary_init(&s, 720, 16, 3), FW_OK);
    u.frames = 3u;
    FWT_CHECK_EQ(bands_hw_collect(&hw, &s), 0u);
    FWT_CHECK_EQ(radio_summary_init(&s, 720, 32, BANDS_HW_SLOTS + 1u), FW_OK);
    FWT_CHECK_EQ(bands_hw_collect(&hw, &s), 0u);
    FWT_CHECK_EQ(radio_summary_init(&s, 720, 32, 3), FW_OK);
    FWT_CHECK_EQ(bands_hw_collect(&hw, &s), 1u);      /* frames 1 and 2 were never read */
    FWT_CHECK_EQ(hw.missed, 2u);
    FWT_CHECK_EQ(hw.merged, 1u);
    hal_set_bus_hook(NULL, NULL, NULL, NULL, NULL);
}

void suite_bands_hw(void);
void suite_bands_hw(void)
{
    FWT_RUN(test_merge_equals_records);
    FWT_RUN(test_missed_frames_and_bad_arguments);
}

#ifdef BANDS_HW_TEST_MAIN
extern int fwt_passed;
extern int fwt_failed;

int main(void)
{
    printf("# bands_hw\n");
    suite_bands_hw();
    printf("%d passed, %d failed\n", fwt_passed, fwt_failed);
    return fwt_failed == 0 ? 0 : 1;
}
#endif
