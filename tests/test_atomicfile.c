/* core/base/atomicfile.c: complete file or nothing under the final name, no temporary left. */
#include <dirent.h>
#include <string.h>
#include <sys/stat.h>
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

    /* rename onto a directory fails and cleans up */
    char sub[300];
    snprintf(sub, sizeof sub, "%s/sub", dir);
    mkdir(sub, 0755);
    char inner[320];
    snprintf(inner, sizeof inner, "%s/x", sub);
    FILE *f = fopen(inner, "w");
    if (f)
        fclose(f);
    CHECK_OK(cdvr_atomic_open(&af, sub, &err), err);
    fputs("x", af.f);
    CHECK(cdvr_atomic_commit(&af, 0, &err) == CDVR_ERR_IO, "rename onto a non-empty directory fails");
    CHECK(count_entries(dir) == 2, "only out.txt and sub remain");

    unlink(inner);
    rmdir(sub);
    unlink(path);
    rmdir(dir);
    return check_finish();
}
