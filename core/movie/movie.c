/* core/movie/movie.c - cdvr/movie.h through libavformat, libavcodec and libswscale.
 *
 *   frames (RGB8) --pad/convert--> AVFrame --encoder--> packets --muxer--> AVIO --> atomic file
 *
 * The muxer writes through a custom AVIO context whose write and seek go to the atomic file's
 * FILE (mp4 and mkv seek back to finish their index), so the movie follows the atomic-file
 * rules exactly as a PNG does: nothing stands under path until close commits it.
 * Conversion: yuv420p (H.264, VP9) through libswscale (BT.601, limited range, as tagged in the
 * stream), after padding odd sizes by repeating the last column/row; FFV1 takes bgr0, a byte
 * shuffle of the RGB (lossless); GIF takes pal8 with the fixed palette of movie.h.
 *
 * Threads: the conversion, the encoder and the muxer run on one encoder thread per movie, so a
 * capture renders frame n+1 while frame n is encoded. add copies the frame into the padded
 * buffer `pad` and hands it over (waiting while the thread still encodes the one before: at most
 * one frame in flight); the thread works on `work`. The frames reach the encoder in order on one
 * thread, so the output does not depend on the timing (the determinism movie.h promises). An
 * encoder error stops the thread and is returned by the next add or by close (naming the frame).
 *
 *   caller: [fill pad] -> handover (swap pad <-> work) -> [fill pad] -> handover ...
 *   thread:                     [convert work, encode, mux] ...    [convert, encode, mux]
 */
#include <pthread.h>
#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include <libavcodec/avcodec.h>
#include <libavformat/avformat.h>
#include <libavutil/imgutils.h>
#include <libavutil/opt.h>
#include <libswscale/swscale.h>

#include "cdvr/atomicfile.h"
#include "cdvr/movie.h"
#include "movie_table.h"

/* ---- the codecs ----------------------------------------------------------------------------- */

typedef struct codec_info {
    const char *name;      /* cdvr's name */
    const char *encoder;   /* libavcodec's */
    enum AVPixelFormat pix_fmt;
    int even;              /* needs an even width and height (4:2:0) */
    int crf_max, crf_def;  /* crf range 0..crf_max; crf_max 0: no crf */
} codec_info;

static const codec_info codecs[] = {
    {"h264", "libx264", AV_PIX_FMT_YUV420P, 1, 51, 18},
    {"vp9", "libvpx-vp9", AV_PIX_FMT_YUV420P, 1, 63, 31},
    {"ffv1", "ffv1", AV_PIX_FMT_BGR0, 0, 0, 0},
    {"gif", "gif", AV_PIX_FMT_PAL8, 0, 0, 0},
    {NULL, NULL, AV_PIX_FMT_NONE, 0, 0, 0},
};

static const char *const presets[] = {"ultrafast", "superfast", "veryfast", "faster", "fast", "medium",
                                      "slow", "slower", "veryslow", "placebo", NULL};

struct cdvr_movie {
    char *path;                 /* the final name (af.path points here) */
    const cdvr_movie_container *container;
    const codec_info *codec;
    cdvr_movie_opts opts;
    char preset[16];
    cdvr_atomic_file af;
    int af_open;
    int io_failed, io_errno;    /* a write or seek of the muxer failed */
    AVFormatContext *fmt;
    AVIOContext *io;
    AVCodecContext *enc;
    AVStream *st;
    AVFrame *frame;
    AVPacket *pkt;
    struct SwsContext *sws;
    uint8_t *pad, *rgb;         /* the padded RGB frame (ew x eh x 3) the caller fills; RGBA ->
                                   RGB scratch */
    uint8_t *work;              /* the padded frame the encoder thread converts */
    pthread_t thread;
    pthread_mutex_t mu;
    pthread_cond_t cv;
    int thread_on;              /* the thread runs (join it) */
    int busy;                   /* work holds a frame the thread has not finished */
    int stop;                   /* the thread ends once it is not busy */
    int64_t work_pts;           /* the frame number in work */
    cdvr_status thread_status;  /* the thread's first failure (it then stops encoding) */
    cdvr_error thread_err;
    int width, height;          /* the frames' size (0: not known yet) */
    int ew, eh;                 /* the encoded size */
    int64_t frames;
    int started;                /* encoder open, header written */
};

