/* core/base/atomicfile.c - temporary file, fsync, rename (see atomicfile.h). */
#include "cdvr/atomicfile.h"

#include <errno.h>
#include <fcntl.h>
#include <libgen.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

cdvr_status cdvr_atomic_open(cdvr_atomic_file *af, const char *path, cdvr_error *err)
{
    af->f = NULL;
    af->path = path;
    size_t n = strlen(path) + sizeof ".tmpXXXXXX";
    af->tmp_path = malloc(n);
    if (!af->tmp_path)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: out of memory", path);
    snprintf(af->tmp_path, n, "%s.tmpXXXXXX", path);
    int fd = mkstemp(af->tmp_path);
    if (fd >= 0) {
        fchmod(fd, 0644); /* mkstemp creates 0600; outputs are meant to be shared */
        af->f = fdopen(fd, "wb");
    }
    if (!af->f) {
        int saved = errno;
        if (fd >= 0) {
            close(fd);
            unlink(af->tmp_path);
        }
        free(af->tmp_path);
        af->tmp_path = NULL;
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
    if (!failed && rename(af->tmp_path, af->path) != 0) {
        failed = 1;
        saved = errno;
    }
    if (failed)
        unlink(af->tmp_path);
    else
        sync_parent_dir(af->path);
    free(af->tmp_path);
    af->tmp_path = NULL;
    af->f = NULL;
    if (failed)
        return cdvr_error_set(err, CDVR_ERR_IO, "%s: cannot write: %s", af->path,
                              saved ? strerror(saved) : "write failed");
    return CDVR_OK;
}
