/* Readers read only what the user named and replace no header field silently (issue 21, items 4
 * and 5). Every case writes its own hostile file here (NRRD and NIfTI headers, a store patched
 * with a recomputed CRC-32C) and runs in a child process under a CPU-time limit, an alarm and, in
 * the normal build, an address-space limit (setrlimit), so a hang or a blow-up fails the case;
 * the child's peak RSS (wait4) is checked too. Proven:
 *  - a detached NRRD's data files (a name, "..", a symlink, LIST, a printf list) outside the
 *    header's directory are refused naming the path, and load with allow_outside; a header
 *    reached through a symbolic link reads files relative to the link (as teem does);
 *  - a LIST of 200000 files and a NIfTI with 100000 extensions are refused within a second,
 *    naming the limit; a gzip stream that holds more than the header claims is refused; a claim
 *    above max_bytes is refused before anything is inflated (and the default is half the
 *    physical memory);
 *  - NRRD loads (raw, gzip, f64 -> f32) peak at one copy of the volume, and the reader that
 *    fills it honours line skip, byte skip (also -1), endian, gzip, bzip2 over a LIST, and ascii
 *    and hex (read by teem);
 *  - NIfTI vox_offset 1e18, 100, 352.5 and a bad magic are refused, 368 is honoured; a singular
 *    sform and pixdim 0/NaN/inf are refused; NRRD zero space directions, NaN spacing and a double
 *    beyond f32 are refused, a -1 spacing is honoured (axis backwards); a store whose direction
 *    matrix is all zero is refused naming the file.
 */
#include <bzlib.h>
#include <errno.h>
#include <math.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/time.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>
#include <zlib.h>

#include "cdvr/codec.h"
#include "cdvr/crc32c.h"
#include "cdvr/store.h"
#include "cdvr/volume.h"
#include "check.h"

#if defined(__SANITIZE_ADDRESS__)
#define UNDER_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define UNDER_ASAN 1
#endif
#endif
#ifndef UNDER_ASAN
#define UNDER_ASAN 0
#endif

static char dir_[64];
static char msg_[CDVR_ERRMSG_MAX + 64]; /* the child's message about its case */

static const char *at(const char *name)
{
    static char path[8][512];
    static int k;
    k = (k + 1) % 8;
    snprintf(path[k], sizeof path[k], "%s/%s", dir_, name);
    return path[k];
}

static void put(const char *name, const void *a, size_t na, const void *b, size_t nb)
{
    FILE *f = fopen(at(name), "wb");
    if (!f || fwrite(a, 1, na, f) != na || (nb && fwrite(b, 1, nb, f) != nb) || fclose(f) != 0) {
        fprintf(stderr, "cannot write %s: %s\n", at(name), strerror(errno));
        exit(2);
    }
}

static void put_text(const char *name, const char *text)
{
    put(name, text, strlen(text), NULL, 0);
}

static unsigned char *gzip_of(const void *data, size_t n, size_t *out_n)
{
    uLongf cap = compressBound((uLong)n) + 64;
    unsigned char *out = malloc(cap);
    z_stream z;
    memset(&z, 0, sizeof z);
    if (!out || deflateInit2(&z, 1, Z_DEFLATED, 15 + 16, 8, Z_DEFAULT_STRATEGY) != Z_OK)
        exit(2);
    z.next_in = (unsigned char *)data;
    z.avail_in = (uInt)n;
    z.next_out = out;
    z.avail_out = (uInt)cap;
    if (deflate(&z, Z_FINISH) != Z_STREAM_END)
        exit(2);
    *out_n = z.total_out;
    deflateEnd(&z);
    return out;
}

/* ---- running a case in a child ------------------------------------------------------------ */

static long rss_kb(void)
{
    struct rusage ru;
    getrusage(RUSAGE_SELF, &ru);
    return ru.ru_maxrss;
}

