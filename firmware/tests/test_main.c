#include "fwtest.h"

extern int fwt_passed;
extern int fwt_failed;

int main(void)
{
    printf("# hal\n");
    suite_hal();
    printf("# iic\n");
    suite_iic();
    printf("# adv7180\n");
    suite_adv7180();
    printf("# pipeline\n");
    suite_pipeline();
    printf("# radio\n");
    suite_radio();
    printf("# xbee\n");
    suite_xbee();
    printf("# pose\n");
    suite_pose();
    printf("# rectify\n");
    suite_rectify();
    printf("%d passed, %d failed\n", fwt_passed, fwt_failed);
    return fwt_failed == 0 ? 0 : 1;
}
