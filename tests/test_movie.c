/* tests/test_movie.c - movies (cdvr/movie.h) read back with libavformat/libavcodec.
 *
 * Proves, on synthetic frames (a moving smooth blob over gradients, even and odd sizes):
 *  - mkv/FFV1 decodes to exactly the RGB8 frames given (bit-identical), any size;
 *  - mp4/H.264 decodes to within a PSNR floor (measured figures printed), odd sizes padded by
 *    one column/row (the decoded frame's top-left part is the image);
 *  - webm/VP9 and gif/palette decode with the frame count, size and rate asked;
 *  - the frame count and the frame rate (fps=) are those of the stream;
 *  - two writes of the same frames give byte-identical files (mkv and mp4);
 *  - nothing stands under the final name before close, abort leaves nothing (also no temporary
 *    file with CDVR_ATOMIC_NAMED=1), a close without frames writes nothing;
 *  - clear errors: unknown container, unwritable path, a codec the container does not take,
 *    crf where it does not apply, a bad preset, a frame of another size.
 * `test_movie compare MOVIE PNG_PATTERN N MIN_PSNR|exact FPS` decodes MOVIE and compares its
 * frames with the PNGs PNG_PATTERN (printf, frame numbers from 1; "-": count and rate only) of the same capture: used by
 * tests/test_movie.sh on the player's captures. Without FFmpeg in the build: skipped (77),
 * after checking that open fails with CDVR_ERR_UNSUPPORTED.
 */
#include "check.h"
#include "cdvr/movie.h"

#include <dirent.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#if CDVR_HAVE_MOVIE
#include <libavcodec/avcodec.h>
#include <libavformat/avformat.h>
#include <libswscale/swscale.h>

#define STB_IMAGE_IMPLEMENTATION
#define STBI_ONLY_PNG
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wunused-function"
#pragma GCC diagnostic ignored "-Wsign-compare"
#include <stb/stb_image.h>
#pragma GCC diagnostic pop

#define MAXF 64

typedef struct decoded {
    int n, w, h;      /* frames, decoded size */
    double fps;
    char codec[32];
    uint8_t *rgb[MAXF];
} decoded;

static void decoded_free(decoded *d)
{
    for (int i = 0; i < d->n; i++)
        free(d->rgb[i]);
    d->n = 0;
}

static int keep_frame(decoded *d, const AVFrame *f)
{
    if (d->n >= MAXF)
        return -1;
    d->w = f->width, d->h = f->height;
    uint8_t *rgb = malloc((size_t)f->width * (size_t)f->height * 3);
    struct SwsContext *sws = sws_getContext(f->width, f->height, f->format, f->width, f->height, AV_PIX_FMT_RGB24,
                                            SWS_BILINEAR | SWS_ACCURATE_RND | SWS_BITEXACT, NULL, NULL, NULL);
    if (!rgb || !sws) {
        free(rgb);
        sws_freeContext(sws);
        return -1;
    }
    uint8_t *dst[1] = {rgb};
    int stride[1] = {3 * f->width};
    sws_scale(sws, (const uint8_t *const *)f->data, f->linesize, 0, f->height, dst, stride);
    sws_freeContext(sws);
    d->rgb[d->n++] = rgb;
    return 0;
}

/* Decodes every frame of path to RGB24; 0 on success. */
static int decode_movie(const char *path, decoded *d)
{
    memset(d, 0, sizeof *d);
    AVFormatContext *fmt = NULL;
    if (avformat_open_input(&fmt, path, NULL, NULL) < 0)
        return -1;
    int ok = -1, si;
    AVCodecContext *dec = NULL;
    AVPacket *pkt = av_packet_alloc();
    AVFrame *f = av_frame_alloc();
    const AVCodec *c = NULL;
    if (avformat_find_stream_info(fmt, NULL) < 0 || (si = av_find_best_stream(fmt, AVMEDIA_TYPE_VIDEO, -1, -1, &c, 0)) < 0)
        goto done;
    AVStream *st = fmt->streams[si];
    d->fps = st->avg_frame_rate.num ? av_q2d(st->avg_frame_rate) : av_q2d(st->r_frame_rate);
    snprintf(d->codec, sizeof d->codec, "%s", c->name);
    dec = avcodec_alloc_context3(c);
    if (!dec || avcodec_parameters_to_context(dec, st->codecpar) < 0 || avcodec_open2(dec, c, NULL) < 0)
        goto done;
    int r;
    for (;;) {
        int eof = av_read_frame(fmt, pkt) < 0;
        if (!eof && pkt->stream_index != si) {
            av_packet_unref(pkt);
            continue;
        }
        r = avcodec_send_packet(dec, eof ? NULL : pkt);
        av_packet_unref(pkt);
        if (r < 0 && r != AVERROR_EOF)
            goto done;
        while ((r = avcodec_receive_frame(dec, f)) == 0)
            if (keep_frame(d, f) != 0)
                goto done;
        if (eof)
            break;
    }
    ok = 0;
done:
    av_frame_free(&f);
    av_packet_free(&pkt);
    avcodec_free_context(&dec);
    avformat_close_input(&fmt);
    return ok;
}

