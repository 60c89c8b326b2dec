/* The floor line's learning (see floor.h; specification golden/floor.py learn_line). */
#include "floor.h"

#include <stdlib.h>

#define BIN_SHIFT 7
#define HALF_BIN (1 << (BIN_SHIFT - 1))
#define OFFSET_LIM 131072L
#define MAX_ROW_BANDS 128

void floor_default_params(floor_params_t *p)
{
    p->slope_min = 32;
    p->slope_max = 160;
    p->slope_step = 2;
    p->band = 1;
    p->below_weight = 1;
    p->support_weight = 4;
    p->row_shift = 3;
    p->min_support = 4;
    p->prior_slope = 16;
    p->prior_px = 12;
    p->margin = 16;
}

/* floor(v / 2^s) for any sign */
static int64_t asr(int64_t v, uint32_t s)
{
    return v >= 0 ? v >> s : -((-v - 1) >> s) - 1;
}

static int cmp64(const void *a, const void *b)
{
    int64_t x = *(const int64_t *)a, y = *(const int64_t *)b;
    return (x > y) - (x < y);
}

static int64_t bin_of(uint16_t y, uint16_t d16, uint16_t slope)
{
    return asr(((int64_t)d16 << 4) - (int64_t)slope * y, BIN_SHIFT);
}

/* Sorted keys k * 2^16 + row band of one slope's records into work[0..n). */
static void keys(const uint16_t *y, const uint16_t *d16, uint32_t n, uint16_t slope,
                 uint32_t row_shift, int64_t *work)
{
    for (uint32_t i = 0; i < n; i++)
        work[i] = bin_of(y[i], d16[i], slope) * 65536 + (y[i] >> row_shift);
    qsort(work, n, sizeof work[0], cmp64);
}

static int64_t key_bin(int64_t key) { return asr(key, 16); }
static uint32_t key_band(int64_t key) { return (uint32_t)(key - key_bin(key) * 65536); }

/* score of the line of bin kl on one slope's sorted keys */
static int64_t score_at(const int64_t *k, uint32_t n, int64_t kl, const floor_params_t *p,
                        int64_t *support_out)
{
    static uint8_t seen[MAX_ROW_BANDS];
    uint32_t lo = 0, hi;
    int64_t support = 0;
    while (lo < n && key_bin(k[lo]) < kl - p->band)
        lo++;
    for (hi = lo; hi < n && key_bin(k[hi]) <= kl + p->band; hi++) {
        uint32_t b = key_band(k[hi]);
        if (!seen[b]) {
            seen[b] = 1;
            support++;
        }
    }
    for (uint32_t i = lo; i < hi; i++)
        seen[key_band(k[i])] = 0;
    *support_out = support;
    return support * p->support_weight - (int64_t)lo * p->below_weight;
}

