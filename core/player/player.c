/* core/player/player.c - the playback pipeline of player.h.
 *
 * Threads (pipelined): reader (decisions requested from the calling thread, b1) -> queue ->
 * unzip (b1') -> queue -> calling thread (b2..b5, callbacks). One mutex and one condition
 * variable guard the queues, the item pool and the decision hand-off; every wait loops on
 * its predicate and on `abort`.
 */
#include "cdvr/player.h"
#include "cdvr/timing.h"

#include <pthread.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#if CDVR_HAVE_OPENCL
#include "cdvr/device.h"
#endif

/* One chunk of a group: the group's chunk of one brick. */
typedef struct chunk_part {
    size_t chunk;
    uint8_t *stored, *payload;
    size_t stored_cap, payload_cap;
} chunk_part;

/* A chunk group in flight: the chunks of every brick for the same timesteps. */
typedef struct chunk_item {
    int variant;
    size_t chunk;            /* chunk index of brick 0 of the group */
    size_t t_begin, t_end;   /* timesteps of this group to render */
    size_t frame0;           /* frame number of t_begin */
    int group_start;
    char reason[160];
    double read_ms, unzip_ms;
    uint64_t stored_bytes, payload_bytes;
    cdvr_error err;          /* status != OK: the group failed (rows get the error) */
    struct chunk_item *next;
    chunk_part *parts;       /* nbricks */
} chunk_item;

typedef struct item_queue {
    chunk_item *head, *tail;
    size_t count;
} item_queue;

struct cdvr_player {
    cdvr_player_opts opts;
    size_t group_len;
    size_t voxels;           /* per frame */
    size_t nbricks;
    size_t stopped_early;    /* frames of the last run not played (end of series, no loop) */

    /* run state */
    size_t first, frames;
    cdvr_frame_row *rows;
    size_t nrows, rows_cap;
    double t_last_frame, t_deadline;

    /* pipeline */
    pthread_mutex_t mu;
    pthread_cond_t cv;
    item_queue free_items, read_q, unzip_q;
    chunk_item *items;
    size_t nitems;
    int reader_done, unzip_done, abort;
    int decide_state;        /* 0 idle, 1 requested, 2 answered */
    size_t decide_t, decide_group;
    int decide_variant;
    char decide_reason[160];
    cdvr_error decide_err;
    size_t planned;          /* frames planned by the reader */
    int current_variant;

    /* device */
    uint8_t *host_frames;    /* decoded frames of one group (cpu device, host decode) */
    size_t host_frames_cap;
    uint8_t *brick_frames;   /* scratch: decoded frames of one brick */
    size_t brick_frames_cap;
#if CDVR_HAVE_OPENCL
    cdvr_cl *cl;
    cdvr_cl_stream *stream;
#endif
};

static void sleep_ms(double ms)
{
    if (ms <= 0)
        return;
    struct timespec ts = {(time_t)(ms / 1e3), (long)((ms - (time_t)(ms / 1e3) * 1e3) * 1e6)};
    while (nanosleep(&ts, &ts) != 0) {
    }
}

static size_t gcd(size_t a, size_t b)
{
    while (b) {
        size_t r = a % b;
        a = b;
        b = r;
    }
    return a;
}

/* Timesteps per chunk of variant v: its codec's chunk shape for brick 0 (the recorded count
 * when the codec is not loaded). */
static size_t chunk_timesteps(const cdvr_store *st, size_t v)
{
    const cdvr_chunk_info *ch = cdvr_store_chunk(st, v, 0);
    if (!ch)
        return 1;
    size_t lo[3], dims[3];
    cdvr_codec_shape shape;
    cdvr_store_brick_box(cdvr_store_get_info(st), 0, lo, dims);
    if (ch->codec && cdvr_codec_shape_of(ch->codec, &ch->params, dims, &shape, NULL) == CDVR_OK)
        return shape.timesteps;
    return ch->count ? ch->count : 1;
}

