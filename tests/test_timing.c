/* core/base/timing.c: median definition and a monotonic clock. */
#include "cdvr/timing.h"
#include "check.h"

int main(void)
{
    double odd[] = {5, 1, 3};
    CHECK(cdvr_median(odd, 3) == 3, "odd count: middle value");
    double even[] = {4, 1, 3, 2};
    CHECK(cdvr_median(even, 4) == 2.5, "even count: mean of the two middle values");
    double one[] = {7};
    CHECK(cdvr_median(one, 1) == 7, "one value");
    CHECK(cdvr_median(NULL, 0) == 0, "empty: 0");
    double a = cdvr_now_ms(), b = cdvr_now_ms();
    CHECK(a > 0 && b >= a, "monotonic: %f then %f", a, b);
    return check_finish();
}
