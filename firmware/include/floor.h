/*
 * The floor line's learning on the CPU (specification: golden/floor.py learn_line).
 *
 * After each frame the firmware learns the v-disparity floor line from the frame's records
 * (row y, subpixel disparity d16 in 1/16 px) and writes it to the floor flag unit's registers
 * for the next frame (hdl/floor.py). The search is an integer Hough vote over slopes; a line
 * scores support_weight per band of (1 << row_shift) rows holding a record within `band` bins
 * (1/2 px each) of it, less below_weight per record under it. Bit-exact with the golden model.
 */
#ifndef FLOOR_H
#define FLOOR_H

#include <stdint.h>

typedef struct {
    uint16_t slope;     /* 1/256 px of disparity per row, 0..1023 */
    int32_t offset;     /* 1/256 px, -131072..131071 */
} floor_line_t;

typedef struct {
    uint16_t slope_min, slope_max, slope_step;
    uint8_t band, below_weight, support_weight, row_shift;
    uint16_t min_support, prior_slope, prior_px, margin;
} floor_params_t;

/* The parameters of golden.floor.FloorParams' defaults. */
void floor_default_params(floor_params_t *p);

/*
 * Learn the line from n records. *line holds the current line when has_line is non-zero (it is
 * kept unless a candidate scores more than margin above it); prior (or NULL) limits the search
 * to lines near the rig's. work: 2 * n int64 words. Returns 1 when *line was (re)written, 0
 * when it stays, -1 on bad arguments.
 */
int floor_learn(const uint16_t *y, const uint16_t *d16, uint32_t n, const floor_params_t *p,
                const floor_line_t *prior, floor_line_t *line, int has_line, int64_t *work);

/*
 * The floor flag of one record (golden/floor.py floor_flags, hdl/floor.py): 1 when
 * d16 <= line16(y) + tol + (max(line16(y), 0) >> tol_shift), line16(y) = (slope y + offset) >> 4.
 * The CPU has the line it wrote, so it can flag the records itself where the flag bit does not
 * reach it (without the obstacle feet of golden/floor.py keep_feet, which the flag unit adds).
 */
int floor_flag(uint16_t y, uint16_t d16, const floor_line_t *line, uint8_t tol,
               uint8_t tol_shift);

/*
 * Free space per column band from the records and their floor flags (golden/freespace.py
 * free_space_points): a row of band b (columns b band_w .. (b + 1) band_w - 1) is an obstacle row
 * when the band has a record in it that is not a floor point; out[b] is the bottom row of the
 * lowest run of at least run_r obstacle rows, 0xFFFF without one. rows: height words of work.
 * Returns -1 on bad arguments (run_r 0, band_w 0, a row >= height), else 0.
 */
#define FLOOR_FREE_BANDS 16
#define FLOOR_FREE_NONE 0xFFFFu
int floor_free_space(const uint16_t *x, const uint16_t *y, const uint8_t *floor, uint32_t n,
                     uint16_t height, uint16_t band_w, uint8_t run_r,
                     uint16_t out[FLOOR_FREE_BANDS], uint16_t *rows);

#endif