size_t cdvr_player_group_length(const cdvr_store *st)
{
    size_t len = 1;
    size_t nvar = cdvr_store_get_info(st)->nvariants;
    for (size_t v = 0; v < nvar; v++) {
        size_t n = chunk_timesteps(st, v);
        len = len / gcd(len, n) * n;
    }
    return len;
}

/* ---- queues (caller holds mu) ------------------------------------------------------------ */

static void queue_push(item_queue *q, chunk_item *it)
{
    it->next = NULL;
    if (q->tail)
        q->tail->next = it;
    else
        q->head = it;
    q->tail = it;
    q->count++;
}

static chunk_item *queue_pop(item_queue *q)
{
    chunk_item *it = q->head;
    if (it) {
        q->head = it->next;
        if (!q->head)
            q->tail = NULL;
        q->count--;
    }
    return it;
}

static int grow(uint8_t **buf, size_t *cap, uint64_t need)
{
    if (need <= *cap)
        return 1;
    if (need > SIZE_MAX)
        return 0;
    uint8_t *nb = realloc(*buf, (size_t)need);
    if (!nb)
        return 0;
    *buf = nb;
    *cap = (size_t)need;
    return 1;
}

/* ---- stage functions -------------------------------------------------------------------- */

/* Asks for the variant of the group starting at t. threaded: hand the request to the calling
 * thread and wait; otherwise call the callback directly. */
static cdvr_status decide(cdvr_player *p, size_t t, size_t group, int threaded, int *variant,
                          char *reason, cdvr_error *err)
{
    *variant = p->current_variant;
    reason[0] = '\0';
    if (!p->opts.decide) {
        snprintf(reason, 160, "fixed: %s", cdvr_store_variant(p->opts.store, (size_t)*variant)->name);
        return CDVR_OK;
    }
    if (!threaded)
        return p->opts.decide(p->opts.decide_ud, p, t, group, variant, reason, 160, err);
    pthread_mutex_lock(&p->mu);
    p->decide_t = t;
    p->decide_group = group;
    p->decide_state = 1;
    pthread_cond_broadcast(&p->cv);
    while (p->decide_state != 2 && !p->abort)
        pthread_cond_wait(&p->cv, &p->mu);
    cdvr_status st = p->abort ? CDVR_ERR_ARG : p->decide_err.status;
    if (!p->abort) {
        *variant = p->decide_variant;
        memcpy(reason, p->decide_reason, 160);
        if (st != CDVR_OK && err)
            *err = p->decide_err;
    }
    p->decide_state = 0;
    pthread_mutex_unlock(&p->mu);
    return st;
}

/* Plans the next chunk item (decision at group boundaries) and reads it (b1).
 * Returns 0 when every frame is planned, -1 when a decision failed (err set), 1 otherwise. */
