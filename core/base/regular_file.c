/* core/base/regular_file.c - opening input files without blocking (see regular_file.h). */
#include "cdvr/regular_file.h"

#include <errno.h>
#include <fcntl.h>
#include <string.h>
#include <unistd.h>

const char *cdvr_file_kind(unsigned mode)
{
    if (S_ISREG(mode))
        return "a regular file";
    if (S_ISDIR(mode))
        return "a directory";
    if (S_ISFIFO(mode))
        return "a FIFO";
    if (S_ISCHR(mode))
        return "a character device";
    if (S_ISBLK(mode))
        return "a block device";
    if (S_ISSOCK(mode))
        return "a socket";
    return "not a regular file";
}

static cdvr_status not_regular(const char *path, unsigned mode, cdvr_error *err)
{
    return cdvr_error_set(err, CDVR_ERR_IO, "%s: not a regular file (%s); cdvr reads regular files only",
                          path, cdvr_file_kind(mode));
}

cdvr_status cdvr_check_regular_file(const char *path, struct stat *sb, cdvr_error *err)
{
    struct stat local;
    if (!sb)
        sb = &local;
    if (stat(path, sb) != 0)
        return cdvr_error_set(err, CDVR_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
    if (!S_ISREG(sb->st_mode))
        return not_regular(path, sb->st_mode, err);
    return CDVR_OK;
}

cdvr_status cdvr_open_regular_file(const char *path, int *fd, struct stat *sb, cdvr_error *err)
{
    struct stat local;
    if (!sb)
        sb = &local;
    *fd = -1;
    cdvr_status st = cdvr_check_regular_file(path, sb, err);
    if (st != CDVR_OK)
        return st;
    int f = open(path, O_RDONLY | O_NONBLOCK | O_CLOEXEC);
    if (f < 0)
        return cdvr_error_set(err, CDVR_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
    if (fstat(f, sb) != 0 || !S_ISREG(sb->st_mode)) { /* replaced since the stat */
        int saved = errno;
        close(f);
        return S_ISREG(sb->st_mode) ? cdvr_error_set(err, CDVR_ERR_IO, "%s: cannot open: %s", path, strerror(saved))
                                    : not_regular(path, sb->st_mode, err);
    }
    int flags = fcntl(f, F_GETFL);
    if (flags < 0 || fcntl(f, F_SETFL, flags & ~O_NONBLOCK) != 0) {
        int saved = errno;
        close(f);
        return cdvr_error_set(err, CDVR_ERR_IO, "%s: cannot open: %s", path, strerror(saved));
    }
    *fd = f;
    return CDVR_OK;
}

cdvr_status cdvr_fopen_regular_file(const char *path, FILE **f, struct stat *sb, cdvr_error *err)
{
    int fd;
    *f = NULL;
    cdvr_status st = cdvr_open_regular_file(path, &fd, sb, err);
    if (st != CDVR_OK)
        return st;
    *f = fdopen(fd, "rb");
    if (!*f) {
        int saved = errno;
        close(fd);
        return cdvr_error_set(err, CDVR_ERR_IO, "%s: cannot open: %s", path, strerror(saved));
    }
    return CDVR_OK;
}
