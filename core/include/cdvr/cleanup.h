/* cdvr/cleanup.h - the process-wide temporary-file cleanup context.
 *
 * Writers that build a file under a temporary name (cdvr/atomicfile.h: cdvr.encode, raw and
 * PNG saves, player captures) register the temporary file here for as long as it exists (with
 * O_TMPFILE that is only the instant between link and rename). When the process receives a
 * catchable signal whose default ends it (the cleanup signals: SIGINT, SIGTERM, SIGQUIT,
 * SIGHUP, SIGUSR1, SIGUSR2, SIGPIPE, SIGALRM, SIGXCPU, SIGXFSZ, SIGVTALRM, SIGPROF), the
 * handler removes every registered temporary file, then lets the signal do what it did before: the handler that was installed
 * before is called, or, for the default action, the default is restored and the signal raised
 * again, so the process ends as killed by that signal (exit status 128 + n in a shell). An
 * interrupted encode thus leaves neither a partial file under its final name nor a temporary
 * file beside it. A signal that is ignored (SIG_IGN, e.g. SIGINT for a background job) stays
 * ignored. SIGKILL cannot be caught: with O_TMPFILE the kernel drops the unnamed file; on a
 * filesystem without it the named one ("PATH.tmp.PID.XXXXXX") stays until the next writer of
 * PATH removes it (cdvr_atomic_clean_stale).
 *
 * The handler is installed at the first registration, and again at a later one if something
 * replaced it meanwhile. It calls only unlink, sigaction, raise and the previous handler
 * (async-signal-safe); the table is a fixed array of CDVR_CLEANUP_SLOTS paths with atomic
 * slot states, so registering never allocates. Registering is thread-safe.
 */
#ifndef CDVR_CLEANUP_H
#define CDVR_CLEANUP_H

#include <signal.h>

#define CDVR_CLEANUP_SLOTS 64

/* Registers tmp_path for removal on the cleanup signals; returns its slot, or -1 when the
 * table is full or the path too long (the file is then not removed on a signal). */
int cdvr_cleanup_register(const char *tmp_path);

/* mkstemp(tmpl) and cdvr_cleanup_register(tmpl) as one step for the cleanup signals (they are
 * blocked in between), so a signal never finds the file created but not yet registered.
 * Returns the descriptor, or -1 with errno set; *slot as cdvr_cleanup_register. */
int cdvr_cleanup_mkstemp(char *tmpl, int *slot);

/* Blocks the cleanup signals in the calling thread (old gets the previous mask), and restores
 * that mask (a signal that came meanwhile is then handled): for a step that creates a file and
 * registers it, so that no signal finds it created but not registered. */
void cdvr_cleanup_block(sigset_t *old);
void cdvr_cleanup_unblock(const sigset_t *old);

/* Forgets slot (after the file was renamed or removed); -1 is ignored. */
void cdvr_cleanup_unregister(int slot);

#endif