static int plan_and_read(cdvr_player *p, chunk_item *it, int threaded, cdvr_error *err)
{
    const cdvr_store *st = p->opts.store;
    const cdvr_store_info *info = cdvr_store_get_info(st);
    if (p->planned >= p->frames)
        return 0;
    size_t frame = p->planned;
    size_t t = (p->first + frame) % info->timesteps;
    memset(it, 0, offsetof(chunk_item, parts));
    cdvr_error_clear(&it->err);
    if (frame == 0 || t % p->group_len == 0) {
        int v;
        if (decide(p, t, t / p->group_len, threaded, &v, it->reason, err) != CDVR_OK)
            return -1;
        if (v < 0 || (size_t)v >= info->nvariants) {
            cdvr_error_set(err, CDVR_ERR_ARG, "%s: policy chose variant %d of %zu", cdvr_store_path(st), v + 1, info->nvariants);
            return -1;
        }
        p->current_variant = v;
        it->group_start = 1;
    }
    it->variant = p->current_variant;
    it->chunk = cdvr_store_chunk_for(st, (size_t)it->variant, t, 0);
    const cdvr_chunk_info *ch = cdvr_store_chunk(st, (size_t)it->variant, it->chunk);
    size_t end = ch->t0 + ch->count;
    size_t left = p->frames - frame;
    if (end - t > left)
        end = t + left;
    it->t_begin = t;
    it->t_end = end;
    it->frame0 = frame;
    p->planned += end - t;

    double t0 = cdvr_now_ms();
    for (size_t b = 0; b < p->nbricks && it->err.status == CDVR_OK; b++) {
        chunk_part *part = &it->parts[b];
        part->chunk = it->chunk + b;
        const cdvr_chunk_info *pc = cdvr_store_chunk(st, (size_t)it->variant, part->chunk);
        it->stored_bytes += pc->stored_bytes;
        it->payload_bytes += pc->payload_bytes;
        if (!grow(&part->stored, &part->stored_cap, pc->stored_bytes)) {
            cdvr_error_set(&it->err, CDVR_ERR_NOMEM, "%s: chunk %zu: cannot allocate %llu bytes",
                           cdvr_store_path(st), part->chunk + 1,
                           (unsigned long long)pc->stored_bytes);
            break;
        }
        if (p->opts.cold)
            cdvr_store_drop_cache(st, (size_t)it->variant, part->chunk);
        cdvr_store_read_chunk(st, (size_t)it->variant, part->chunk, part->stored, &it->err);
        if (p->opts.cold)
            cdvr_store_drop_cache(st, (size_t)it->variant, part->chunk);
    }
    if (p->opts.read_mbps > 0)
        sleep_ms(it->stored_bytes / (p->opts.read_mbps * 1e3) - (cdvr_now_ms() - t0));
    it->read_ms = cdvr_now_ms() - t0;
    return 1;
}

static void unzip(cdvr_player *p, chunk_item *it)
{
    if (it->err.status != CDVR_OK)
        return;
    const cdvr_store *st = p->opts.store;
    double t0 = cdvr_now_ms();
    for (size_t b = 0; b < p->nbricks && it->err.status == CDVR_OK; b++) {
        chunk_part *part = &it->parts[b];
        const cdvr_chunk_info *ch = cdvr_store_chunk(st, (size_t)it->variant, part->chunk);
        if (!grow(&part->payload, &part->payload_cap, ch->payload_bytes)) {
            cdvr_error_set(&it->err, CDVR_ERR_NOMEM, "%s: chunk %zu: cannot allocate %llu bytes",
                           cdvr_store_path(st), part->chunk + 1,
                           (unsigned long long)ch->payload_bytes);
            break;
        }
        cdvr_store_unpack_chunk(st, (size_t)it->variant, part->chunk, part->stored,
                                part->payload, &it->err);
    }
    it->unzip_ms = cdvr_now_ms() - t0;
}

/* ---- device (calling thread) ------------------------------------------------------------ */

static cdvr_frame_row *add_row(cdvr_player *p)
{
    if (p->nrows == p->rows_cap) {
        size_t cap = p->rows_cap ? 2 * p->rows_cap : 64;
        cdvr_frame_row *nr = realloc(p->rows, cap * sizeof *nr);
        if (!nr)
            return NULL;
        p->rows = nr;
        p->rows_cap = cap;
    }
    cdvr_frame_row *row = &p->rows[p->nrows++];
    memset(row, 0, sizeof *row);
    return row;
}

static void render_opts_for(const cdvr_player *p, const cdvr_camera *cam, cdvr_render_opts *ro)
{
    memset(ro, 0, sizeof *ro);
    ro->tf = p->opts.tf;
    ro->camera = cam;
    ro->step = p->opts.step;
    ro->unit = p->opts.unit;
    ro->term_alpha = p->opts.term_alpha;
    memcpy(ro->background, p->opts.background, sizeof ro->background);
    ro->threads = p->opts.threads;
}