/* Runs fn in a child with limits; fn returns 1 when the case holds and leaves a message. */
static void run_case(const char *name, int (*fn)(void), int seconds, long mem_mb)
{
    int fds[2];
    if (pipe(fds) != 0)
        exit(2);
    struct timespec t0, t1;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    pid_t pid = fork();
    if (pid == 0) {
        close(fds[0]);
        struct rlimit cpu = {(rlim_t)seconds, (rlim_t)seconds + 1};
        setrlimit(RLIMIT_CPU, &cpu);
        if (!UNDER_ASAN && mem_mb > 0) {
            struct rlimit as = {(rlim_t)mem_mb << 20, (rlim_t)mem_mb << 20};
            setrlimit(RLIMIT_AS, &as);
        }
        alarm((unsigned)seconds * 2 + 2);
        msg_[0] = '\0';
        int ok = fn();
        if (write(fds[1], msg_, strlen(msg_)) < 0)
            _exit(3);
        _exit(ok ? 0 : 1);
    }
    close(fds[1]);
    char msg[sizeof msg_] = {0};
    ssize_t got = 0, n;
    while (got < (ssize_t)sizeof msg - 1 && (n = read(fds[0], msg + got, sizeof msg - 1 - (size_t)got)) > 0)
        got += n;
    close(fds[0]);
    int status = 0;
    struct rusage ru;
    memset(&ru, 0, sizeof ru);
    wait4(pid, &status, 0, &ru);
    clock_gettime(CLOCK_MONOTONIC, &t1);
    double secs = (double)(t1.tv_sec - t0.tv_sec) + 1e-9 * (double)(t1.tv_nsec - t0.tv_nsec);
    CHECK(WIFEXITED(status) && WEXITSTATUS(status) == 0, "%s: %s (%s %d, %.2f s, peak %ld KB)",
          name, msg[0] ? msg : "(no message)", WIFSIGNALED(status) ? "signal" : "exit",
          WIFSIGNALED(status) ? WTERMSIG(status) : WEXITSTATUS(status), secs, ru.ru_maxrss);
    printf("%-28s %s %.2f s, peak %ld KB: %s\n", name,
           WIFEXITED(status) && WEXITSTATUS(status) == 0 ? "ok  " : "FAIL", secs, ru.ru_maxrss, msg);
}

/* Load path with opts; 1 when refused with a message holding want (and want2 unless NULL). */
static int refused(const char *path, const cdvr_raw_opts *opts, const char *want, const char *want2)
{
    cdvr_volume *v = NULL;
    cdvr_error err;
    cdvr_status st = cdvr_volume_load(path, opts, &v, &err);
    cdvr_volume_free(v);
    if (st == CDVR_OK) {
        snprintf(msg_, sizeof msg_, "%s: loaded, expected a refusal", path);
        return 0;
    }
    snprintf(msg_, sizeof msg_, "%s", err.msg);
    return strstr(err.msg, want) && (!want2 || strstr(err.msg, want2));
}

static cdvr_volume *loads(const char *path, const cdvr_raw_opts *opts)
{
    cdvr_volume *v = NULL;
    cdvr_error err;
    if (cdvr_volume_load(path, opts, &v, &err) != CDVR_OK) {
        snprintf(msg_, sizeof msg_, "%s", err.msg);
        return NULL;
    }
    snprintf(msg_, sizeof msg_, "loaded");
    return v;
}

/* ---- item 4: only what was named --------------------------------------------------------- */

static const cdvr_raw_opts outside_ok = {.allow_outside = 1};

static int c_abs(void) { return refused(at("sub/abs.nhdr"), NULL, "outside the header's directory", "/etc/passwd"); }
static int c_dotdot(void) { return refused(at("sub/dotdot.nhdr"), NULL, "outside the header's directory", "etc/passwd"); }
static int c_symlink(void) { return refused(at("sub/link.nhdr"), NULL, "outside the header's directory", "link.raw"); }
static int c_list(void) { return refused(at("sub/list.nhdr"), NULL, "outside the header's directory", "outside32.raw"); }
static int c_format(void) { return refused(at("sub/fmt.nhdr"), NULL, "outside the header's directory", "slab1.raw"); }

