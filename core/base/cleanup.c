/* core/base/cleanup.c - the process-wide temporary-file cleanup context (see cleanup.h). */
#include "cdvr/cleanup.h"

#include <errno.h>
#include <limits.h>
#include <pthread.h>
#include <signal.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

enum { SLOT_FREE, SLOT_FILLING, SLOT_ACTIVE };

/* Every signal whose default action ends the process and that a handler can catch. */
static const int cleanup_signals[] = {SIGINT,  SIGTERM, SIGQUIT, SIGHUP,  SIGUSR1,   SIGUSR2,
                                      SIGPIPE, SIGALRM, SIGXCPU, SIGXFSZ, SIGVTALRM, SIGPROF};
#define NSIGNALS (sizeof cleanup_signals / sizeof cleanup_signals[0])

/* The one cleanup context of the process: registered temporary files and the signal
 * dispositions that were in place before ours. */
static struct cdvr_cleanup_context {
    _Atomic int state[CDVR_CLEANUP_SLOTS];
    char path[CDVR_CLEANUP_SLOTS][PATH_MAX];
    struct sigaction previous[NSIGNALS];
    pthread_mutex_t install_lock;
} cdvr_cleanup = {.install_lock = PTHREAD_MUTEX_INITIALIZER};

static void remove_registered_files(void)
{
    for (int i = 0; i < CDVR_CLEANUP_SLOTS; i++)
        if (atomic_load(&cdvr_cleanup.state[i]) == SLOT_ACTIVE)
            unlink(cdvr_cleanup.path[i]);
}

static void cleanup_on_signal(int sig, siginfo_t *info, void *context)
{
    int saved_errno = errno;
    remove_registered_files();
    for (size_t k = 0; k < NSIGNALS; k++) {
        if (cleanup_signals[k] != sig)
            continue;
        struct sigaction *prev = &cdvr_cleanup.previous[k];
        if (prev->sa_flags & SA_SIGINFO) {
            prev->sa_sigaction(sig, info, context);
        } else if (prev->sa_handler != SIG_DFL && prev->sa_handler != SIG_IGN) {
            prev->sa_handler(sig);
        } else { /* default action: end the process by this signal once the handler returns */
            sigaction(sig, prev, NULL);
            raise(sig);
        }
    }
    errno = saved_errno;
}

/* Installs the handler for every signal whose disposition is not ours and not SIG_IGN. */
static void install_handlers(void)
{
    pthread_mutex_lock(&cdvr_cleanup.install_lock);
    for (size_t k = 0; k < NSIGNALS; k++) {
        struct sigaction now;
        if (sigaction(cleanup_signals[k], NULL, &now) != 0)
            continue;
        if ((now.sa_flags & SA_SIGINFO) && now.sa_sigaction == cleanup_on_signal)
            continue;
        if (!(now.sa_flags & SA_SIGINFO) && now.sa_handler == SIG_IGN)
            continue;
        struct sigaction ours;
        memset(&ours, 0, sizeof ours);
        ours.sa_sigaction = cleanup_on_signal;
        ours.sa_flags = SA_SIGINFO | SA_RESTART;
        sigfillset(&ours.sa_mask);
        cdvr_cleanup.previous[k] = now;
        sigaction(cleanup_signals[k], &ours, NULL);
    }
    pthread_mutex_unlock(&cdvr_cleanup.install_lock);
}

int cdvr_cleanup_register(const char *tmp_path)
{
    size_t len = strlen(tmp_path);
    if (len >= PATH_MAX)
        return -1;
    install_handlers();
    for (int i = 0; i < CDVR_CLEANUP_SLOTS; i++) {
        int expected = SLOT_FREE;
        if (atomic_compare_exchange_strong(&cdvr_cleanup.state[i], &expected, SLOT_FILLING)) {
            memcpy(cdvr_cleanup.path[i], tmp_path, len + 1);
            atomic_store(&cdvr_cleanup.state[i], SLOT_ACTIVE);
            return i;
        }
    }
    return -1;
}

void cdvr_cleanup_block(sigset_t *old)
{
    sigset_t block;
    sigemptyset(&block);
    for (size_t k = 0; k < NSIGNALS; k++)
        sigaddset(&block, cleanup_signals[k]);
    pthread_sigmask(SIG_BLOCK, &block, old);
}

void cdvr_cleanup_unblock(const sigset_t *old)
{
    pthread_sigmask(SIG_SETMASK, old, NULL); /* a signal that came meanwhile is handled now */
}

int cdvr_cleanup_mkstemp(char *tmpl, int *slot)
{
    sigset_t old;
    cdvr_cleanup_block(&old);
    int fd = mkstemp(tmpl);
    int saved = errno;
    *slot = fd >= 0 ? cdvr_cleanup_register(tmpl) : -1;
    cdvr_cleanup_unblock(&old);
    errno = saved;
    return fd;
}

void cdvr_cleanup_unregister(int slot)
{
    if (slot >= 0 && slot < CDVR_CLEANUP_SLOTS)
        atomic_store(&cdvr_cleanup.state[slot], SLOT_FREE);
}
