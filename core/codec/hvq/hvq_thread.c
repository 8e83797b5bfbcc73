/* core/codec/hvq/hvq_thread.c - a parallel for over work items (pthreads) for the hvq encoder,
 * decoder and payload check.
 * Items are handed out in order from a shared counter; every item writes only its own
 * results, so what the encoder produces does not depend on the number of threads. */
#include "codec/hvq/hvq_internal.h"

#include <pthread.h>
#include <unistd.h>

typedef struct parallel_job {
    pthread_mutex_t mu;
    size_t next, count;
    void (*fn)(void *ctx, size_t item);
    void *ctx;
} parallel_job;

static void *parallel_worker(void *arg)
{
    parallel_job *job = arg;
    for (;;) {
        pthread_mutex_lock(&job->mu);
        size_t item = job->next < job->count ? job->next++ : job->count;
        pthread_mutex_unlock(&job->mu);
        if (item == job->count)
            return NULL;
        job->fn(job->ctx, item);
    }
}

void hvq_parallel_for(unsigned threads, size_t count, void (*fn)(void *ctx, size_t item),
                      void *ctx)
{
    if (threads <= 1 || count <= 1) {
        for (size_t i = 0; i < count; i++)
            fn(ctx, i);
        return;
    }
    enum { MAX_THREADS = 64 };
    pthread_t tid[MAX_THREADS];
    parallel_job job = {PTHREAD_MUTEX_INITIALIZER, 0, count, fn, ctx};
    size_t extra = (threads < count ? threads : count) - 1, started = 0;
    if (extra > MAX_THREADS)
        extra = MAX_THREADS;
    while (started < extra && pthread_create(&tid[started], NULL, parallel_worker, &job) == 0)
        started++; /* fewer threads than asked only costs time */
    parallel_worker(&job);
    for (size_t i = 0; i < started; i++)
        pthread_join(tid[i], NULL);
    pthread_mutex_destroy(&job.mu);
}

unsigned hvq_threads_auto(void)
{
    long n = sysconf(_SC_NPROCESSORS_ONLN);
    return n < 1 ? 1u : n > 16 ? 16u : (unsigned)n;
}