/* PSNR (dB) of the w x h top-left part of a (stride aw pixels) against b (w x h); INFINITY if equal. */
static double psnr(const uint8_t *a, int aw, const uint8_t *b, int w, int h)
{
    double se = 0;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < 3 * w; x++) {
            double e = (double)a[(size_t)y * 3 * aw + x] - b[(size_t)y * 3 * w + x];
            se += e * e;
        }
    return se == 0 ? INFINITY : 10 * log10(255.0 * 255.0 / (se / (3.0 * w * h)));
}

/* ---- compare mode -------------------------------------------------------------------------- */

static int compare(const char *movie, const char *pattern, int n, const char *floor_arg, double fps)
{
    decoded d;
    if (decode_movie(movie, &d) != 0) {
        fprintf(stderr, "test_movie: %s: cannot decode\n", movie);
        return 1;
    }
    int exact = strcmp(floor_arg, "exact") == 0, bad = 0;
    double floor_db = exact ? INFINITY : atof(floor_arg), worst = INFINITY;
    if (d.n != n || fabs(d.fps - fps) > 0.01 * fps) {
        fprintf(stderr, "test_movie: %s: %d frames at %g fps, expected %d at %g\n", movie, d.n, d.fps, n, fps);
        bad = 1;
    }
    for (int i = 0; i < d.n && i < n && !bad && strcmp(pattern, "-") != 0; i++) {
        char png[4096];
        snprintf(png, sizeof png, pattern, i + 1);
        int w, h, ch;
        uint8_t *ref = stbi_load(png, &w, &h, &ch, 3);
        if (!ref || w > d.w || h > d.h || d.w - w > 1 || d.h - h > 1) {
            fprintf(stderr, "test_movie: %s: unreadable or of another size than the movie's %dx%d\n", png, d.w, d.h);
            bad = 1;
        } else {
            double p = psnr(d.rgb[i], d.w, ref, w, h);
            worst = p < worst ? p : worst;
            if (exact ? p != INFINITY : p < floor_db) {
                fprintf(stderr, "test_movie: %s frame %d: %.2f dB against %s (floor %s)\n", movie, i + 1, p, png, floor_arg);
                bad = 1;
            }
        }
        stbi_image_free(ref);
    }
    printf("test_movie: %s (%s): %d frames at %g fps, lowest PSNR against the PNGs %.2f dB%s\n", movie, d.codec, d.n,
           d.fps, worst, bad ? " FAILED" : "");
    decoded_free(&d);
    return bad;
}

/* ---- unit tests ---------------------------------------------------------------------------- */

static char dir[256];

static void frame_rgba(uint8_t *rgba, int w, int h, int k)
{
    double cx = 0.3 * w + 1.5 * k, cy = 0.4 * h + 0.7 * k, s2 = 0.02 * w * h;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            uint8_t *p = rgba + 4 * ((size_t)y * w + x);
            double blob = exp(-((x - cx) * (x - cx) + (y - cy) * (y - cy)) / s2);
            p[0] = (uint8_t)lround(255 * blob);
            p[1] = (uint8_t)lround(200 * blob * blob + 40.0 * y / h);
            p[2] = (uint8_t)lround(60 + 80.0 * x / w * (1 - blob));
            p[3] = 255;
        }
}