int cdvr_movie_available(void) { return 1; }
int64_t cdvr_movie_frames(const cdvr_movie *m) { return m->frames; }
const char *cdvr_movie_path(const cdvr_movie *m) { return m->path; }
const char *cdvr_movie_codec(const cdvr_movie *m) { return m->codec->name; }

static const codec_info *find_codec(const char *name)
{
    for (const codec_info *c = codecs; c->name; c++)
        if (strcmp(c->name, name) == 0)
            return c;
    return NULL;
}

static const char *averr(int code, char *buf, size_t size)
{
    if (av_strerror(code, buf, size) < 0)
        snprintf(buf, size, "error %d", code);
    return buf;
}

/* ---- AVIO onto the atomic file -------------------------------------------------------------- */

#if LIBAVFORMAT_VERSION_MAJOR >= 61
static int io_write(void *opaque, const uint8_t *buf, int size)
#else
static int io_write(void *opaque, uint8_t *buf, int size)
#endif
{
    cdvr_movie *m = opaque;
    if (fwrite(buf, 1, (size_t)size, m->af.f) != (size_t)size) {
        if (!m->io_failed)
            m->io_errno = errno ? errno : EIO;
        m->io_failed = 1;
        return AVERROR(EIO);
    }
    return size;
}

static int64_t io_seek(void *opaque, int64_t offset, int whence)
{
    cdvr_movie *m = opaque;
    FILE *f = m->af.f;
    if (whence & AVSEEK_SIZE) {
        off_t cur = ftello(f), end = -1;
        if (cur >= 0 && fseeko(f, 0, SEEK_END) == 0)
            end = ftello(f);
        if (cur < 0 || fseeko(f, cur, SEEK_SET) != 0)
            return AVERROR(EIO);
        return end;
    }
    whence &= ~AVSEEK_FORCE;
    if (fseeko(f, (off_t)offset, whence) != 0) {
        if (!m->io_failed)
            m->io_errno = errno ? errno : EIO;
        m->io_failed = 1;
        return AVERROR(errno ? errno : EIO);
    }
    return ftello(f);
}

/* ---- open ----------------------------------------------------------------------------------- */

static cdvr_status check_opts(const char *path, const cdvr_movie_opts *o, const cdvr_movie_container *c,
                              const codec_info **codec, cdvr_error *err)
{
    const char *name = o->codec ? o->codec : c->codec;
    int takes = 0;
    for (int i = 0; c->codecs[i]; i++)
        takes |= strcmp(c->codecs[i], name) == 0;
    *codec = find_codec(name);
    if (!*codec)
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: unknown movie codec '%s' (h264, vp9, ffv1, gif)", path, name);
    if (!takes)
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: the %s container does not take codec '%s'", path, c->ext, name);
    if (!(o->fps > 0 && o->fps <= 1000))
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: fps %g out of range (0, 1000]", path, o->fps);
    if (o->crf != -1 && (*codec)->crf_max == 0)
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: crf applies to h264 and vp9, not to %s", path, name);
    if (o->crf != -1 && (o->crf < 0 || o->crf > (*codec)->crf_max))
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: crf %d out of range 0..%d for %s", path, o->crf,
                              (*codec)->crf_max, name);
    if (o->preset) {
        int ok = 0;
        for (int i = 0; presets[i]; i++)
            ok |= strcmp(presets[i], o->preset) == 0;
        if (strcmp(name, "h264") != 0)
            return cdvr_error_set(err, CDVR_ERR_ARG, "%s: preset applies to h264, not to %s", path, name);
        if (!ok)
            return cdvr_error_set(err, CDVR_ERR_ARG, "%s: unknown preset '%s' (ultrafast, superfast, veryfast, "
                                  "faster, fast, medium, slow, slower, veryslow, placebo)", path, o->preset);
    }
    if ((o->width == 0) != (o->height == 0) || o->width < 0 || o->height < 0 || o->width > 16384 ||
        o->height > 16384)
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: size %dx%d: both 1..16384, or both 0 (the first frame's)",
                              path, o->width, o->height);
    if (o->threads < 1 || o->threads > 64)
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: threads %d out of range 1..64", path, o->threads);
    return CDVR_OK;
}

static cdvr_status ff_fail(cdvr_movie *m, const char *what, int code, cdvr_error *err)
{
    char buf[AV_ERROR_MAX_STRING_SIZE];
    if (m->io_failed)
        return cdvr_error_set(err, CDVR_ERR_IO, "%s: cannot write: %s", m->path, strerror(m->io_errno));
    return cdvr_error_set(err, CDVR_ERR_IO, "%s: %s: %s", m->path, what, averr(code, buf, sizeof buf));
}

