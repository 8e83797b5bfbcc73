/* core/base/atomicfile.c and cleanup.c: complete file or nothing under the final name, no temporary
 * left: with O_TMPFILE nothing is visible under any name before commit, not even after SIGKILL;
 * on the named path (CDVR_ATOMIC_NAMED=1, as on a filesystem without O_TMPFILE) every catchable
 * terminating signal removes the temporary and the process still dies by that signal, and the
 * temporary a SIGKILL leaves (it carries the pid) is removed by the next writer, while a live
 * writer's is kept; symbolic links written through, non-regular files never replaced. */
#define _GNU_SOURCE /* O_TMPFILE */
#include <dirent.h>
#include <fcntl.h>
#include <stdlib.h>
#include <signal.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "cdvr/atomicfile.h"
#include "check.h"

static int count_entries(const char *dir)
{
    DIR *d = opendir(dir);
    int n = 0;
    struct dirent *e;
    while (d && (e = readdir(d)))
        if (strcmp(e->d_name, ".") && strcmp(e->d_name, ".."))
            n++;
    if (d)
        closedir(d);
    return n;
}

static char *read_all(const char *path, char *buf, size_t n)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return NULL;
    size_t got = fread(buf, 1, n - 1, f);
    buf[got] = '\0';
    fclose(f);
    return buf;
}

static void write_file(const char *path, const char *text)
{
    FILE *f = fopen(path, "w");
    if (f) {
        fputs(text, f);
        fclose(f);
    }
}

/* A FIFO (or device) under the final name is refused, not replaced, and nothing blocks. */
static void check_fifo(const char *dir)
{
    char fifo[300];
    snprintf(fifo, sizeof fifo, "%s/fifo", dir);
    CHECK(mkfifo(fifo, 0644) == 0, "mkfifo");
    cdvr_atomic_file af;
    cdvr_error err;
    CHECK(cdvr_atomic_open(&af, fifo, &err) == CDVR_ERR_IO && strstr(err.msg, "a FIFO") && !af.f,
          "FIFO refused: %s", err.msg);
    struct stat sb;
    CHECK(lstat(fifo, &sb) == 0 && S_ISFIFO(sb.st_mode), "the FIFO is still there");
    unlink(fifo);
}

/* A symbolic link is written through: its target gets the data, the link stays; a dangling
 * link creates its target; a link loop is an error. */
static void check_symlinks(const char *dir)
{
    char target[300], link1[300], link2[300], dangling[300], loop[300], buf[64];
    snprintf(target, sizeof target, "%s/target.txt", dir);
    snprintf(link1, sizeof link1, "%s/link1", dir);
    snprintf(link2, sizeof link2, "%s/link2", dir);
    snprintf(dangling, sizeof dangling, "%s/dangling", dir);
    snprintf(loop, sizeof loop, "%s/loop", dir);
    write_file(target, "old");
    CHECK(symlink("target.txt", link1) == 0 && symlink("link1", link2) == 0, "symlinks");
    cdvr_atomic_file af;
    cdvr_error err;
    CHECK_OK(cdvr_atomic_open(&af, link2, &err), err);
    fputs("new", af.f);
    CHECK_OK(cdvr_atomic_commit(&af, 0, &err), err);
    struct stat sb;
    CHECK(lstat(link2, &sb) == 0 && S_ISLNK(sb.st_mode) && lstat(link1, &sb) == 0 && S_ISLNK(sb.st_mode),
          "the links stay links");
    CHECK(read_all(target, buf, sizeof buf) && strcmp(buf, "new") == 0, "the target got the data");

    CHECK(symlink("created.txt", dangling) == 0, "dangling symlink");
    CHECK_OK(cdvr_atomic_open(&af, dangling, &err), err);
    fputs("made", af.f);
    CHECK_OK(cdvr_atomic_commit(&af, 0, &err), err);
    char created[300];
    snprintf(created, sizeof created, "%s/created.txt", dir);
    CHECK(read_all(created, buf, sizeof buf) && strcmp(buf, "made") == 0 && lstat(dangling, &sb) == 0 &&
              S_ISLNK(sb.st_mode),
          "a dangling link's target is created");

    CHECK(symlink("loop", loop) == 0, "loop symlink");
    CHECK(cdvr_atomic_open(&af, loop, &err) == CDVR_ERR_IO && strstr(err.msg, loop), "link loop: %s", err.msg);
    unlink(link2);
    unlink(link1);
    unlink(target);
    unlink(dangling);
    unlink(created);
    unlink(loop);
}