static int c_allowed(void)
{
    const char *names[] = {"sub/link.nhdr", "sub/up.nhdr", "sub/list.nhdr", "sub/fmt.nhdr"};
    for (int i = 0; i < 4; i++) {
        cdvr_volume *v = loads(at(names[i]), &outside_ok);
        int ok = v && v->dims[0] == 4 && ((unsigned char *)v->data)[5] == 5;
        cdvr_volume_free(v);
        if (!ok) {
            size_t n = strlen(msg_);
            snprintf(msg_ + n, sizeof msg_ - n, " (%s with allow_outside)", names[i]);
            return 0;
        }
    }
    /* a header reached through a symbolic link names files relative to the link's directory
     * (as teem opens them): sub2/in.raw is inside */
    cdvr_volume *v = loads(at("sub2/link.nhdr"), NULL);
    int ok = v && ((unsigned char *)v->data)[5] == 5;
    cdvr_volume_free(v);
    if (!ok) {
        size_t n = strlen(msg_);
        snprintf(msg_ + n, sizeof msg_ - n, " (sub2/link.nhdr, a link to sub/inside.nhdr)");
        return 0;
    }
    /* and the series probe refuses the same file without the option */
    cdvr_volume head;
    cdvr_error err;
    if (cdvr_volume_probe(at("sub/up.nhdr"), NULL, &head, &err) == CDVR_OK ||
        !strstr(err.msg, "outside")) {
        snprintf(msg_, sizeof msg_, "probe: %s", err.msg);
        return 0;
    }
    return 1;
}

static int c_list_200000(void) { return refused(at("list200k.nhdr"), NULL, "LIST names 200000 files", "limit"); }
static int c_nifti_ext(void) { return refused(at("ext100k.nii"), NULL, "more than 1024 extensions", "limit"); }
static int c_gz_more(void) { return refused(at("gz_more.nrrd"), NULL, "more data than the header claims", "gz_more.nrrd"); }

static int c_max_bytes(void)
{
    cdvr_raw_opts o = {.max_bytes = 64u << 20};
    return refused(at("bomb.nrrd"), &o, "more than max_bytes 67108864", "bomb.nrrd");
}

static int c_max_default(void)
{
    long pages = sysconf(_SC_PHYS_PAGES), size = sysconf(_SC_PAGESIZE);
    uint64_t half = (uint64_t)pages * (uint64_t)size / 2;
    snprintf(msg_, sizeof msg_, "default max_bytes %llu, half the memory %llu",
             (unsigned long long)cdvr_load_max_bytes_default(), (unsigned long long)half);
    cdvr_raw_opts o = {.dims = {1024, 1024, 1024}, .type = CDVR_TYPE_U8, .max_bytes = 1u << 20};
    return cdvr_load_max_bytes_default() == half && cdvr_load_max_bytes(NULL) == half &&
           refused(at("sub/in.raw"), &o, "max_bytes 1048576", NULL);
}

/* The volume's bytes; the load must peak at about one copy of them. */
static int one_copy(const char *name, size_t bytes)
{
    long before = rss_kb();
    cdvr_volume *v = loads(at(name), NULL);
    long grew = rss_kb() - before;
    int ok = v && cdvr_volume_voxels(v) * cdvr_type_size(v->type) == bytes &&
             (long)(bytes / 1024) * 5 / 4 + 8192 > grew; /* 2x before */
    if (v && v->type == CDVR_TYPE_U8)
        ok = ok && ((unsigned char *)v->data)[bytes - 1] == (unsigned char)((bytes - 1) % 251);
    if (v && v->type == CDVR_TYPE_F32)
        ok = ok && ((float *)v->data)[bytes / 4 - 1] == (float)((bytes / 4 - 1) % 1000) * 0.5f;
    snprintf(msg_, sizeof msg_, "%s: volume %zu KB, peak RSS grew by %ld KB", name, bytes / 1024, grew);
    cdvr_volume_free(v);
    return ok;
}
static int c_copy_raw(void) { return one_copy("big.nrrd", 64u << 20); }
static int c_copy_gz(void) { return one_copy("big_gz.nrrd", 64u << 20); }
static int c_copy_f64(void) { return one_copy("big_f64.nrrd", 16u << 20); }

