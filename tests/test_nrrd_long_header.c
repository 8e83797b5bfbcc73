/* A NRRD whose header is longer than the loader reads (4 MiB of comment lines) is refused with
 * an error naming the file and the limit, not a crash (issue 21: teem's nrrdIoStateNix was called
 * on NULL after the header read failed, core/io/io_nrrd_check.c). Both the load and the probe
 * (cdvr_series_open reads headers only) run in a child process, so a crash is reported as the
 * signal that ended it instead of ending this test; a hang ends by alarm(). The file is made
 * here, in a temporary directory. */
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include "cdvr/series.h"
#include "cdvr/volume.h"
#include "check.h"

#define HEADER_BYTES (5u << 20) /* more than the 4 MiB the loader reads */

static int write_long_header(const char *path)
{
    FILE *f = fopen(path, "wb");
    if (!f)
        return 0;
    fputs("NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n", f);
    char line[81];
    memset(line, 'x', sizeof line - 1);
    line[0] = '#';
    line[79] = '\n';
    line[80] = '\0';
    for (size_t n = 0; n < HEADER_BYTES; n += 80)
        fputs(line, f);
    fputs("\n", f);
    for (int i = 0; i < 8; i++)
        fputc(i, f);
    return fclose(f) == 0;
}

/* Runs one load kind (0: cdvr_volume_load, 1: cdvr_series_open) in a child; the child exits 0
 * when it got the expected error and writes the message to the pipe. */
static void check_refused(const char *path, int kind)
{
    int fds[2];
    CHECK(pipe(fds) == 0, "pipe");
    pid_t pid = fork();
    if (pid == 0) {
        close(fds[0]);
        alarm(60);
        cdvr_error err;
        cdvr_status st;
        if (kind == 0) {
            cdvr_volume *vol = NULL;
            st = cdvr_volume_load(path, NULL, &vol, &err);
            cdvr_volume_free(vol);
        } else {
            cdvr_series *s = NULL;
            st = cdvr_series_open(&path, 1, NULL, &s, &err);
            cdvr_series_close(s);
        }
        if (st == CDVR_OK)
            _exit(2);
        if (write(fds[1], err.msg, strlen(err.msg)) < 0)
            _exit(3);
        _exit(0);
    }
    close(fds[1]);
    char msg[CDVR_ERRMSG_MAX + 1] = {0};
    ssize_t got = 0, n;
    while (got < CDVR_ERRMSG_MAX && (n = read(fds[0], msg + got, CDVR_ERRMSG_MAX - got)) > 0)
        got += n;
    close(fds[0]);
    int status = 0;
    CHECK(waitpid(pid, &status, 0) == pid, "waitpid");
    CHECK(!WIFSIGNALED(status), "kind %d: the child died by signal %d", kind,
          WIFSIGNALED(status) ? WTERMSIG(status) : 0);
    CHECK(WIFEXITED(status) && WEXITSTATUS(status) == 0, "kind %d: child exit %d (2: loaded)",
          kind, WIFEXITED(status) ? WEXITSTATUS(status) : -1);
    CHECK(strstr(msg, path) != NULL, "kind %d: the message names the file: %s", kind, msg);
    CHECK(strstr(msg, "header longer than") != NULL, "kind %d: the message names the limit: %s",
          kind, msg);
}

int main(void)
{
    char dir[] = "/tmp/cdvr_nrrd_long_XXXXXX";
    if (!mkdtemp(dir)) {
        perror("mkdtemp");
        return 1;
    }
    char path[256];
    snprintf(path, sizeof path, "%s/long.nrrd", dir);
    CHECK(write_long_header(path), "cannot write %s", path);
    check_refused(path, 0);
    check_refused(path, 1);
    unlink(path);
    rmdir(dir);
    return check_finish();
}