/* Decodes the group's chunks on the CPU into p->host_frames (count full frames). */
static cdvr_status decode_host(cdvr_player *p, chunk_item *it, size_t count, cdvr_error *err)
{
    const cdvr_store *st = p->opts.store;
    const cdvr_store_info *info = cdvr_store_get_info(st);
    size_t need;
    if (count > 64 || !cdvr_size_mul(p->voxels, count, &need) ||
        !grow(&p->host_frames, &p->host_frames_cap, need))
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: chunk %zu: cannot allocate %zu frames",
                              cdvr_store_path(st), it->chunk + 1, count);
    uint8_t *frames[64];
    for (size_t b = p->nbricks; b-- > 0;) { /* the lower brick owns a shared voxel (store.h) */
        size_t lo[3], bd[3], bvox;
        cdvr_store_brick_box(info, b, lo, bd);
        bvox = bd[0] * bd[1] * bd[2];
        uint8_t *base = p->host_frames;
        if (p->nbricks > 1) {
            if (!grow(&p->brick_frames, &p->brick_frames_cap, (uint64_t)bvox * count))
                return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: cannot allocate a brick",
                                      cdvr_store_path(st));
            base = p->brick_frames;
        }
        for (size_t i = 0; i < count; i++)
            frames[i] = base + i * bvox;
        cdvr_status s = cdvr_store_decode_chunk(st, (size_t)it->variant, it->parts[b].chunk,
                                                it->parts[b].payload, frames, err);
        if (s != CDVR_OK)
            return s;
        for (size_t i = 0; p->nbricks > 1 && i < count; i++)
            cdvr_brick_place(p->host_frames + i * p->voxels, info->dims, frames[i], lo, bd);
    }
    return CDVR_OK;
}

/* b2 + b3 for one chunk group. */
static cdvr_status upload_decode(cdvr_player *p, chunk_item *it, double *upload_ms, double *decode_ms,
                                 cdvr_error *err)
{
    const cdvr_store *st = p->opts.store;
    const cdvr_chunk_info *ch = cdvr_store_chunk(st, (size_t)it->variant, it->chunk);
    *upload_ms = *decode_ms = 0;
#if CDVR_HAVE_OPENCL
    int device_codec = ch->codec && ch->codec->cl_mode != CDVR_CODEC_CL_NONE && p->nbricks == 1;
    if (p->opts.device == CDVR_DEVICE_CL && device_codec) {
        double t0 = cdvr_now_ms();
        cdvr_status s = cdvr_cl_upload(p->stream, it->parts[0].payload,
                                       (size_t)ch->payload_bytes, err);
        double t1 = cdvr_now_ms();
        if (s == CDVR_OK)
            s = cdvr_cl_decode(p->stream, ch->codec, &ch->params, ch->count, err);
        *upload_ms = t1 - t0;
        *decode_ms = cdvr_now_ms() - t1;
        return s;
    }
#endif
    double t0 = cdvr_now_ms();
    cdvr_status s = decode_host(p, it, ch->count, err);
    *decode_ms = cdvr_now_ms() - t0;
#if CDVR_HAVE_OPENCL
    if (s == CDVR_OK && p->opts.device == CDVR_DEVICE_CL) {
        double t1 = cdvr_now_ms();
        s = cdvr_cl_upload_frames(p->stream, p->host_frames, ch->count, err);
        *upload_ms = cdvr_now_ms() - t1;
    }
#endif
    return s;
}