/* u16 value i * 7 + 3 for 4x4x4 voxels, in files of every encoding the reader handles */
static int c_encodings(void)
{
    const char *names[] = {"enc_skip.nrrd", "enc_skip_end.nhdr", "enc_gz_skip.nrrd",
                           "enc_bz_list.nhdr", "enc_ascii.nrrd", "enc_hex.nrrd"};
    for (int f = 0; f < 6; f++) {
        cdvr_volume *v = loads(at(names[f]), NULL);
        int ok = v && v->type == CDVR_TYPE_U16 && cdvr_volume_voxels(v) == 64;
        for (int i = 0; ok && i < 64; i++)
            ok = ((uint16_t *)v->data)[i] == (uint16_t)(i * 7 + 3);
        cdvr_volume_free(v);
        if (!ok) {
            size_t n = strlen(msg_);
            snprintf(msg_ + n, sizeof msg_ - n, " (%s: wrong values)", names[f]);
            return 0;
        }
    }
    snprintf(msg_, sizeof msg_, "6 encodings read the same values");
    return 1;
}

/* ---- item 5: fields honoured or refused ---------------------------------------------------- */

static int c_off_1e18(void) { return refused(at("off1e18.nii"), NULL, "vox_offset 1e+18", NULL); }
static int c_off_100(void) { return refused(at("off100.nii"), NULL, "vox_offset 100 ", NULL); }
static int c_off_frac(void) { return refused(at("off352_5.nii"), NULL, "vox_offset 352.5", NULL); }
static int c_off_368(void)
{
    cdvr_volume *v = loads(at("off368.nii"), NULL);
    int ok = v && ((unsigned char *)v->data)[0] == 101 && ((unsigned char *)v->data)[63] == 164;
    if (v)
        snprintf(msg_, sizeof msg_, "voxel 0 = %d (want 101: data from byte 368)", ((unsigned char *)v->data)[0]);
    cdvr_volume_free(v);
    return ok;
}
static int c_magic(void) { return refused(at("magic.nii"), NULL, "magic is \"xx1\"", NULL); }
static int c_sform(void) { return refused(at("sform0.nii"), NULL, "sform (sform_code 1) is singular", NULL); }
static int c_pix0(void) { return refused(at("pix0.nii"), NULL, "pixdim[2] = 0", NULL); }
static int c_pixnan(void) { return refused(at("pixnan.nii"), NULL, "pixdim[1] = nan", NULL); }
static int c_pixinf(void) { return refused(at("pixinf.nii"), NULL, "pixdim[3] = inf", NULL); }
static int c_zero_dir(void) { return refused(at("zerodir.nrrd"), NULL, "space directions of axis 1 is (0,0,0): a zero vector", NULL); }
static int c_nan_spacing(void) { return refused(at("nanspacing.nrrd"), NULL, "spacings of axis 0 is nan", NULL); }
static int c_neg_spacing(void)
{
    cdvr_volume *v = loads(at("negspacing.nrrd"), NULL);
    int ok = v && v->spacing[0] == 1 && v->direction[0] == -1 && v->spacing[1] == 2;
    if (v)
        snprintf(msg_, sizeof msg_, "spacing %g %g, direction[0] %g (want 1 2, -1: the axis runs backwards)",
                 v->spacing[0], v->spacing[1], v->direction[0]);
    cdvr_volume_free(v);
    return ok;
}
static int c_f64_huge(void) { return refused(at("f64huge.nrrd"), NULL, "NRRD value 1e+300", "beyond the range of f32"); }

static int c_store_dir(void)
{
    cdvr_store *st = NULL;
    cdvr_error err;
    cdvr_status s = cdvr_store_open(at("zerodir.cdv"), &st, &err);
    cdvr_store_close(st);
    if (s == CDVR_OK) {
        snprintf(msg_, sizeof msg_, "zerodir.cdv: opened, expected a refusal");
        return 0;
    }
    snprintf(msg_, sizeof msg_, "%s", err.msg);
    return strstr(err.msg, "zerodir.cdv") && strstr(err.msg, "direction matrix 0 0 0");
}

/* ---- the files ---------------------------------------------------------------------------- */