static void encoder_options(const cdvr_movie *m, AVDictionary **d)
{
    char crf[16];
    snprintf(crf, sizeof crf, "%d", m->opts.crf >= 0 ? m->opts.crf : m->codec->crf_def);
    if (strcmp(m->codec->name, "h264") == 0) {
        av_dict_set(d, "crf", crf, 0);
        av_dict_set(d, "preset", m->preset, 0);
    } else if (strcmp(m->codec->name, "vp9") == 0) {
        av_dict_set(d, "crf", crf, 0);
        av_dict_set(d, "deadline", "good", 0);
        av_dict_set(d, "cpu-used", "4", 0);
    }
}

/* Opens the muxer and the encoder for frames of width x height and writes the header. */
static void *encoder_thread(void *arg);

static cdvr_status start(cdvr_movie *m, int width, int height, cdvr_error *err)
{
    const AVCodec *c = avcodec_find_encoder_by_name(m->codec->encoder);
    if (!c)
        return cdvr_error_set(err, CDVR_ERR_UNSUPPORTED, "%s: this FFmpeg has no encoder '%s'", m->path,
                              m->codec->encoder);
    m->width = width, m->height = height;
    m->ew = width + (m->codec->even && width % 2);
    m->eh = height + (m->codec->even && height % 2);
    int r = avformat_alloc_output_context2(&m->fmt, NULL, m->container->format, m->path);
    if (r < 0)
        return ff_fail(m, "cannot create the muxer", r, err);
    m->fmt->flags |= AVFMT_FLAG_BITEXACT | AVFMT_FLAG_CUSTOM_IO;
    uint8_t *buf = av_malloc(1 << 16);
    m->io = buf ? avio_alloc_context(buf, 1 << 16, 1, m, NULL, io_write, io_seek) : NULL;
    if (!m->io) {
        av_free(buf);
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: out of memory", m->path);
    }
    m->fmt->pb = m->io;
    m->st = avformat_new_stream(m->fmt, NULL);
    m->enc = avcodec_alloc_context3(c);
    m->frame = av_frame_alloc();
    m->pkt = av_packet_alloc();
    m->pad = malloc((size_t)m->ew * (size_t)m->eh * 3);
    m->work = malloc((size_t)m->ew * (size_t)m->eh * 3);
    if (!m->st || !m->enc || !m->frame || !m->pkt || !m->pad || !m->work)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: out of memory", m->path);
    AVCodecContext *e = m->enc;
    AVRational rate = av_d2q(m->opts.fps, 1001000);
    e->width = m->ew, e->height = m->eh, e->pix_fmt = m->codec->pix_fmt;
    e->time_base = av_inv_q(rate), e->framerate = rate;
    e->flags |= AV_CODEC_FLAG_BITEXACT;
    e->thread_count = m->opts.threads;
    e->bit_rate = 0;
    if (m->codec->pix_fmt == AV_PIX_FMT_YUV420P) {
        e->colorspace = AVCOL_SPC_SMPTE170M, e->color_primaries = AVCOL_PRI_SMPTE170M;
        e->color_trc = AVCOL_TRC_SMPTE170M, e->color_range = AVCOL_RANGE_MPEG;
    }
    if (m->fmt->oformat->flags & AVFMT_GLOBALHEADER)
        e->flags |= AV_CODEC_FLAG_GLOBAL_HEADER;
    AVDictionary *d = NULL;
    encoder_options(m, &d);
    r = avcodec_open2(e, c, &d);
    av_dict_free(&d);
    if (r < 0)
        return ff_fail(m, "cannot open the encoder", r, err);
    if ((r = avcodec_parameters_from_context(m->st->codecpar, e)) < 0)
        return ff_fail(m, "cannot set the stream", r, err);
    m->st->time_base = e->time_base;
    m->st->avg_frame_rate = rate;
    if ((r = avformat_write_header(m->fmt, NULL)) < 0)
        return ff_fail(m, "cannot write the header", r, err);
    m->frame->format = e->pix_fmt, m->frame->width = m->ew, m->frame->height = m->eh;
    if ((r = av_frame_get_buffer(m->frame, 0)) < 0)
        return ff_fail(m, "cannot allocate a frame", r, err);
    if (m->codec->pix_fmt == AV_PIX_FMT_YUV420P) {
        m->sws = sws_getContext(m->ew, m->eh, AV_PIX_FMT_RGB24, m->ew, m->eh, AV_PIX_FMT_YUV420P,
                                SWS_BILINEAR | SWS_ACCURATE_RND | SWS_BITEXACT | SWS_FULL_CHR_H_INP, NULL, NULL, NULL);
        if (!m->sws)
            return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: cannot create the colour converter", m->path);
    }
    if ((r = pthread_create(&m->thread, NULL, encoder_thread, m)) != 0)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: cannot start the encoder thread: %s", m->path,
                              strerror(r));
    m->thread_on = 1;
    m->started = 1;
    return CDVR_OK;
}

