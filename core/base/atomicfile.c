/* core/base/atomicfile.c - unnamed or temporary file, fsync, link/rename (see atomicfile.h). */
#define _GNU_SOURCE /* O_TMPFILE, AT_EMPTY_PATH */
#include "cdvr/atomicfile.h"
#include "cdvr/cleanup.h"
#include "cdvr/regular_file.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <libgen.h>
#include <limits.h>
#include <signal.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#define MAX_LINK_HOPS 40 /* as the kernel's limit (ELOOP) */
#define TMP_TAG ".tmp."  /* temporary names: TARGET.tmp.PID.XXXXXX */
#define NAME_TRIES 100   /* attempts at a free temporary name */

/* The file a write to path lands on: path with symbolic links at its last component followed
 * (a dangling link gives its target); malloc'd, or NULL with errno set. */
static char *resolve_links(const char *path)
{
    char *cur = strdup(path);
    for (int hops = 0; cur; hops++) {
        struct stat sb;
        if (lstat(cur, &sb) != 0 || !S_ISLNK(sb.st_mode))
            return cur;
        char link[PATH_MAX];
        ssize_t n = hops < MAX_LINK_HOPS ? readlink(cur, link, sizeof link - 1) : -1;
        if (n < 0) {
            if (hops >= MAX_LINK_HOPS)
                errno = ELOOP;
            free(cur);
            return NULL;
        }
        link[n] = '\0';
        const char *slash = strrchr(cur, '/');
        size_t dir = link[0] == '/' || !slash ? 0 : (size_t)(slash - cur) + 1; /* keep "dir/" */
        char *next = malloc(dir + (size_t)n + 1);
        if (next) {
            memcpy(next, cur, dir);
            memcpy(next + dir, link, (size_t)n + 1);
        }
        free(cur);
        cur = next;
    }
    return NULL;
}

/* Refuses an existing target that is not a regular file: renaming over /dev/null (as root), a
 * FIFO or a socket would replace it with a plain file. *mode gets an existing file's mode. */
static cdvr_status check_target(const char *path, const char *target, mode_t *mode, cdvr_error *err)
{
    struct stat sb;
    *mode = 0644;
    if (stat(target, &sb) != 0)
        return CDVR_OK; /* a new file */
    if (!S_ISREG(sb.st_mode))
        return cdvr_error_set(err, CDVR_ERR_IO, "%s: not a regular file (%s); cdvr writes regular files only", path,
                              cdvr_file_kind(sb.st_mode));
    *mode = sb.st_mode & 07777;
    return CDVR_OK;
}

/* ---- stale temporaries of dead writers ------------------------------------------------------ */

/* 1 when name is base + ".tmp." + PID + "." + 6 characters and no process PID exists. */
static int is_stale(const char *name, const char *base)
{
    size_t nb = strlen(base), nt = strlen(TMP_TAG);
    if (strncmp(name, base, nb) != 0 || strncmp(name + nb, TMP_TAG, nt) != 0)
        return 0;
    char *end;
    errno = 0;
    long pid = strtol(name + nb + nt, &end, 10);
    if (errno || end == name + nb + nt || pid <= 0 || pid > INT32_MAX || *end != '.' || strlen(end + 1) != 6)
        return 0;
    return kill((pid_t)pid, 0) != 0 && errno == ESRCH; /* EPERM: alive, someone else's */
}

void cdvr_atomic_clean_stale(const char *target)
{
    char *dcopy = strdup(target), *bcopy = strdup(target);
    DIR *d = dcopy && bcopy ? opendir(dirname(dcopy)) : NULL;
    const char *base = d ? basename(bcopy) : NULL;
    struct dirent *e;
    while (d && (e = readdir(d)))
        if (is_stale(e->d_name, base))
            (void)unlinkat(dirfd(d), e->d_name, 0);
    if (d)
        closedir(d);
    free(dcopy);
    free(bcopy);
}

/* ---- creating ------------------------------------------------------------------------------- */

static void release(cdvr_atomic_file *af)
{
    cdvr_cleanup_unregister(af->cleanup_slot);
    af->cleanup_slot = -1;
    free(af->tmp_path);
    free(af->target_path);
    af->tmp_path = af->target_path = NULL;
    af->f = NULL;
}

/* 1 when this process must use a named temporary file: CDVR_ATOMIC_NAMED=1 in the environment
 * (what a filesystem without O_TMPFILE gets; tests use it) or no /proc/self/fd to link from. */
static int named_only(void)
{
    const char *env = getenv("CDVR_ATOMIC_NAMED");
    return (env && strcmp(env, "1") == 0) || access("/proc/self/fd", X_OK) != 0;
}

/* An unnamed file in target's directory (O_TMPFILE), or -1 where the filesystem has none. */
static int open_unnamed(const char *target)
{
    char *copy = strdup(target);
    int fd = copy && !named_only() ? open(dirname(copy), O_TMPFILE | O_WRONLY | O_CLOEXEC, 0600) : -1;
    free(copy);
    return fd;
}

/* af->tmp_path = TARGET.tmp.PID.XXXXXX (the X's left for mkstemp or fill_name). */
static int make_tmp_name(cdvr_atomic_file *af)
{
    size_t n = strlen(af->target_path) + sizeof TMP_TAG + 24;
    free(af->tmp_path);
    af->tmp_path = malloc(n);
    if (af->tmp_path)
        snprintf(af->tmp_path, n, "%s" TMP_TAG "%ld.XXXXXX", af->target_path, (long)getpid());
    return af->tmp_path != NULL;
}

