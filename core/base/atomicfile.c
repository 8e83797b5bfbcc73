/* core/base/atomicfile.c - temporary file, fsync, rename (see atomicfile.h). */
#include "cdvr/atomicfile.h"
#include "cdvr/cleanup.h"
#include "cdvr/regular_file.h"

#include <errno.h>
#include <fcntl.h>
#include <libgen.h>
#include <limits.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#define MAX_LINK_HOPS 40 /* as the kernel's limit (ELOOP) */

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

static void release(cdvr_atomic_file *af)
{
    cdvr_cleanup_unregister(af->cleanup_slot);
    af->cleanup_slot = -1;
    free(af->tmp_path);
    free(af->target_path);
    af->tmp_path = af->target_path = NULL;
    af->f = NULL;
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
    size_t n = strlen(af->target_path) + sizeof ".tmpXXXXXX";
    af->tmp_path = st == CDVR_OK ? malloc(n) : NULL;
    if (st == CDVR_OK && !af->tmp_path)
        st = cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: out of memory", path);
    if (st != CDVR_OK) {
        release(af);
        return st;
    }
    snprintf(af->tmp_path, n, "%s.tmpXXXXXX", af->target_path);
    int fd = cdvr_cleanup_mkstemp(af->tmp_path, &af->cleanup_slot);
    if (fd >= 0) {
        fchmod(fd, mode); /* mkstemp creates 0600; keep the mode of the file replaced, else 0644 */
        af->f = fdopen(fd, "wb");
    }
    if (!af->f) {
        int saved = errno;
        if (fd >= 0) {
            close(fd);
            unlink(af->tmp_path);
        }
        release(af);
        return cdvr_error_set(err, CDVR_ERR_IO, "%s: cannot create temporary file: %s", path, strerror(saved));
    }
    return CDVR_OK;
}

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

cdvr_status cdvr_atomic_commit(cdvr_atomic_file *af, int failed, cdvr_error *err)
{
    int saved = failed ? errno : 0;
    if (!failed && (ferror(af->f) || fflush(af->f) != 0 || fsync(fileno(af->f)) != 0)) {
        failed = 1;
        saved = errno;
    }
    if (fclose(af->f) != 0 && !failed) {
        failed = 1;
        saved = errno;
    }
    if (!failed && rename(af->tmp_path, af->target_path) != 0) {
        failed = 1;
        saved = errno;
    }
    if (failed)
        unlink(af->tmp_path);
    else
        sync_parent_dir(af->target_path);
    const char *path = af->path;
    release(af);
    if (failed)
        return cdvr_error_set(err, CDVR_ERR_IO, "%s: cannot write: %s", path,
                              saved ? strerror(saved) : "write failed");
    return CDVR_OK;
}