cdvr_status cdvr_movie_open(const char *path, const cdvr_movie_opts *opts, cdvr_movie **out,
                            cdvr_error *err)
{
    *out = NULL;
    cdvr_movie_opts o = opts ? *opts : cdvr_movie_defaults();
    const cdvr_movie_container *c = cdvr_movie_container_of(path);
    if (!c) {
        const char *dot = strrchr(path, '.'), *slash = strrchr(path, '/');
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: unknown movie container '%s' (.mp4, .webm, .mkv, .gif)", path,
                              dot && (!slash || dot > slash) ? dot : "(no extension)");
    }
    const codec_info *codec;
    cdvr_status s = check_opts(path, &o, c, &codec, err);
    if (s != CDVR_OK)
        return s;
    cdvr_movie *m = calloc(1, sizeof *m);
    if (!m || !(m->path = strdup(path))) {
        free(m);
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: out of memory", path);
    }
    m->container = c, m->codec = codec, m->opts = o;
    pthread_mutex_init(&m->mu, NULL);
    pthread_cond_init(&m->cv, NULL);
    snprintf(m->preset, sizeof m->preset, "%s", o.preset ? o.preset : "medium");
    m->opts.preset = m->preset;
    m->opts.codec = codec->name;
    av_log_set_level(AV_LOG_ERROR); /* no encoder statistics on stderr */
    if ((s = cdvr_atomic_open(&m->af, m->path, err)) != CDVR_OK) {
        free(m->path);
        free(m);
        return s;
    }
    m->af_open = 1;
    if (o.width > 0 && (s = start(m, o.width, o.height, err)) != CDVR_OK) {
        cdvr_movie_abort(m);
        return s;
    }
    *out = m;
    return CDVR_OK;
}

/* ---- frames --------------------------------------------------------------------------------- */

/* The nearest colour of the GIF palette: the 6x6x6 cube (index r*36+g*6+b, levels 51*k) or one
 * of the 40 greys 216+k, k = 0..39, of value round((k+1)*255/41). */
static uint8_t gif_index(int r, int g, int b)
{
    int qr = (r + 25) / 51, qg = (g + 25) / 51, qb = (b + 25) / 51;
    int dr = r - qr * 51, dg = g - qg * 51, db = b - qb * 51;
    int best = dr * dr + dg * dg + db * db, idx = qr * 36 + qg * 6 + qb;
    int y = (r + g + b + 1) / 3, k = (y * 41 + 127) / 255 - 1;
    k = k < 0 ? 0 : k > 39 ? 39 : k;
    int v = ((k + 1) * 255 + 20) / 41;
    int d = (r - v) * (r - v) + (g - v) * (g - v) + (b - v) * (b - v);
    return d < best ? (uint8_t)(216 + k) : (uint8_t)idx;
}

static void gif_palette(uint32_t *pal)
{
    for (int i = 0; i < 216; i++)
        pal[i] = 0xFF000000u | (uint32_t)(i / 36 * 51) << 16 | (uint32_t)(i / 6 % 6 * 51) << 8 | (uint32_t)(i % 6 * 51);
    for (int k = 0; k < 40; k++) {
        uint32_t v = (uint32_t)(((k + 1) * 255 + 20) / 41);
        pal[216 + k] = 0xFF000000u | v << 16 | v << 8 | v;
    }
}

/* Sends frame (NULL: flush) and writes what the encoder gives back. */
static cdvr_status encode(cdvr_movie *m, AVFrame *frame, cdvr_error *err)
{
    int r = avcodec_send_frame(m->enc, frame);
    if (r < 0)
        return ff_fail(m, "cannot encode", r, err);
    while ((r = avcodec_receive_packet(m->enc, m->pkt)) == 0) {
        av_packet_rescale_ts(m->pkt, m->enc->time_base, m->st->time_base);
        m->pkt->stream_index = m->st->index;
        if ((r = av_interleaved_write_frame(m->fmt, m->pkt)) < 0)
            return ff_fail(m, "cannot write a frame", r, err);
    }
    if (r != AVERROR(EAGAIN) && r != AVERROR_EOF)
        return ff_fail(m, "cannot encode", r, err);
    return CDVR_OK;
}

