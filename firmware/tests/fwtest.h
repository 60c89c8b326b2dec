/**
 * @file fwtest.h
 * A tiny test runner: FWT_CHECK records a failure and goes on; FWT_RUN runs one test
 * function and counts it as passed or failed. The runner's last line is
 * "N passed, N failed".
 */
#ifndef FWTEST_H
#define FWTEST_H

#include <stdio.h>

extern int fwt_current_failed;

#define FWT_CHECK(cond)                                                          \
    do {                                                                         \
        if (!(cond)) {                                                           \
            printf("  FAIL %s:%d: %s\n", __FILE__, __LINE__, #cond);             \
            fwt_current_failed = 1;                                              \
        }                                                                        \
    } while (0)

#define FWT_CHECK_EQ(a, b)                                                       \
    do {                                                                         \
        long fwt_a_ = (long)(a), fwt_b_ = (long)(b);                             \
        if (fwt_a_ != fwt_b_) {                                                  \
            printf("  FAIL %s:%d: %s == %s (%ld != %ld)\n", __FILE__, __LINE__,  \
                   #a, #b, fwt_a_, fwt_b_);                                      \
            fwt_current_failed = 1;                                              \
        }                                                                        \
    } while (0)

typedef void (*fwt_fn)(void);
void fwt_run(const char *name, fwt_fn fn);
#define FWT_RUN(fn) fwt_run(#fn, fn)

/* suites, one per firmware module */
void suite_hal(void);
void suite_iic(void);
void suite_adv7180(void);
void suite_pipeline(void);
void suite_radio(void);
void suite_rectify(void);
void suite_xbee(void);
void suite_pose(void);

#endif /* FWTEST_H */