/* b4 + b5 for timestep t of the current chunk; *img receives the frame. */
static cdvr_status setup_render(cdvr_player *p, chunk_item *it, size_t t, const cdvr_camera *cam,
                                cdvr_image **img, double *setup_ms, double *render_ms, cdvr_error *err)
{
    const cdvr_store *st = p->opts.store;
    const cdvr_store_info *info = cdvr_store_get_info(st);
    const cdvr_chunk_info *ch = cdvr_store_chunk(st, (size_t)it->variant, it->chunk);
    size_t f = t - ch->t0; /* frame within the group */
    cdvr_render_opts ro;
    render_opts_for(p, cam, &ro);
    *setup_ms = *render_ms = 0;
#if CDVR_HAVE_OPENCL
    if (p->opts.device == CDVR_DEVICE_CL) {
        double t0 = cdvr_now_ms();
        cdvr_status s = cdvr_cl_setup(p->stream, f, p->opts.tf, err);
        double t1 = cdvr_now_ms();
        if (s == CDVR_OK)
            s = cdvr_image_create(cam->width, cam->height, img, err);
        if (s == CDVR_OK)
            s = cdvr_cl_render(p->stream, f, &ro, info->spacing, info->origin, info->direction, *img, err);
        *setup_ms = t1 - t0;
        *render_ms = cdvr_now_ms() - t1;
        return s;
    }
#endif
    cdvr_volume frame = {0};
    memcpy(frame.dims, info->dims, sizeof frame.dims);
    memcpy(frame.spacing, info->spacing, sizeof frame.spacing);
    memcpy(frame.origin, info->origin, sizeof frame.origin);
    memcpy(frame.direction, info->direction, sizeof frame.direction);
    frame.timesteps = 1;
    frame.type = CDVR_TYPE_U8;
    frame.data = p->host_frames + f * p->voxels;
    double t0 = cdvr_now_ms();
    cdvr_status s = cdvr_render_cpu(&frame, 0, &ro, img, err);
    *render_ms = cdvr_now_ms() - t0;
    return s;
}

static void fill_row(cdvr_frame_row *row, const chunk_item *it, size_t t, size_t n)
{
    row->frame = it->frame0 + (t - it->t_begin);
    row->t = t;
    row->variant = it->variant;
    row->read_ms = it->read_ms / n;
    row->unzip_ms = it->unzip_ms / n;
    row->bytes = it->stored_bytes / n;
    row->payload_bytes = it->payload_bytes / n;
    if (t == it->t_begin && it->group_start) {
        row->group_start = 1;
        memcpy(row->reason, it->reason, sizeof row->reason);
    }
}

/* Shows frame `row` no earlier than its slot in the paced schedule (deadline k = deadline
 * k-1 + 1/pace_fps, so one late frame is caught up by the next; a frame more than one
 * period late restarts the schedule) and records its display interval. */
static void pace_and_show(cdvr_player *p, cdvr_frame_row *row)
{
    double now = cdvr_now_ms();
    if (p->opts.pace_fps > 0) {
        double period = 1e3 / p->opts.pace_fps;
        double deadline = p->t_deadline + period;
        if (now > deadline + period)
            deadline = now;
        sleep_ms(deadline - now);
        p->t_deadline = deadline;
        now = cdvr_now_ms();
    }
    row->interval_ms = now - p->t_last_frame;
    p->t_last_frame = now;
}

/* Renders the frames of one item. Returns non-OK only for callback failures (stop the run).
 * frame_ms: the work from the end of the previous chunk's last frame to the end of this
 * chunk's last frame, pacing waits excluded, shared equally by the chunk's frames. */
static cdvr_status consume(cdvr_player *p, chunk_item *it, cdvr_error *err)
{
    size_t n = it->t_end - it->t_begin;
    size_t first_row = p->nrows;
    double work_start = p->t_last_frame, work_ms = 0;
    double upload_ms = 0, decode_ms = 0;
    cdvr_error frame_err = it->err;
    if (frame_err.status == CDVR_OK)
        upload_decode(p, it, &upload_ms, &decode_ms, &frame_err);
    cdvr_status cb = CDVR_OK;
    for (size_t t = it->t_begin; t < it->t_end && cb == CDVR_OK; t++) {
        cdvr_frame_row *row = add_row(p);
        if (!row)
            return cdvr_error_set(err, CDVR_ERR_NOMEM, "player: cannot grow the frame table");
        fill_row(row, it, t, n);
        row->upload_ms = upload_ms / n;
        row->decode_ms = decode_ms / n;
        cdvr_image *img = NULL;
        cdvr_error ferr = frame_err;
        if (ferr.status == CDVR_OK) {
            cdvr_camera cam = p->opts.camera;
            cdvr_error cerr;
            cdvr_error_clear(&cerr);
            if (p->opts.camera_fn &&
                p->opts.camera_fn(p->opts.camera_ud, t, row->frame, &cam, &cerr) != CDVR_OK) {
                if (err)
                    *err = cerr;
                return cerr.status != CDVR_OK ? cerr.status : CDVR_ERR_ARG;
            }
            setup_render(p, it, t, &cam, &img, &row->setup_ms, &row->render_ms, &ferr);
        }
#if CDVR_HAVE_OPENCL
        if (p->stream)
            row->device_bytes = cdvr_cl_stream_bytes(p->stream);
#endif
        row->status = ferr.status;
        if (ferr.status != CDVR_OK)
            snprintf(row->error, sizeof row->error, "%s", ferr.msg);
        if (ferr.status == CDVR_OK && p->opts.frame_fn)
            cb = p->opts.frame_fn(p->opts.frame_ud, row, img, err);
        cdvr_image_free(img);
        work_ms += cdvr_now_ms() - work_start;
        pace_and_show(p, row);
        work_start = p->t_last_frame;
    }
    size_t shown = p->nrows - first_row;
    for (size_t i = first_row; i < p->nrows; i++) {
        p->rows[i].frame_ms = work_ms / (double)shown;
        if (p->opts.pace_fps <= 0)
            p->rows[i].interval_ms = p->rows[i].frame_ms;
    }
    return cb;
}