/* Fills m->frame from the padded RGB frame src. */
static cdvr_status convert(cdvr_movie *m, const uint8_t *src, cdvr_error *err)
{
    int r = av_frame_make_writable(m->frame);
    if (r < 0)
        return ff_fail(m, "cannot allocate a frame", r, err);
    AVFrame *f = m->frame;
    if (m->sws) {
        const uint8_t *planes[1] = {src};
        int strides[1] = {3 * m->ew};
        sws_scale(m->sws, planes, strides, 0, m->eh, f->data, f->linesize);
        return CDVR_OK;
    }
    for (int y = 0; y < m->eh; y++) {
        const uint8_t *s = src + (size_t)y * (size_t)m->ew * 3;
        uint8_t *d = f->data[0] + (size_t)y * (size_t)f->linesize[0];
        if (m->codec->pix_fmt == AV_PIX_FMT_BGR0) {
            for (int x = 0; x < m->ew; x++, s += 3, d += 4)
                d[0] = s[2], d[1] = s[1], d[2] = s[0], d[3] = 0;
        } else {
            for (int x = 0; x < m->ew; x++, s += 3)
                d[x] = gif_index(s[0], s[1], s[2]);
        }
    }
    if (m->codec->pix_fmt == AV_PIX_FMT_PAL8)
        gif_palette((uint32_t *)f->data[1]);
    return CDVR_OK;
}

/* The encoder thread: converts, encodes and muxes each frame handed over in work. */
static void *encoder_thread(void *arg)
{
    cdvr_movie *m = arg;
    pthread_mutex_lock(&m->mu);
    for (;;) {
        while (!m->busy && !m->stop)
            pthread_cond_wait(&m->cv, &m->mu);
        if (!m->busy)
            break;
        int failed = m->thread_status != CDVR_OK;
        pthread_mutex_unlock(&m->mu);
        cdvr_error err;
        cdvr_status s = CDVR_OK;
        if (!failed && (s = convert(m, m->work, &err)) == CDVR_OK) {
            m->frame->pts = m->work_pts;
            s = encode(m, m->frame, &err);
        }
        pthread_mutex_lock(&m->mu);
        if (s != CDVR_OK) {
            m->thread_status = s;
            m->thread_err = err;
            size_t n = strlen(err.msg); /* the frame's number after the message, where it fits */
            if (n + 32 < sizeof m->thread_err.msg)
                snprintf(m->thread_err.msg + n, sizeof m->thread_err.msg - n, " (frame %lld)",
                         (long long)m->work_pts + 1);
        }
        m->busy = 0;
        pthread_cond_broadcast(&m->cv);
    }
    pthread_mutex_unlock(&m->mu);
    return NULL;
}

/* Waits until the thread has finished the frame in work; its failure, if any. Caller holds mu. */
static cdvr_status wait_idle_locked(cdvr_movie *m, cdvr_error *err)
{
    while (m->busy)
        pthread_cond_wait(&m->cv, &m->mu);
    if (m->thread_status != CDVR_OK && err)
        *err = m->thread_err;
    return m->thread_status;
}

/* Ends the encoder thread once it has finished its frame; the thread's failure, if any. */
static cdvr_status stop_thread(cdvr_movie *m, cdvr_error *err)
{
    if (!m->thread_on)
        return CDVR_OK;
    pthread_mutex_lock(&m->mu);
    cdvr_status s = wait_idle_locked(m, err);
    m->stop = 1;
    pthread_cond_broadcast(&m->cv);
    pthread_mutex_unlock(&m->mu);
    pthread_join(m->thread, NULL);
    m->thread_on = 0;
    return s;
}