/* Writes nf frames of w x h to name in dir; returns the status. */
static cdvr_status write_movie(const char *name, const cdvr_movie_opts *o, int w, int h, int nf, cdvr_error *err)
{
    char path[512];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    cdvr_movie *m;
    cdvr_status s = cdvr_movie_open(path, o, &m, err);
    if (s != CDVR_OK)
        return s;
    uint8_t *rgba = malloc((size_t)w * h * 4);
    for (int k = 0; k < nf && s == CDVR_OK; k++) {
        frame_rgba(rgba, w, h, k);
        s = cdvr_movie_add_rgba8(m, rgba, w, h, err);
    }
    free(rgba);
    if (s != CDVR_OK) {
        cdvr_movie_abort(m);
        return s;
    }
    return cdvr_movie_close(m, err);
}

/* Lowest PSNR of the decoded frames of name against the synthetic frames (INFINITY: exact). */
static double check_movie(const char *name, int w, int h, int nf, double fps, const char *codec)
{
    char path[512];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    decoded d;
    double worst = -1;
    CHECK(decode_movie(path, &d) == 0, "%s decodes", name);
    CHECK(d.n == nf, "%s: %d frames, %d written", name, d.n, nf);
    CHECK(fabs(d.fps - fps) < 0.01 * fps, "%s: %g fps, %g asked", name, d.fps, fps);
    CHECK(strcmp(d.codec, codec) == 0, "%s: decoder %s, %s expected", name, d.codec, codec);
    CHECK(d.w >= w && d.h >= h && d.w - w <= 1 && d.h - h <= 1, "%s: %dx%d for %dx%d frames", name, d.w, d.h, w, h);
    uint8_t *rgba = malloc((size_t)w * h * 4), *rgb = malloc((size_t)w * h * 3);
    for (int k = 0; k < d.n && k < nf && d.w >= w && d.h >= h; k++) {
        frame_rgba(rgba, w, h, k);
        for (size_t i = 0; i < (size_t)w * h; i++)
            memcpy(rgb + 3 * i, rgba + 4 * i, 3);
        double p = psnr(d.rgb[k], d.w, rgb, w, h);
        worst = k == 0 || p < worst ? p : worst;
    }
    free(rgba);
    free(rgb);
    decoded_free(&d);
    printf("  %s: %dx%d, %d frames at %g fps (%s): lowest PSNR %.2f dB\n", name, w, h, nf, fps, codec, worst);
    return worst;
}

static int same_bytes(const char *a, const char *b)
{
    char pa[512], pb[512];
    snprintf(pa, sizeof pa, "%s/%s", dir, a);
    snprintf(pb, sizeof pb, "%s/%s", dir, b);
    FILE *fa = fopen(pa, "rb"), *fb = fopen(pb, "rb");
    int same = fa && fb;
    while (same) {
        int ca = fgetc(fa), cb = fgetc(fb);
        same = ca == cb;
        if (ca == EOF || cb == EOF)
            break;
    }
    if (fa)
        fclose(fa);
    if (fb)
        fclose(fb);
    return same;
}

static int entries(void) /* files in dir */
{
    DIR *dp = opendir(dir);
    int n = 0;
    for (struct dirent *e; dp && (e = readdir(dp));)
        n += e->d_name[0] != '.';
    if (dp)
        closedir(dp);
    return n;
}