static void check_mode_kept(const char *dir)
{
    char path[300];
    snprintf(path, sizeof path, "%s/private.txt", dir);
    write_file(path, "x");
    chmod(path, 0600);
    cdvr_atomic_file af;
    cdvr_error err;
    CHECK_OK(cdvr_atomic_open(&af, path, &err), err);
    fputs("y", af.f);
    CHECK_OK(cdvr_atomic_commit(&af, 0, &err), err);
    struct stat sb;
    CHECK(stat(path, &sb) == 0 && (sb.st_mode & 0777) == 0600, "the replaced file's mode is kept");
    unlink(path);
}

/* A child opens an atomic file (named: CDVR_ATOMIC_NAMED=1), writes, tells the parent through
 * a pipe and waits; the parent sends sig. The child must die by sig; *left gets the number of
 * directory entries the child left beyond those before; *child its pid. */
static void kill_writer(const char *dir, int sig, int named, int *left, pid_t *child)
{
    char path[300];
    snprintf(path, sizeof path, "%s/signalled.bin", dir);
    int before = count_entries(dir), fds[2];
    CHECK(pipe(fds) == 0, "pipe");
    pid_t pid = fork();
    if (pid == 0) {
        close(fds[0]);
        signal(sig, SIG_DFL);
        if (named)
            setenv("CDVR_ATOMIC_NAMED", "1", 1);
        else
            unsetenv("CDVR_ATOMIC_NAMED");
        cdvr_atomic_file af;
        if (cdvr_atomic_open(&af, path, NULL) != CDVR_OK)
            _exit(3);
        fputs("partial", af.f);
        fflush(af.f);
        if (named != (af.tmp_path && access(af.tmp_path, F_OK) == 0))
            _exit(4); /* named: the temporary stands; unnamed: it has no name */
        if (write(fds[1], "r", 1) != 1)
            _exit(5);
        for (;;)
            pause(); /* until the signal ends the process */
    }
    close(fds[1]);
    char c;
    CHECK(pid > 0 && read(fds[0], &c, 1) == 1, "the writer is writing (signal %d)", sig);
    close(fds[0]);
    kill(pid, sig);
    int status = 0;
    CHECK(pid > 0 && waitpid(pid, &status, 0) == pid, "fork/wait");
    CHECK(WIFSIGNALED(status) && WTERMSIG(status) == sig, "child ended by signal %d (status 0x%x)", sig, status);
    CHECK(access(path, F_OK) != 0, "nothing under the final name after signal %d", sig);
    *left = count_entries(dir) - before;
    *child = pid;
}

/* Every catchable terminating signal removes the named temporary. */
static void check_signal_cleanup(const char *dir)
{
    static const int sigs[] = {SIGINT,  SIGTERM, SIGQUIT, SIGHUP,  SIGUSR1,   SIGUSR2,
                               SIGPIPE, SIGALRM, SIGXCPU, SIGXFSZ, SIGVTALRM, SIGPROF};
    for (size_t i = 0; i < sizeof sigs / sizeof sigs[0]; i++) {
        int left;
        pid_t pid;
        kill_writer(dir, sigs[i], 1, &left, &pid);
        CHECK(left == 0, "no temporary file left after signal %d (%d left)", sigs[i], left);
    }
}