cdvr_status cdvr_atomic_open(cdvr_atomic_file *af, const char *path, cdvr_error *err)
{
    memset(af, 0, sizeof *af);
    af->path = path;
    af->cleanup_slot = -1;
    af->target_path = resolve_links(path);
    if (!af->target_path)
        return cdvr_error_set(err, CDVR_ERR_IO, "%s: cannot follow its symbolic link: %s", path, strerror(errno));
    mode_t mode;
    cdvr_status st = check_target(path, af->target_path, &mode, err);
    if (st != CDVR_OK) {
        release(af);
        return st;
    }
    int fd = open_unnamed(af->target_path);
    af->unnamed = fd >= 0;
    if (fd < 0) {
        cdvr_atomic_clean_stale(af->target_path); /* where a writer's kill -9 leaves a name */
        if (!make_tmp_name(af)) {
            release(af);
            return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: out of memory", path);
        }
        fd = cdvr_cleanup_mkstemp(af->tmp_path, &af->cleanup_slot);
    }
    if (fd >= 0) {
        fchmod(fd, mode); /* created 0600; keep the mode of the file replaced, else 0644 */
        af->f = fdopen(fd, "wb");
    }
    if (!af->f) {
        int saved = errno;
        if (fd >= 0) {
            close(fd);
            if (!af->unnamed)
                unlink(af->tmp_path);
        }
        release(af);
        return cdvr_error_set(err, CDVR_ERR_IO, "%s: cannot create temporary file: %s", path, strerror(saved));
    }
    return CDVR_OK;
}

/* ---- committing ----------------------------------------------------------------------------- */

/* fsync the directory so that the rename itself is durable. */
static void sync_parent_dir(const char *path)
{
    char *copy = strdup(path);
    if (!copy)
        return;
    int fd = open(dirname(copy), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (fd >= 0) {
        (void)fsync(fd);
        close(fd);
    }
    free(copy);
}

/* Gives the unnamed file fd the name `name`: through /proc/self/fd, else AT_EMPTY_PATH. */
static int link_unnamed(int fd, const char *name)
{
    char proc[64];
    snprintf(proc, sizeof proc, "/proc/self/fd/%d", fd);
    if (linkat(AT_FDCWD, proc, AT_FDCWD, name, AT_SYMLINK_FOLLOW) == 0)
        return 0;
    if (errno == EEXIST)
        return -1;
    return linkat(fd, "", AT_FDCWD, name, AT_EMPTY_PATH);
}

/* Replaces the X's at the end of af->tmp_path with letters. */
static void fill_name(cdvr_atomic_file *af, unsigned *seed)
{
    static const char letters[] = "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789";
    char *x = af->tmp_path + strlen(af->tmp_path) - 6;
    for (int i = 0; i < 6; i++) {
        *seed = *seed * 1103515245u + 12345u;
        x[i] = letters[(*seed >> 16) % (sizeof letters - 1)];
    }
}

/* Links the finished unnamed file onto the target: directly where no file stands there (one
 * atomic step), else under a temporary name (registered for signal cleanup) renamed over it. */
static int publish_unnamed(cdvr_atomic_file *af, int fd)
{
    if (link_unnamed(fd, af->target_path) == 0)
        return 0;
    if (errno != EEXIST || !make_tmp_name(af))
        return -1;
    unsigned seed = (unsigned)getpid() ^ (unsigned)time(NULL) ^ (unsigned)(uintptr_t)af;
    for (int tries = 0; tries < NAME_TRIES; tries++) {
        fill_name(af, &seed);
        sigset_t old;
        cdvr_cleanup_block(&old); /* no signal between the link and its registration */
        int r = link_unnamed(fd, af->tmp_path);
        if (r == 0)
            af->cleanup_slot = cdvr_cleanup_register(af->tmp_path);
        cdvr_cleanup_unblock(&old);
        if (r == 0) {
            if (rename(af->tmp_path, af->target_path) == 0)
                return 0;
            int saved = errno;
            unlink(af->tmp_path);
            errno = saved;
            return -1;
        }
        if (errno != EEXIST)
            return -1;
    }
    return -1;
}

cdvr_status cdvr_atomic_commit(cdvr_atomic_file *af, int failed, cdvr_error *err)
{
    int saved = failed ? errno : 0;
    if (!failed && (ferror(af->f) || fflush(af->f) != 0 || fsync(fileno(af->f)) != 0)) {
        failed = 1;
        saved = errno;
    }
    if (!failed && af->unnamed && publish_unnamed(af, fileno(af->f)) != 0) {
        failed = 1;
        saved = errno;
    }
    if (fclose(af->f) != 0 && !failed) {
        failed = 1;
        saved = errno;
    }
    if (!failed && !af->unnamed && rename(af->tmp_path, af->target_path) != 0) {
        failed = 1;
        saved = errno;
    }
    if (failed && !af->unnamed)
        unlink(af->tmp_path);
    else if (!failed)
        sync_parent_dir(af->target_path);
    const char *path = af->path;
    release(af);
    if (failed)
        return cdvr_error_set(err, CDVR_ERR_IO, "%s: cannot write: %s", path,
                              saved ? strerror(saved) : "write failed");
    return CDVR_OK;
}