static void test_codecs(void)
{
    cdvr_error err;
    cdvr_movie_opts o = cdvr_movie_defaults();
    CHECK_OK(write_movie("a.mkv", &o, 64, 48, 12, &err), err);
    CHECK(check_movie("a.mkv", 64, 48, 12, 25, "ffv1") == INFINITY, "FFV1 is lossless");
    CHECK_OK(write_movie("odd.mkv", &o, 33, 31, 5, &err), err);
    CHECK(check_movie("odd.mkv", 33, 31, 5, 25, "ffv1") == INFINITY, "FFV1 is lossless at an odd size");
    o.fps = 30;
    CHECK_OK(write_movie("a.mp4", &o, 64, 48, 12, &err), err);
    double p = check_movie("a.mp4", 64, 48, 12, 30, "h264");
    CHECK(p >= 35, "H.264 crf 18: %.2f dB >= 35 (measured 37.2)", p);
    CHECK_OK(write_movie("odd.mp4", &o, 33, 31, 5, &err), err);
    p = check_movie("odd.mp4", 33, 31, 5, 30, "h264");
    CHECK(p >= 30, "H.264 odd size (padded; 33x31: chroma edges weigh more): %.2f dB >= 30 (measured 32.4)", p);
    /* crf 0 is lossless H.264: what remains is the RGB -> yuv420p -> RGB ceiling (measured 39.4 dB
     * here; chroma at half resolution) */
    cdvr_movie_opts z = o;
    z.crf = 0;
    CHECK_OK(write_movie("z.mp4", &z, 64, 48, 12, &err), err);
    double ceiling = check_movie("z.mp4", 64, 48, 12, 30, "h264");
    CHECK(ceiling >= 38, "H.264 crf 0 (4:2:0 ceiling): %.2f dB >= 38", ceiling);
    o.crf = 40, o.preset = "ultrafast";
    CHECK_OK(write_movie("low.mp4", &o, 64, 48, 12, &err), err);
    double low = check_movie("low.mp4", 64, 48, 12, 30, "h264");
    CHECK(low < p, "crf 40 (%.2f dB) is below crf 18 (%.2f dB)", low, p);
    o = cdvr_movie_defaults();
    o.fps = 10;
    CHECK_OK(write_movie("a.webm", &o, 64, 48, 6, &err), err);
    p = check_movie("a.webm", 64, 48, 6, 10, "vp9");
    CHECK(p >= 33, "VP9 crf 31: %.2f dB >= 33 (measured 36.9)", p);
    CHECK_OK(write_movie("a.gif", &o, 33, 31, 6, &err), err);
    p = check_movie("a.gif", 33, 31, 6, 10, "gif");
    CHECK(p >= 24, "GIF (256 fixed colours, no dithering): %.2f dB >= 24 (measured 25.1)", p);
    o = cdvr_movie_defaults();
    o.codec = "h264";
    CHECK_OK(write_movie("h.mkv", &o, 64, 48, 4, &err), err);
    check_movie("h.mkv", 64, 48, 4, 25, "h264");
}

static void test_determinism(void)
{
    cdvr_error err;
    cdvr_movie_opts o = cdvr_movie_defaults();
    CHECK_OK(write_movie("d1.mkv", &o, 64, 48, 8, &err), err);
    CHECK_OK(write_movie("d2.mkv", &o, 64, 48, 8, &err), err);
    CHECK(same_bytes("d1.mkv", "d2.mkv"), "two mkv writes are byte-identical");
    CHECK_OK(write_movie("d1.mp4", &o, 64, 48, 8, &err), err);
    CHECK_OK(write_movie("d2.mp4", &o, 64, 48, 8, &err), err);
    CHECK(same_bytes("d1.mp4", "d2.mp4"), "two mp4 writes are byte-identical");
}

static void test_atomic(int named)
{
    char path[512];
    snprintf(path, sizeof path, "%s/atomic.mp4", dir);
    if (named)
        setenv("CDVR_ATOMIC_NAMED", "1", 1);
    int before = entries();
    cdvr_error err;
    cdvr_movie *m;
    CHECK_OK(cdvr_movie_open(path, NULL, &m, &err), err);
    uint8_t rgba[16 * 16 * 4];
    frame_rgba(rgba, 16, 16, 0);
    CHECK_OK(cdvr_movie_add_rgba8(m, rgba, 16, 16, &err), err);
    CHECK(access(path, F_OK) != 0, "nothing under the final name before close (named %d)", named);
    CHECK(entries() == before + named, "%s temporary file while writing", named ? "a named" : "no named");
    cdvr_status s = cdvr_movie_add_rgba8(m, rgba, 8, 8, &err);
    CHECK(s == CDVR_ERR_ARG && strstr(err.msg, "is 8x8, the movie is 16x16"), "a frame of another size: %s", err.msg);
    cdvr_movie_abort(m);
    CHECK(access(path, F_OK) != 0 && entries() == before, "abort leaves nothing (named %d)", named);
    CHECK_OK(cdvr_movie_open(path, NULL, &m, &err), err);
    s = cdvr_movie_close(m, &err);
    CHECK(s == CDVR_ERR_ARG && strstr(err.msg, "no frame"), "close without frames: %s", err.msg);
    CHECK(access(path, F_OK) != 0 && entries() == before, "a movie without frames leaves nothing");
    unsetenv("CDVR_ATOMIC_NAMED");
}

