#include "fwtest.h"

int fwt_current_failed;
int fwt_passed;
int fwt_failed;

void fwt_run(const char *name, fwt_fn fn)
{
    fwt_current_failed = 0;
    fn();
    if (fwt_current_failed) {
        fwt_failed++;
        printf("FAIL %s\n", name);
    } else {
        fwt_passed++;
        printf("ok   %s\n", name);
    }
}