/* A 348-byte NIfTI-1 header, 4 extender bytes, 16 pad bytes and 64 u8 voxels of 4x4x4 (value
 * i + 1 at byte 352 + i for i < 16, value i + 101 at byte 368 + i). */
static void put_nifti(const char *name, const char *magic, float vox_offset, const float pix[3],
                      short sform_code)
{
    unsigned char h[368 + 64];
    memset(h, 0, sizeof h);
    int32_t sz = 348;
    short dim[8] = {3, 4, 4, 4, 1, 1, 1, 1};
    short datatype = 2, bitpix = 8;
    float pixdim[8] = {1, pix[0], pix[1], pix[2], 1, 0, 0, 0};
    memcpy(h, &sz, 4);
    memcpy(h + 40, dim, sizeof dim);
    memcpy(h + 70, &datatype, 2);
    memcpy(h + 72, &bitpix, 2);
    memcpy(h + 76, pixdim, sizeof pixdim);
    memcpy(h + 108, &vox_offset, 4);
    memcpy(h + 254, &sform_code, 2); /* srow_x/y/z (bytes 280..327) stay 0: singular */
    memcpy(h + 344, magic, 4);
    for (int i = 0; i < 16; i++)
        h[352 + i] = (unsigned char)(i + 1);
    for (int i = 0; i < 64; i++)
        h[368 + i] = (unsigned char)(i + 101);
    put(name, h, sizeof h, NULL, 0);
}

static void make_store_zero_direction(void)
{
    size_t dims[3] = {8, 8, 8};
    cdvr_volume *v;
    cdvr_error err;
    if (cdvr_volume_create(dims, 1, CDVR_TYPE_U8, &v, &err) != CDVR_OK)
        exit(2);
    cdvr_variant_spec spec = {.codec = cdvr_codec_find("raw"), .lzo_min_saving = -1};
    spec.codec->params_default(&spec.params);
    snprintf(spec.name, sizeof spec.name, "raw");
    cdvr_encode_opts o = {.variants = &spec, .nvariants = 1, .qlo = 0, .qhi = 255,
                          .source_type = CDVR_TYPE_U8, .threads = 1};
    if (cdvr_store_encode(v, &o, at("zerodir.cdv"), &err) != CDVR_OK) {
        fprintf(stderr, "encode: %s\n", err.msg);
        exit(2);
    }
    cdvr_volume_free(v);
    FILE *f = fopen(at("zerodir.cdv"), "r+b");
    unsigned char buf[1 << 16];
    size_t n = f ? fread(buf, 1, sizeof buf, f) : 0;
    uint64_t meta = 0;
    for (int b = 0; b < 8; b++)
        meta |= (uint64_t)buf[16 + b] << (8 * b);
    if (!f || n < 256 || meta + 4 > n)
        exit(2);
    memset(buf + 104, 0, 72); /* the direction matrix, all zero; the metadata CRC made anew */
    uint32_t crc = cdvr_crc32c(0, buf, (size_t)meta);
    for (int b = 0; b < 4; b++)
        buf[meta + (size_t)b] = (unsigned char)(crc >> (8 * b));
    if (fseek(f, 0, SEEK_SET) != 0 || fwrite(buf, 1, (size_t)meta + 4, f) != meta + 4 || fclose(f) != 0)
        exit(2);
}