/* ---- threads ---------------------------------------------------------------------------- */

static chunk_item *take_free(cdvr_player *p)
{
    pthread_mutex_lock(&p->mu);
    while (!p->free_items.head && !p->abort)
        pthread_cond_wait(&p->cv, &p->mu);
    chunk_item *it = p->abort ? NULL : queue_pop(&p->free_items);
    pthread_mutex_unlock(&p->mu);
    return it;
}

static void put(cdvr_player *p, item_queue *q, chunk_item *it)
{
    pthread_mutex_lock(&p->mu);
    queue_push(q, it);
    pthread_cond_broadcast(&p->cv);
    pthread_mutex_unlock(&p->mu);
}

static void *reader_main(void *arg)
{
    cdvr_player *p = arg;
    for (;;) {
        chunk_item *it = take_free(p);
        if (!it)
            break;
        int r = plan_and_read(p, it, 1, &it->err);
        if (r == 0) {
            put(p, &p->free_items, it);
            break;
        }
        if (r < 0) { /* decision failed: hand the error to the calling thread */
            pthread_mutex_lock(&p->mu);
            p->abort = 1;
            pthread_cond_broadcast(&p->cv);
            pthread_mutex_unlock(&p->mu);
            put(p, &p->free_items, it);
            break;
        }
        put(p, &p->read_q, it);
    }
    pthread_mutex_lock(&p->mu);
    p->reader_done = 1;
    pthread_cond_broadcast(&p->cv);
    pthread_mutex_unlock(&p->mu);
    return NULL;
}

static void *unzip_main(void *arg)
{
    cdvr_player *p = arg;
    for (;;) {
        pthread_mutex_lock(&p->mu);
        while (!p->read_q.head && !p->reader_done && !p->abort)
            pthread_cond_wait(&p->cv, &p->mu);
        chunk_item *it = p->abort ? NULL : queue_pop(&p->read_q);
        pthread_mutex_unlock(&p->mu);
        if (!it)
            break;
        unzip(p, it);
        put(p, &p->unzip_q, it);
    }
    pthread_mutex_lock(&p->mu);
    p->unzip_done = 1;
    pthread_cond_broadcast(&p->cv);
    pthread_mutex_unlock(&p->mu);
    return NULL;
}

/* Waits for the next unzipped item, answering decision requests meanwhile (callbacks run
 * here, on the calling thread). NULL at the end or on a failed decision (err set). */