/* 1 when dir holds an entry whose name starts with prefix. */
static int has_prefix(const char *dir, const char *prefix)
{
    DIR *d = opendir(dir);
    struct dirent *e;
    int found = 0;
    while (d && (e = readdir(d)))
        found |= strncmp(e->d_name, prefix, strlen(prefix)) == 0;
    if (d)
        closedir(d);
    return found;
}

/* SIGKILL: with O_TMPFILE nothing is left under any name; on the named path the temporary
 * stays with the dead pid in its name and the next writer of the same file removes it, but
 * keeps the temporary of a live process. */
static void check_sigkill(const char *dir)
{
    int fd = open(dir, O_TMPFILE | O_WRONLY, 0600);
    if (fd >= 0) {
        close(fd);
        int left;
        pid_t pid;
        kill_writer(dir, SIGKILL, 0, &left, &pid);
        CHECK(left == 0, "O_TMPFILE: SIGKILL left %d entries", left);
    } else {
        printf("note: %s has no O_TMPFILE; the unnamed case is skipped\n", dir);
    }
    int left;
    pid_t pid;
    kill_writer(dir, SIGKILL, 1, &left, &pid);
    char stale[64], live[300], path[300];
    snprintf(stale, sizeof stale, "signalled.bin.tmp.%ld.", (long)pid);
    CHECK(left == 1 && has_prefix(dir, stale), "named: SIGKILL left %s* (%d entries)", stale, left);
    snprintf(live, sizeof live, "%s/signalled.bin.tmp.%ld.abcdef", dir, (long)getpid());
    write_file(live, "mine");
    snprintf(path, sizeof path, "%s/signalled.bin", dir);
    cdvr_atomic_file af;
    cdvr_error err;
    CHECK_OK(cdvr_atomic_open(&af, path, &err), err);
    CHECK(!has_prefix(dir, stale), "the next writer removed the dead writer's %s*", stale);
    CHECK(access(live, F_OK) == 0, "a live writer's temporary is kept");
    fputs("whole", af.f);
    CHECK_OK(cdvr_atomic_commit(&af, 0, &err), err);
    unlink(live);
    unlink(path);
}

/* Unnamed (O_TMPFILE) writes: nothing in the directory until commit; commit links the file in
 * as a new name and also replaces an existing file (through a temporary name renamed over it),
 * leaving nothing else. */
static void check_unnamed(const char *dir)
{
    int fd = open(dir, O_TMPFILE | O_WRONLY, 0600);
    if (fd < 0) {
        printf("note: %s has no O_TMPFILE; unnamed writes are not checked\n", dir);
        return;
    }
    close(fd);
    unsetenv("CDVR_ATOMIC_NAMED");
    char path[300], buf[64];
    snprintf(path, sizeof path, "%s/unnamed.txt", dir);
    int before = count_entries(dir);
    for (int round = 0; round < 2; round++) { /* a new file, then a replaced one */
        cdvr_atomic_file af;
        cdvr_error err;
        CHECK_OK(cdvr_atomic_open(&af, path, &err), err);
        CHECK(af.unnamed && !af.tmp_path, "O_TMPFILE used");
        fputs(round ? "two" : "one", af.f);
        CHECK(count_entries(dir) == before + round, "nothing new visible before commit (round %d)", round);
        CHECK_OK(cdvr_atomic_commit(&af, 0, &err), err);
        CHECK(read_all(path, buf, sizeof buf) && strcmp(buf, round ? "two" : "one") == 0, "committed (round %d)", round);
        CHECK(count_entries(dir) == before + 1, "only the file itself (round %d)", round);
    }
    cdvr_atomic_file af;
    cdvr_error err;
    CHECK_OK(cdvr_atomic_open(&af, path, &err), err);
    fputs("failed", af.f);
    CHECK(cdvr_atomic_commit(&af, 1, &err) == CDVR_ERR_IO, "failure reported");
    CHECK(read_all(path, buf, sizeof buf) && strcmp(buf, "two") == 0 && count_entries(dir) == before + 1,
          "a failed unnamed write leaves the old file and nothing else");
    unlink(path);
    setenv("CDVR_ATOMIC_NAMED", "1", 1);
}