/* Adds one RGB8 frame (rows of 3 * width bytes): padded into pad, then handed to the thread. */
static cdvr_status add_rgb(cdvr_movie *m, const uint8_t *rgb, int width, int height, cdvr_error *err)
{
    cdvr_status s;
    if (!m->started && (s = start(m, width, height, err)) != CDVR_OK)
        return s;
    if (width != m->width || height != m->height)
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: frame %lld is %dx%d, the movie is %dx%d", m->path,
                              (long long)m->frames + 1, width, height, m->width, m->height);
    size_t row = (size_t)width * 3, prow = (size_t)m->ew * 3;
    for (int y = 0; y < m->eh; y++) {
        uint8_t *d = m->pad + (size_t)y * prow;
        memcpy(d, rgb + (size_t)(y < height ? y : height - 1) * row, row);
        if (m->ew > width)
            memcpy(d + row, d + row - 3, 3);
    }
    pthread_mutex_lock(&m->mu);
    s = wait_idle_locked(m, err);
    if (s == CDVR_OK) {
        uint8_t *t = m->work;
        m->work = m->pad, m->pad = t;
        m->work_pts = m->frames++;
        m->busy = 1;
        pthread_cond_broadcast(&m->cv);
    }
    pthread_mutex_unlock(&m->mu);
    return s;
}

static cdvr_status check_size(const cdvr_movie *m, int width, int height, cdvr_error *err)
{
    if (width < 1 || height < 1 || width > 16384 || height > 16384)
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: frame size %dx%d out of range 1..16384", m->path, width, height);
    return CDVR_OK;
}

cdvr_status cdvr_movie_add_rgba8(cdvr_movie *m, const uint8_t *rgba, int width, int height, cdvr_error *err)
{
    cdvr_status s = check_size(m, width, height, err);
    if (s != CDVR_OK)
        return s;
    size_t n = (size_t)width * (size_t)height;
    uint8_t *rgb = realloc(m->rgb, n * 3);
    if (!rgb)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: out of memory", m->path);
    m->rgb = rgb;
    for (size_t i = 0; i < n; i++)
        memcpy(rgb + 3 * i, rgba + 4 * i, 3);
    return add_rgb(m, rgb, width, height, err);
}

cdvr_status cdvr_movie_add_image(cdvr_movie *m, const cdvr_image *img, cdvr_error *err)
{
    cdvr_status s = check_size(m, img->width, img->height, err);
    if (s != CDVR_OK)
        return s;
    uint8_t *rgb = realloc(m->rgb, (size_t)img->width * (size_t)img->height * 3);
    if (!rgb)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: out of memory", m->path);
    m->rgb = rgb;
    cdvr_image_to_rgb8(img, rgb);
    return add_rgb(m, rgb, img->width, img->height, err);
}

/* ---- close ---------------------------------------------------------------------------------- */

/* Frees everything of libav and the buffers (not the atomic file). */
static void release(cdvr_movie *m)
{
    stop_thread(m, NULL);
    if (m->fmt)
        m->fmt->pb = NULL;
    avformat_free_context(m->fmt);
    if (m->io) {
        av_freep(&m->io->buffer);
        avio_context_free(&m->io);
    }
    avcodec_free_context(&m->enc);
    av_frame_free(&m->frame);
    av_packet_free(&m->pkt);
    sws_freeContext(m->sws);
    free(m->pad);
    free(m->work);
    free(m->rgb);
}

void cdvr_movie_abort(cdvr_movie *m)
{
    if (!m)
        return;
    release(m);
    if (m->af_open)
        cdvr_atomic_commit(&m->af, 1, NULL); /* failed: removes the temporary file */
    pthread_cond_destroy(&m->cv);
    pthread_mutex_destroy(&m->mu);
    free(m->path);
    free(m);
}

cdvr_status cdvr_movie_close(cdvr_movie *m, cdvr_error *err)
{
    cdvr_status s = CDVR_OK;
    if (m->frames == 0)
        s = cdvr_error_set(err, CDVR_ERR_ARG, "%s: no frame was added; nothing written", m->path);
    if (s == CDVR_OK)
        s = stop_thread(m, err); /* every frame encoded: the flush below runs here */
    if (s == CDVR_OK)
        s = encode(m, NULL, err);
    int r;
    if (s == CDVR_OK && (r = av_write_trailer(m->fmt)) < 0)
        s = ff_fail(m, "cannot finish the file", r, err);
    if (s == CDVR_OK) {
        avio_flush(m->io);
        if (m->io_failed)
            s = ff_fail(m, "cannot write", AVERROR(EIO), err);
    }
    if (s != CDVR_OK) {
        cdvr_movie_abort(m);
        return s;
    }
    release(m);
    s = cdvr_atomic_commit(&m->af, 0, err);
    pthread_cond_destroy(&m->cv);
    pthread_mutex_destroy(&m->mu);
    free(m->path);
    free(m);
    return s;
}