static void make_files(void)
{
    char path[600];
    snprintf(path, sizeof path, "%s/sub", dir_);
    mkdir(path, 0755);
    unsigned char v64[64];
    for (int i = 0; i < 64; i++)
        v64[i] = (unsigned char)i;
    put("outside.raw", v64, 64, NULL, 0);
    put("slab1.raw", v64, 32, NULL, 0);
    put("slab2.raw", v64 + 32, 32, NULL, 0);
    put("sub/in.raw", v64, 64, NULL, 0);
    put("sub/in32.raw", v64, 32, NULL, 0);
    put("outside32.raw", v64 + 32, 32, NULL, 0);
    snprintf(path, sizeof path, "%s/sub2", dir_);
    mkdir(path, 0755);
    put("sub2/in.raw", v64, 64, NULL, 0);
    put_text("sub/inside.nhdr", "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 4 4 4\nencoding: raw\n"
             "data file: in.raw\n");
    snprintf(path, sizeof path, "%s/sub2/link.nhdr", dir_);
    unlink(path);
    if (symlink("../sub/inside.nhdr", path) != 0)
        exit(2);
    snprintf(path, sizeof path, "%s/sub/link.raw", dir_);
    unlink(path);
    if (symlink("../outside.raw", path) != 0)
        exit(2);
    const char *u8 = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 4 4 4\nencoding: raw\n";
    char hdr[4096];
    static const struct { const char *name, *data; } detached[] = {
        {"sub/abs.nhdr", "data file: /etc/passwd\n"},
        {"sub/dotdot.nhdr", "data file: ../../../../../../../../../../../etc/passwd\n"},
        {"sub/link.nhdr", "data file: link.raw\n"},
        {"sub/up.nhdr", "data file: ../outside.raw\n"},
        {"sub/list.nhdr", "data file: LIST 3\nin32.raw\n../outside32.raw\n"},
        {"sub/fmt.nhdr", "data file: ../slab%d.raw 1 2 1 3\n"},
    };
    for (size_t i = 0; i < sizeof detached / sizeof *detached; i++) {
        snprintf(hdr, sizeof hdr, "%s%s", i < 2 ? "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 1 1 1\nencoding: raw\n" : u8,
                 detached[i].data);
        put_text(detached[i].name, hdr);
    }
    /* LIST of 200000 one-byte files (one file, named 200000 times) */
    put("x.raw", v64, 1, NULL, 0);
    FILE *f = fopen(at("list200k.nhdr"), "wb");
    fputs("NRRD0004\ntype: uchar\ndimension: 3\nsizes: 1 1 200000\nencoding: raw\ndata file: LIST\n", f);
    for (int i = 0; i < 200000; i++)
        fputs("x.raw\n", f);
    fclose(f);
    /* NIfTI with 100000 empty extensions (16 bytes each) */
    {
        size_t next = 100000, off = 352 + 16 * next;
        unsigned char *b = calloc(1, off + 64);
        float pix[3] = {1, 1, 1};
        put_nifti("ext100k.nii", "n+1", 352, pix, 0);
        FILE *g = fopen(at("ext100k.nii"), "rb");
        if (!b || !g || fread(b, 1, 352, g) != 352)
            exit(2);
        fclose(g);
        float vo = (float)off;
        memcpy(b + 108, &vo, 4);
        b[348] = 1;
        for (size_t e = 0; e < next; e++) {
            int32_t esize = 16, ecode = 4;
            memcpy(b + 352 + 16 * e, &esize, 4);
            memcpy(b + 356 + 16 * e, &ecode, 4);
        }
        put("ext100k.nii", b, off + 64, NULL, 0);
        free(b);
    }
    /* a gzip stream of 8192 bytes where the header claims 4096 */
    {
        unsigned char z[8192];
        memset(z, 7, sizeof z);
        size_t gn;
        unsigned char *g = gzip_of(z, sizeof z, &gn);
        const char *h = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 16 16 16\nencoding: gzip\n\n";
        put("gz_more.nrrd", h, strlen(h), g, gn);
        free(g);
    }
    /* a consistent gzip bomb: 512 MiB of zeros (about 0.5 MB of gzip) */
    {
        size_t n = 512u << 20, gn;
        unsigned char *z = calloc(1, n), *g = z ? gzip_of(z, n, &gn) : NULL;
        const char *h = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 1024 1024 512\nencoding: gzip\n\n";
        if (!g)
            exit(2);
        put("bomb.nrrd", h, strlen(h), g, gn);
        free(z);
        free(g);
    }
    /* 64 MiB volumes, raw and gzip, and 32 MiB of f64 (16 MiB as f32) */
    {
        size_t n = 64u << 20, gn;
        unsigned char *p = malloc(n);
        for (size_t i = 0; p && i < n; i++)
            p[i] = (unsigned char)(i % 251);
        const char *h = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 512 512 256\nencoding: raw\n\n";
        put("big.nrrd", h, strlen(h), p, n);
        unsigned char *g = gzip_of(p, n, &gn);
        const char *hg = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 512 512 256\nencoding: gzip\n\n";
        put("big_gz.nrrd", hg, strlen(hg), g, gn);
        free(g);
        double *d = (double *)p;
        for (size_t i = 0; i < (4u << 20); i++)
            d[i] = (double)(i % 1000) * 0.5;
        const char *hd = "NRRD0004\ntype: double\ndimension: 3\nsizes: 256 256 64\nendian: little\nencoding: raw\n\n";
        put("big_f64.nrrd", hd, strlen(hd), d, 32u << 20);
        free(p);
    }
    /* the reader's encodings: u16 i * 7 + 3, little and big endian */
    {
        unsigned char le[128], be[128], text[1024], hex[300];
        size_t tn = 0, hn = 0, gn;
        for (int i = 0; i < 64; i++) {
            unsigned x = (unsigned)(i * 7 + 3);
            le[2 * i] = (unsigned char)x, le[2 * i + 1] = (unsigned char)(x >> 8);
            be[2 * i] = (unsigned char)(x >> 8), be[2 * i + 1] = (unsigned char)x;
            tn += (size_t)snprintf((char *)text + tn, sizeof text - tn, "%u\n", x);
        }
        for (int i = 0; i < 128; i++)
            hn += (size_t)snprintf((char *)hex + hn, sizeof hex - hn, "%02x", le[i]);
        const char *u16 = "NRRD0004\ntype: ushort\ndimension: 3\nsizes: 4 4 4\n";
        unsigned char buf[512];
        snprintf(hdr, sizeof hdr, "%sencoding: raw\nendian: big\nline skip: 2\nbyte skip: 3\n\n"
                 "junk line\nanother\nxyz", u16);
        put("enc_skip.nrrd", hdr, strlen(hdr), be, 128);
        memset(buf, 'j', 10);
        memcpy(buf + 10, le, 128);
        put("enc_end.raw", buf, 138, NULL, 0);
        snprintf(hdr, sizeof hdr, "%sencoding: raw\nendian: little\nbyte skip: -1\ndata file: enc_end.raw\n", u16);
        put_text("enc_skip_end.nhdr", hdr);
        memset(buf, 'k', 5);
        memcpy(buf + 5, le, 128);
        unsigned char *g = gzip_of(buf, 133, &gn);
        snprintf(hdr, sizeof hdr, "%sencoding: gzip\nendian: little\nbyte skip: 5\n\n", u16);
        put("enc_gz_skip.nrrd", hdr, strlen(hdr), g, gn);
        free(g);
        for (int half = 0; half < 2; half++) {
            char bz[512];
            unsigned bn = sizeof bz;
            if (BZ2_bzBuffToBuffCompress(bz, &bn, (char *)le + 64 * half, 64, 9, 0, 0) != BZ_OK)
                exit(2);
            put(half ? "enc_bz2.bz2" : "enc_bz1.bz2", bz, bn, NULL, 0);
        }
        snprintf(hdr, sizeof hdr, "%sencoding: bzip2\nendian: little\ndata file: LIST 3\nenc_bz1.bz2\nenc_bz2.bz2\n", u16);
        put_text("enc_bz_list.nhdr", hdr);
        snprintf(hdr, sizeof hdr, "%sencoding: ascii\n\n", u16);
        put("enc_ascii.nrrd", hdr, strlen(hdr), text, tn);
        snprintf(hdr, sizeof hdr, "%sencoding: hex\nendian: little\n\n", u16);
        put("enc_hex.nrrd", hdr, strlen(hdr), hex, hn);
    }
    /* item 5 */
    float one[3] = {1, 1, 1}, p0[3] = {1, 0, 1}, pnan[3] = {NAN, 1, 1}, pinf[3] = {1, 1, INFINITY};
    put_nifti("off1e18.nii", "n+1", 1e18f, one, 0);
    put_nifti("off100.nii", "n+1", 100, one, 0);
    put_nifti("off352_5.nii", "n+1", 352.5f, one, 0);
    put_nifti("off368.nii", "n+1", 368, one, 0);
    put_nifti("magic.nii", "xx1", 352, one, 0);
    put_nifti("sform0.nii", "n+1", 352, one, 1);
    put_nifti("pix0.nii", "n+1", 352, p0, 0);
    put_nifti("pixnan.nii", "n+1", 352, pnan, 0);
    put_nifti("pixinf.nii", "n+1", 352, pinf, 0);
    snprintf(hdr, sizeof hdr, "%sspace: RAS\nspace directions: (1,0,0) (0,0,0) (0,0,1)\n\n", u8);
    put("zerodir.nrrd", hdr, strlen(hdr), v64, 64);
    snprintf(hdr, sizeof hdr, "%sspacings: nan 1 1\n\n", u8);
    put("nanspacing.nrrd", hdr, strlen(hdr), v64, 64);
    snprintf(hdr, sizeof hdr, "%sspacings: -1 2 1\n\n", u8);
    put("negspacing.nrrd", hdr, strlen(hdr), v64, 64);
    const double d[2] = {1e300, -2.5};
    const char *hd = "NRRD0004\ntype: double\ndimension: 3\nsizes: 2 1 1\nendian: little\nencoding: raw\n\n";
    put("f64huge.nrrd", hd, strlen(hd), d, sizeof d);
    make_store_zero_direction();
}