/* An ignored SIGTERM stays ignored: the writer goes on and commits. */
static void check_ignored_signal(const char *dir)
{
    char path[300];
    snprintf(path, sizeof path, "%s/ignored.bin", dir);
    pid_t pid = fork();
    if (pid == 0) {
        signal(SIGTERM, SIG_IGN);
        cdvr_atomic_file af;
        if (cdvr_atomic_open(&af, path, NULL) != CDVR_OK)
            _exit(3);
        raise(SIGTERM);
        fputs("done", af.f);
        _exit(cdvr_atomic_commit(&af, 0, NULL) == CDVR_OK ? 0 : 4);
    }
    int status = 0;
    CHECK(pid > 0 && waitpid(pid, &status, 0) == pid, "fork/wait");
    CHECK(WIFEXITED(status) && WEXITSTATUS(status) == 0, "ignored SIGTERM: the child committed (status 0x%x)", status);
    CHECK(access(path, F_OK) == 0, "file written");
    unlink(path);
}

int main(void)
{
    setenv("CDVR_ATOMIC_NAMED", "1", 1); /* the named path, except where a check says otherwise */
    char dir[] = "atomicfile_test_XXXXXX";
    CHECK(mkdtemp(dir) != NULL, "mkdtemp");
    char path[256], buf[64];
    snprintf(path, sizeof path, "%s/out.txt", dir);
    cdvr_error err;

    cdvr_atomic_file af;
    CHECK_OK(cdvr_atomic_open(&af, path, &err), err);
    fputs("first", af.f);
    CHECK(access(path, F_OK) != 0, "nothing under the final name before commit");
    CHECK_OK(cdvr_atomic_commit(&af, 0, &err), err);
    CHECK(read_all(path, buf, sizeof buf) && strcmp(buf, "first") == 0, "committed contents");
    struct stat sb;
    CHECK(stat(path, &sb) == 0 && (sb.st_mode & 0777) == 0644, "mode 0644");
    CHECK(count_entries(dir) == 1, "no temporary file left");

    /* a failed write keeps the old file and leaves no temporary */
    CHECK_OK(cdvr_atomic_open(&af, path, &err), err);
    fputs("second, half", af.f);
    CHECK(cdvr_atomic_commit(&af, 1, &err) == CDVR_ERR_IO && strstr(err.msg, path), "failure reported: %s", err.msg);
    CHECK(read_all(path, buf, sizeof buf) && strcmp(buf, "first") == 0, "old contents kept");
    CHECK(count_entries(dir) == 1, "temporary removed after failure");

    /* missing directory: error names the path */
    char bad[300];
    snprintf(bad, sizeof bad, "%s/no/such/dir/x.png", dir);
    CHECK(cdvr_atomic_open(&af, bad, &err) == CDVR_ERR_IO && strstr(err.msg, bad) && !af.f, "missing dir: %s", err.msg);

    /* a directory is not replaced: refused before any temporary file exists */
    char sub[300];
    snprintf(sub, sizeof sub, "%s/sub", dir);
    mkdir(sub, 0755);
    char inner[320];
    snprintf(inner, sizeof inner, "%s/x", sub);
    FILE *f = fopen(inner, "w");
    if (f)
        fclose(f);
    CHECK(cdvr_atomic_open(&af, sub, &err) == CDVR_ERR_IO && strstr(err.msg, "a directory") && strstr(err.msg, sub),
          "directory refused: %s", err.msg);
    CHECK(count_entries(dir) == 2, "only out.txt and sub remain");

    check_fifo(dir);
    check_symlinks(dir);
    check_mode_kept(dir);
    check_signal_cleanup(dir);
    check_sigkill(dir);
    check_unnamed(dir);
    check_ignored_signal(dir);

    unlink(inner);
    rmdir(sub);
    unlink(path);
    rmdir(dir);
    return check_finish();
}
