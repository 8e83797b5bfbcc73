/* core/base/atomicfile.c and cleanup.c: complete file or nothing under the final name, no temporary
 * left (also when the writer is killed by SIGINT or SIGTERM), symbolic links written through,
 * non-regular files never replaced. */
#include <dirent.h>
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

/* A child opens an atomic file and is killed by sig while writing: it dies by that signal
 * and its temporary file is gone. */
static void check_signal_cleanup(const char *dir, int sig)
{
    char path[300];
    snprintf(path, sizeof path, "%s/signalled.bin", dir);
    int before = count_entries(dir);
    pid_t pid = fork();
    if (pid == 0) {
        signal(sig, SIG_DFL);
        cdvr_atomic_file af;
        if (cdvr_atomic_open(&af, path, NULL) != CDVR_OK)
            _exit(3);
        fputs("partial", af.f);
        fflush(af.f);
        if (access(af.tmp_path, F_OK) != 0)
            _exit(4);
        raise(sig);
        _exit(5); /* not reached: the signal ends the process */
    }
    int status = 0;
    CHECK(pid > 0 && waitpid(pid, &status, 0) == pid, "fork/wait");
    CHECK(WIFSIGNALED(status) && WTERMSIG(status) == sig, "child ended by signal %d (status 0x%x)", sig, status);
    CHECK(count_entries(dir) == before, "no temporary file left after signal %d", sig);
    CHECK(access(path, F_OK) != 0, "nothing under the final name");
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
    check_signal_cleanup(dir, SIGTERM);
    check_signal_cleanup(dir, SIGINT);
    check_ignored_signal(dir);

    unlink(inner);
    rmdir(sub);
    unlink(path);
    rmdir(dir);
    return check_finish();
}