static void test_errors(void)
{
    cdvr_error err;
    cdvr_movie *m = NULL;
    cdvr_movie_opts o = cdvr_movie_defaults();
    char path[512];
    snprintf(path, sizeof path, "%s/x.avi", dir);
    cdvr_status s = cdvr_movie_open(path, &o, &m, &err);
    CHECK(s == CDVR_ERR_ARG && strstr(err.msg, "unknown movie container '.avi'") && !m, "unknown container: %s", err.msg);
    s = cdvr_movie_open("/nonexistent-dir/x.mp4", &o, &m, &err);
    CHECK(s == CDVR_ERR_IO && strstr(err.msg, "/nonexistent-dir/x.mp4") && !m, "unwritable path: %s", err.msg);
    s = cdvr_movie_open("/proc/version.mp4", &o, &m, &err);
    CHECK(s == CDVR_ERR_IO && strstr(err.msg, "/proc/version.mp4"), "unwritable directory: %s", err.msg);
    snprintf(path, sizeof path, "%s/x.webm", dir);
    o.codec = "h264";
    s = cdvr_movie_open(path, &o, &m, &err);
    CHECK(s == CDVR_ERR_ARG && strstr(err.msg, "does not take codec 'h264'"), "codec and container: %s", err.msg);
    o.codec = "mpeg2";
    s = cdvr_movie_open(path, &o, &m, &err);
    CHECK(s == CDVR_ERR_ARG && strstr(err.msg, "unknown movie codec"), "unknown codec: %s", err.msg);
    o = cdvr_movie_defaults();
    o.crf = 10;
    snprintf(path, sizeof path, "%s/x.mkv", dir);
    s = cdvr_movie_open(path, &o, &m, &err);
    CHECK(s == CDVR_ERR_ARG && strstr(err.msg, "crf applies"), "crf on FFV1: %s", err.msg);
    o = cdvr_movie_defaults();
    o.preset = "quick";
    snprintf(path, sizeof path, "%s/x.mp4", dir);
    s = cdvr_movie_open(path, &o, &m, &err);
    CHECK(s == CDVR_ERR_ARG && strstr(err.msg, "unknown preset 'quick'"), "bad preset: %s", err.msg);
    o = cdvr_movie_defaults();
    o.fps = 0;
    s = cdvr_movie_open(path, &o, &m, &err);
    CHECK(s == CDVR_ERR_ARG && strstr(err.msg, "fps"), "fps 0: %s", err.msg);
    CHECK(cdvr_movie_is_movie_path("a/B.MP4") && cdvr_movie_is_movie_path("x.gif") && !cdvr_movie_is_movie_path("x%04d.png") &&
              !cdvr_movie_is_movie_path(".mp4"),
          "movie paths by extension");
}

int main(int argc, char **argv)
{
    if (argc == 7 && strcmp(argv[1], "compare") == 0)
        return compare(argv[2], argv[3], atoi(argv[4]), argv[5], atof(argv[6]));
    CHECK(cdvr_movie_available(), "built with FFmpeg");
    snprintf(dir, sizeof dir, "/tmp/cdvr_test_movie_XXXXXX");
    CHECK(mkdtemp(dir) != NULL, "temporary directory");
    test_errors();
    test_codecs();
    test_determinism();
    test_atomic(0);
    test_atomic(1);
    char cmd[300];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
    CHECK(system(cmd) == 0, "cleanup");
    return check_finish();
}
#else
int main(void)
{
    cdvr_movie *m = (cdvr_movie *)1;
    cdvr_error err;
    cdvr_status s = cdvr_movie_open("x.mp4", NULL, &m, &err);
    CHECK(s == CDVR_ERR_UNSUPPORTED && !m && strstr(err.msg, "without FFmpeg"), "no FFmpeg: %s", err.msg);
    CHECK(!cdvr_movie_available(), "not available");
    if (check_finish() != 0)
        return 1;
    return 77;
}
#endif