static chunk_item *next_ready(cdvr_player *p, cdvr_error *err)
{
    pthread_mutex_lock(&p->mu);
    for (;;) {
        if (p->unzip_q.head) {
            chunk_item *it = queue_pop(&p->unzip_q);
            pthread_mutex_unlock(&p->mu);
            return it;
        }
        if (p->decide_state == 1) {
            size_t t = p->decide_t, group = p->decide_group;
            int v = p->current_variant;
            pthread_mutex_unlock(&p->mu);
            cdvr_error derr;
            cdvr_error_clear(&derr);
            char reason[160] = "";
            p->opts.decide(p->opts.decide_ud, p, t, group, &v, reason, sizeof reason, &derr);
            pthread_mutex_lock(&p->mu);
            p->decide_variant = v;
            memcpy(p->decide_reason, reason, sizeof reason);
            p->decide_err = derr;
            p->decide_state = 2;
            pthread_cond_broadcast(&p->cv);
            if (derr.status != CDVR_OK) {
                if (err)
                    *err = derr;
                p->abort = 1;
                pthread_mutex_unlock(&p->mu);
                return NULL;
            }
            continue;
        }
        if (p->unzip_done || p->abort)
            break;
        pthread_cond_wait(&p->cv, &p->mu);
    }
    pthread_mutex_unlock(&p->mu);
    return NULL;
}

static cdvr_status run_pipelined(cdvr_player *p, cdvr_error *err)
{
    pthread_t reader, unzipper;
    if (pthread_create(&reader, NULL, reader_main, p) != 0)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "player: cannot start the reader thread");
    if (pthread_create(&unzipper, NULL, unzip_main, p) != 0) {
        pthread_mutex_lock(&p->mu);
        p->abort = 1;
        pthread_cond_broadcast(&p->cv);
        pthread_mutex_unlock(&p->mu);
        pthread_join(reader, NULL);
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "player: cannot start the unzip thread");
    }
    cdvr_status status = CDVR_OK;
    chunk_item *it;
    while ((it = next_ready(p, err)) != NULL) {
        status = consume(p, it, err);
        put(p, &p->free_items, it);
        if (status != CDVR_OK) {
            pthread_mutex_lock(&p->mu);
            p->abort = 1;
            pthread_cond_broadcast(&p->cv);
            pthread_mutex_unlock(&p->mu);
            break;
        }
    }
    if (status == CDVR_OK && err && err->status != CDVR_OK)
        status = err->status;
    pthread_join(reader, NULL);
    pthread_join(unzipper, NULL);
    return status;
}

static cdvr_status run_serial(cdvr_player *p, cdvr_error *err)
{
    chunk_item *it = &p->items[0];
    for (;;) {
        int r = plan_and_read(p, it, 0, err);
        if (r == 0)
            return CDVR_OK;
        if (r < 0)
            return err->status;
        unzip(p, it);
        cdvr_status s = consume(p, it, err);
        if (s != CDVR_OK)
            return s;
    }
}

/* ---- public ----------------------------------------------------------------------------- */

cdvr_status cdvr_player_create(const cdvr_player_opts *opts, cdvr_player **out, cdvr_error *err)
{
    *out = NULL;
    if (!opts->store || !opts->tf)
        return cdvr_error_set(err, CDVR_ERR_ARG, "player: store and tf are required");
    const cdvr_store_info *info = cdvr_store_get_info(opts->store);
    if (opts->variant < 0 || (size_t)opts->variant >= info->nvariants)
        return cdvr_error_set(err, CDVR_ERR_ARG, "player: variant %d out of range 1..%zu", opts->variant + 1, info->nvariants);
    if (cdvr_camera_validate(&opts->camera, err) != CDVR_OK)
        return err ? err->status : CDVR_ERR_ARG;
    cdvr_player *p = calloc(1, sizeof *p);
    if (!p)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "player: out of memory");
    p->opts = *opts;
    if (p->opts.ring <= 0)
        p->opts.ring = 3;
    p->group_len = cdvr_player_group_length(opts->store);
    p->voxels = info->dims[0] * info->dims[1] * info->dims[2];
    p->nbricks = info->nbricks;
    p->nitems = (size_t)p->opts.ring * 2 + 1;
    p->items = calloc(p->nitems, sizeof *p->items);
    for (size_t i = 0; p->items && i < p->nitems; i++)
        if (!(p->items[i].parts = calloc(p->nbricks, sizeof *p->items[i].parts)))
            p->nitems = i; /* free what was made, then fail below */
    pthread_mutex_init(&p->mu, NULL);
    pthread_cond_init(&p->cv, NULL);
    if (!p->items || p->nitems != (size_t)p->opts.ring * 2 + 1) {
        cdvr_player_free(p);
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "player: out of memory");
    }
    if (opts->device == CDVR_DEVICE_CL) {
#if CDVR_HAVE_OPENCL
        cdvr_status s = cdvr_cl_open(&p->cl, err);
        if (s == CDVR_OK)
            s = cdvr_cl_stream_create(p->cl, info->dims, &p->stream, err);
        if (s == CDVR_OK)
            cdvr_cl_set_skipping(p->stream, opts->empty_skip);
        if (s != CDVR_OK) {
            cdvr_player_free(p);
            return s;
        }
#else
        cdvr_player_free(p);
        return cdvr_error_set(err, CDVR_ERR_UNSUPPORTED, "player: device 'cl': this cdvr was built without OpenCL");
#endif
    }
    *out = p;
    return CDVR_OK;
}