int floor_learn(const uint16_t *y, const uint16_t *d16, uint32_t n, const floor_params_t *p,
                const floor_line_t *prior, floor_line_t *line, int has_line, int64_t *work)
{
    static uint16_t count[MAX_ROW_BANDS];
    int32_t lo_s, hi_s;
    int64_t klo = 0, khi = 0, best = 0, y_ref = 0;
    int found = 0;
    floor_line_t cand = {0, 0};

    if (!y || !d16 || !p || !line || !work || p->slope_step == 0)
        return -1;
    if (n == 0)
        return 0;
    for (uint32_t i = 0; i < n; i++) {
        if ((y[i] >> p->row_shift) >= MAX_ROW_BANDS)
            return -1;
        if (y[i] > y_ref)
            y_ref = y[i];
    }
    lo_s = p->slope_min;
    hi_s = p->slope_max;
    if (prior) {
        if (prior->slope - (int32_t)p->prior_slope > lo_s)
            lo_s = prior->slope - (int32_t)p->prior_slope;
        if (prior->slope + (int32_t)p->prior_slope < hi_s)
            hi_s = prior->slope + (int32_t)p->prior_slope;
        if (lo_s > hi_s)
            return 0;
    }
    /* the bins of every slope */
    for (int32_t s = lo_s; s <= hi_s; s += p->slope_step)
        for (uint32_t i = 0; i < n; i++) {
            int64_t k = bin_of(y[i], d16[i], (uint16_t)s);
            if ((s == lo_s && i == 0) || k < klo)
                klo = k;
            if ((s == lo_s && i == 0) || k > khi)
                khi = k;
        }
    for (int32_t s = lo_s; s <= hi_s; s += p->slope_step) {
        uint32_t lo = 0, hi = 0;
        int64_t support = 0;
        keys(y, d16, n, (uint16_t)s, p->row_shift, work);
        for (int64_t kb = klo; kb <= khi; kb++) {
            int64_t offset = kb * (1 << BIN_SHIFT) + HALF_BIN, score;
            /* window kb - band .. kb + band, the band counts kept as it slides */
            while (hi < n && key_bin(work[hi]) <= kb + p->band) {
                if (count[key_band(work[hi])]++ == 0)
                    support++;
                hi++;
            }
            while (lo < hi && key_bin(work[lo]) < kb - p->band) {
                if (--count[key_band(work[lo])] == 0)
                    support--;
                lo++;
            }
            score = support * p->support_weight - (int64_t)lo * p->below_weight;
            if (support < p->min_support || offset < -OFFSET_LIM || offset >= OFFSET_LIM)
                continue;
            if (prior) {
                int64_t at = (int64_t)s * y_ref + offset;
                int64_t want = (int64_t)prior->slope * y_ref + prior->offset;
                int64_t diff = at > want ? at - want : want - at;
                if (diff > ((int64_t)p->prior_px << 8))
                    continue;
            }
            if (!found || score > best) {
                found = 1;
                best = score;
                cand.slope = (uint16_t)s;
                cand.offset = (int32_t)offset;
            }
        }
        while (lo < hi) {              /* clear the counts for the next slope */
            count[key_band(work[lo])]--;
            lo++;
        }
    }
    if (!found)
        return 0;
    if (has_line) {
        int64_t support, current;
        keys(y, d16, n, line->slope, p->row_shift, work);
        current = score_at(work, n, asr((int64_t)line->offset - HALF_BIN, BIN_SHIFT), p,
                           &support);
        if (best <= current + p->margin)
            return 0;
    }
    *line = cand;
    return 1;
}

int floor_flag(uint16_t y, uint16_t d16, const floor_line_t *line, uint8_t tol,
               uint8_t tol_shift)
{
    int64_t l16 = asr((int64_t)line->slope * y + line->offset, 4);
    int64_t t = tol + ((l16 > 0 ? l16 : 0) >> (tol_shift & 7));
    return d16 <= l16 + t;
}

int floor_free_space(const uint16_t *x, const uint16_t *y, const uint8_t *floor, uint32_t n,
                     uint16_t height, uint16_t band_w, uint8_t run_r,
                     uint16_t out[FLOOR_FREE_BANDS], uint16_t *rows)
{
    if (!out || !rows || (n && (!x || !y || !floor)) || band_w == 0 || run_r == 0)
        return -1;
    for (uint16_t r = 0; r < height; r++)
        rows[r] = 0;
    for (uint32_t i = 0; i < n; i++) {
        uint32_t band = x[i] / band_w;
        if (y[i] >= height)
            return -1;
        if (!floor[i] && band < FLOOR_FREE_BANDS)
            rows[y[i]] |= (uint16_t)(1u << band);
    }
    for (uint32_t b = 0; b < FLOOR_FREE_BANDS; b++) {
        uint32_t run = 0;
        out[b] = FLOOR_FREE_NONE;
        for (uint16_t r = 0; r < height; r++) {
            run = (rows[r] >> b) & 1u ? (run < run_r ? run + 1 : run) : 0;
            if (run >= run_r)
                out[b] = r;
        }
    }
    return 0;
}