int main(void)
{
    snprintf(dir_, sizeof dir_, "/tmp/cdvr_reader_limits_XXXXXX");
    if (!mkdtemp(dir_)) {
        perror("mkdtemp");
        return 1;
    }
    make_files();
    static const struct { const char *name; int (*fn)(void); int seconds; long mem_mb; } cases[] = {
        {"outside: absolute", c_abs, 10, 512},
        {"outside: ..", c_dotdot, 10, 512},
        {"outside: symlink", c_symlink, 10, 512},
        {"outside: LIST", c_list, 10, 512},
        {"outside: printf list", c_format, 10, 512},
        {"outside: allow_outside", c_allowed, 10, 512},
        {"LIST of 200000 files", c_list_200000, 2, 512},
        {"NIfTI 100000 extensions", c_nifti_ext, 2, 512},
        {"gzip longer than claimed", c_gz_more, 10, 512},
        {"gzip bomb over max_bytes", c_max_bytes, 2, 256},
        {"max_bytes default", c_max_default, 10, 512},
        {"one copy: raw", c_copy_raw, 20, 512},
        {"one copy: gzip", c_copy_gz, 20, 512},
        {"one copy: f64 -> f32", c_copy_f64, 20, 512},
        {"encodings read right", c_encodings, 10, 512},
        {"NIfTI vox_offset 1e18", c_off_1e18, 10, 512},
        {"NIfTI vox_offset 100", c_off_100, 10, 512},
        {"NIfTI vox_offset 352.5", c_off_frac, 10, 512},
        {"NIfTI vox_offset 368", c_off_368, 10, 512},
        {"NIfTI bad magic", c_magic, 10, 512},
        {"NIfTI singular sform", c_sform, 10, 512},
        {"NIfTI pixdim 0", c_pix0, 10, 512},
        {"NIfTI pixdim NaN", c_pixnan, 10, 512},
        {"NIfTI pixdim inf", c_pixinf, 10, 512},
        {"NRRD zero direction", c_zero_dir, 10, 512},
        {"NRRD NaN spacing", c_nan_spacing, 10, 512},
        {"NRRD -1 spacing", c_neg_spacing, 10, 512},
        {"NRRD double 1e300", c_f64_huge, 10, 512},
        {"store zero direction", c_store_dir, 10, 512},
    };
    for (size_t i = 0; i < sizeof cases / sizeof *cases; i++)
        run_case(cases[i].name, cases[i].fn, cases[i].seconds, cases[i].mem_mb);
    char cmd[128];
    snprintf(cmd, sizeof cmd, "rm -rf %s", dir_);
    if (system(cmd) != 0)
        fprintf(stderr, "could not remove %s\n", dir_);
    return check_finish();
}