void cdvr_player_free(cdvr_player *p)
{
    if (!p)
        return;
    for (size_t i = 0; p->items && i < p->nitems; i++) {
        for (size_t b = 0; p->items[i].parts && b < p->nbricks; b++) {
            free(p->items[i].parts[b].stored);
            free(p->items[i].parts[b].payload);
        }
        free(p->items[i].parts);
    }
    free(p->items);
    free(p->rows);
    free(p->host_frames);
    free(p->brick_frames);
#if CDVR_HAVE_OPENCL
    cdvr_cl_stream_free(p->stream);
    cdvr_cl_close(p->cl);
#endif
    pthread_mutex_destroy(&p->mu);
    pthread_cond_destroy(&p->cv);
    free(p);
}

cdvr_status cdvr_player_run(cdvr_player *p, size_t first, size_t frames, cdvr_error *err)
{
    const cdvr_store_info *info = cdvr_store_get_info(p->opts.store);
    if (first >= info->timesteps)
        return cdvr_error_set(err, CDVR_ERR_ARG, "player: first timestep %zu out of range 1..%zu", first + 1, info->timesteps);
    size_t left = info->timesteps - first;
    p->stopped_early = !p->opts.loop && frames > left ? frames - left : 0;
    p->first = first;
    p->frames = frames - p->stopped_early;
    p->nrows = 0;
    p->planned = 0;
    p->current_variant = p->opts.variant;
    p->reader_done = p->unzip_done = p->abort = 0;
    p->decide_state = 0;
    memset(&p->free_items, 0, sizeof p->free_items);
    memset(&p->read_q, 0, sizeof p->read_q);
    memset(&p->unzip_q, 0, sizeof p->unzip_q);
    for (size_t i = 0; i < p->nitems; i++)
        queue_push(&p->free_items, &p->items[i]);
    p->t_last_frame = p->t_deadline = cdvr_now_ms();
    cdvr_error e; /* err may be NULL (error.h): the stages always get a real one */
    cdvr_error_clear(&e);
    cdvr_status s = p->opts.pipelined ? run_pipelined(p, &e) : run_serial(p, &e);
    if (err)
        *err = e;
    return s;
}

size_t cdvr_player_stopped_early(const cdvr_player *p)
{
    return p->stopped_early;
}

const cdvr_frame_row *cdvr_player_rows(const cdvr_player *p, size_t *count)
{
    *count = p->nrows;
    return p->rows;
}

double cdvr_player_fps(const cdvr_player *p)
{
    double *ms = malloc((p->nrows ? p->nrows : 1) * sizeof *ms);
    if (!ms)
        return 0;
    size_t n = 0;
    for (size_t i = 0; i < p->nrows; i++)
        if (p->rows[i].status == CDVR_OK)
            ms[n++] = p->rows[i].interval_ms;
    double med = cdvr_median(ms, n);
    free(ms);
    return med > 0 ? 1000.0 / med : 0;
}
