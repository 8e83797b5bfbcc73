/* cdvr/timing.h - the one clock and the one median that timings and benchmarks use. */
#ifndef CDVR_TIMING_H
#define CDVR_TIMING_H

#include <stddef.h>

/* Monotonic wall time in milliseconds (CLOCK_MONOTONIC; only differences are meaningful). */
double cdvr_now_ms(void);
/* CPU time the calling thread has used, in milliseconds (CLOCK_THREAD_CPUTIME_ID; only
 * differences are meaningful; 0 where the clock is missing). For stages whose wall time
 * includes waiting for the cores (the player's workers run at a lower priority). */
double cdvr_thread_cpu_ms(void);
/* Median of v[0..n) (sorts v in place); the mean of the two middle values for even n, 0 for n = 0. */
double cdvr_median(double *v, size_t n);

#endif
