/* core/dist/dist_mpi.c - cdvr/dist.h with MPI (OpenMPI) and IceT: the process group, the
 * per-frame sort-last composite of distributed playback, and the gathering of rows.
 *
 * MPI membership is process-wide by nature, so it lives in one clearly named context,
 * `the_group`; IceT's draw callback takes no user pointer, so the image it copies is handed
 * over in `the_group.draw_source` for the duration of one icetDrawFrame. All MPI and IceT
 * calls come from the thread that called cdvr_dist_init (MPI_THREAD_FUNNELED). */
#include "cdvr/dist.h"
#include "cdvr/timing.h"
#include "dist_internal.h"

#include <IceT.h>
#include <IceTMPI.h>
#include <mpi.h>

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

static struct {
    int joined;                     /* MPI_Init_thread done by us */
    int rank, size;
    int icet_ready;
    IceTCommunicator icet_comm;
    IceTContext icet_ctx;           /* one per process, shared by every distributed player */
    const cdvr_image *draw_source;  /* the image the draw callback copies (NULL: transparent) */
} the_group = {0, 0, 1, 0, NULL, NULL, NULL};

struct cdvr_dist_play {
    cdvr_dist_mode mode;
    const cdvr_store *store;
    uint32_t store_hash, camera_hash; /* what the ranks must agree on (cdvr_dist_play_begin) */
    int *order;                     /* size: blend order of the ranks */
    cdvr_frame_row *rows;           /* gathered rows (rank 0) */
    size_t nrows;
};

static int launched_by_mpi(void)
{
    static const char *const vars[] = {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_RANK", NULL};
    for (int i = 0; vars[i]; i++)
        if (getenv(vars[i]))
            return 1;
    return 0;
}

cdvr_status cdvr_dist_init(int *argc, char ***argv, cdvr_error *err)
{
    if (the_group.joined || !launched_by_mpi())
        return CDVR_OK;
    int provided = 0;
    if (MPI_Init_thread(argc, argv, MPI_THREAD_FUNNELED, &provided) != MPI_SUCCESS)
        return cdvr_error_set(err, CDVR_ERR_UNSUPPORTED, "MPI_Init_thread failed");
    if (provided < MPI_THREAD_FUNNELED) { /* the player's threads need at least this */
        MPI_Finalize();
        return cdvr_error_set(err, CDVR_ERR_UNSUPPORTED, "MPI gives thread level %d, cdvr needs "
                              "MPI_THREAD_FUNNELED", provided);
    }
    the_group.joined = 1;
    MPI_Comm_rank(MPI_COMM_WORLD, &the_group.rank);
    MPI_Comm_size(MPI_COMM_WORLD, &the_group.size);
    return CDVR_OK;
}

void cdvr_dist_finalize(void)
{
    if (!the_group.joined)
        return;
    if (the_group.icet_ready) {
        icetDestroyContext(the_group.icet_ctx);
        icetDestroyMPICommunicator(the_group.icet_comm);
        the_group.icet_ready = 0;
    }
    MPI_Finalize();
    the_group.joined = 0;
}

int cdvr_dist_built(void)
{
    return 1;
}

int cdvr_dist_rank(void)
{
    return the_group.rank;
}

int cdvr_dist_size(void)
{
    return the_group.size;
}

/* ---- collective calls with a deadline ---------------------------------------------------- */

double cdvr_dist_timeout_s(void)
{
    const char *env = getenv("CDVR_MPI_TIMEOUT");
    char *end = NULL;
    double s = env ? strtod(env, &end) : 0;
    return env && end != env && *end == '\0' && s > 0 && s <= 1e6 ? s : CDVR_DIST_TIMEOUT_DEFAULT;
}

/* Completes req (a nonblocking collective call), polling; when the other ranks have not come
 * within cdvr_dist_timeout_s() this rank reports itself, naming `what`, and ends the run
 * (MPI_Abort): a rank that waits where no other rank will come never hangs. */
static void wait_collective(MPI_Request *req, const char *what)
{
    double limit = cdvr_dist_timeout_s(), deadline = cdvr_now_ms() + 1e3 * limit;
    int done = 0;
    for (unsigned polls = 0;; polls++) {
        MPI_Test(req, &done, MPI_STATUS_IGNORE);
        if (done)
            return;
        if (cdvr_now_ms() > deadline) {
            fprintf(stderr, "cdvr: rank %d of %d: %s: the other ranks did not come within %g s "
                    "(CDVR_MPI_TIMEOUT): this rank waits where no other rank will come (a barrier, a "
                    "player or a run that only some ranks reach?); ending the run\n",
                    the_group.rank, the_group.size, what, limit);
            cdvr_dist_abort(1);
            exit(1);
        }
        if (polls > 1000) { /* after the first millisecond or so, poll every 200 us */
            struct timespec ts = {0, 200000};
            nanosleep(&ts, NULL);
        }
    }
}

void cdvr_dist_barrier(void)
{
    if (!the_group.joined)
        return;
    MPI_Request req;
    MPI_Ibarrier(MPI_COMM_WORLD, &req);
    wait_collective(&req, "cdvr.mpi.barrier()");
}

/* One value per item that every rank must share: the item's name, how to print a value (NULL:
 * a fingerprint, not printed) and this rank's value (0 .. 2^30-1). */
typedef struct agree_item {
    const char *what;
    const char *const *names; /* names of values 0, 1, ... (NULL: print the number) */
    int fingerprint;          /* 1: a hash, printed as "differs" only */
    int value;
} agree_item;

/* Appends "what (rank a: x, rank b: y)" for an item the ranks disagree on. */
static void describe(char *msg, size_t size, const agree_item *it, int lo, int lo_rank, int hi, int hi_rank)
{
    size_t len = strlen(msg);
    char a[32], b[32];
    if (it->names) {
        snprintf(a, sizeof a, "%s", it->names[lo]);
        snprintf(b, sizeof b, "%s", it->names[hi]);
    } else {
        snprintf(a, sizeof a, "%d", lo);
        snprintf(b, sizeof b, "%d", hi);
    }
    if (it->fingerprint)
        snprintf(msg + len, size - len, "%s%s (rank %d's differs from rank %d's)", len ? "; " : "", it->what,
                 lo_rank, hi_rank);
    else
        snprintf(msg + len, size - len, "%s%s (rank %d: %s, rank %d: %s)", len ? "; " : "", it->what, lo_rank,
                 a, hi_rank, b);
}

#define MAX_AGREE 8

/* One collective check that every rank has the same values: a MAXLOC reduction over
 * (value, rank) and (-value, rank) pairs gives each item's largest and smallest value and a
 * rank holding each. A disagreement is the same error on every rank, naming what differs. */
static cdvr_status agree(const char *when, const agree_item *items, int n, cdvr_error *err)
{
    int in[2 * MAX_AGREE][2], out[2 * MAX_AGREE][2];
    for (int i = 0; i < n; i++) {
        in[2 * i][0] = items[i].value;
        in[2 * i + 1][0] = -items[i].value;
        in[2 * i][1] = in[2 * i + 1][1] = the_group.rank;
    }
    MPI_Request req;
    MPI_Iallreduce(in, out, 2 * n, MPI_2INT, MPI_MAXLOC, MPI_COMM_WORLD, &req);
    wait_collective(&req, when);
    char msg[CDVR_ERRMSG_MAX] = "";
    for (int i = 0; i < n; i++) {
        int hi = out[2 * i][0], hi_rank = out[2 * i][1], lo = -out[2 * i + 1][0], lo_rank = out[2 * i + 1][1];
        if (hi != lo)
            describe(msg, sizeof msg / 2, &items[i], lo, lo_rank, hi, hi_rank);
    }
    if (!msg[0])
        return CDVR_OK;
    return cdvr_error_set(err, CDVR_ERR_ARG, "distribute: the ranks disagree at %s: %s; every rank must run the "
                          "same player (distribute=, store, camera, frames)", when, msg);
}

static const char *const mode_names[] = {"none", "time", "bricks"};

/* A count as an agree value: itself below 2^30, else a fingerprint. */
static int count_value(size_t n, int *fingerprint)
{
    *fingerprint = n >= 0x40000000u;
    return *fingerprint ? (int)((n ^ (n >> 30) ^ (n >> 60)) & 0x3fffffff) : (int)n;
}

void cdvr_dist_abort(int code)
{
    if (!the_group.joined || the_group.size < 2)
        return;
    fflush(stdout);
    fflush(stderr);
    MPI_Abort(MPI_COMM_WORLD, code);
}

/* ---- compositing ------------------------------------------------------------------------- */

/* IceT's draw callback: the rank's premultiplied image into IceT's (rows from the bottom). */
static void draw_rank_image(const IceTDouble *projection, const IceTDouble *modelview,
                            const IceTFloat *background, const IceTInt *viewport, IceTImage out)
{
    (void)projection, (void)modelview, (void)background, (void)viewport;
    IceTFloat *px = icetImageGetColorf(out);
    int w = (int)icetImageGetWidth(out), h = (int)icetImageGetHeight(out);
    const cdvr_image *src = the_group.draw_source;
    for (int y = 0; y < h; y++) {
        float *row = px + 4 * (size_t)y * (size_t)w;
        if (src && src->width == w && src->height == h)
            memcpy(row, cdvr_image_pixel(src, 0, h - 1 - y), 4 * sizeof(float) * (size_t)w);
        else
            memset(row, 0, 4 * sizeof(float) * (size_t)w);
    }
}

static void icet_setup(int width, int height, const int *order)
{
    icetSetContext(the_group.icet_ctx);
    icetResetTiles();
    icetAddTile(0, 0, width, height, 0);
    icetSetColorFormat(ICET_IMAGE_COLOR_RGBA_FLOAT);
    icetSetDepthFormat(ICET_IMAGE_DEPTH_NONE);
    icetCompositeMode(ICET_COMPOSITE_MODE_BLEND);
    icetEnable(ICET_ORDERED_COMPOSITE);
    icetDisable(ICET_CORRECT_COLORED_BACKGROUND);
    icetStrategy(ICET_STRATEGY_REDUCE);
    icetSingleImageStrategy(ICET_SINGLE_IMAGE_STRATEGY_AUTOMATIC);
    icetCompositeOrder((const IceTInt *)order);
    icetDrawCallback(draw_rank_image);
}

/* The composite hook of CDVR_DIST_BRICKS (player.h): every rank's image blended in
 * visibility order into rank 0's. */
static cdvr_status composite_frame(void *ud, const cdvr_frame_row *row, const cdvr_camera *cam,
                                   cdvr_image **img, double *wait_ms, cdvr_error *err)
{
    cdvr_dist_play *dp = ud;
    /* the failed rank (or -1) and this frame's camera: every rank must render the same view */
    int seen = (int)cdvr_dist_camera_hash(cam);
    int mine[3] = {row->status != CDVR_OK ? the_group.rank : -1, seen, -seen}, all[3];
    double t0 = cdvr_now_ms(); /* the reduction completes when the last rank's frame is ready */
    MPI_Request req;
    MPI_Iallreduce(mine, all, 3, MPI_INT, MPI_MAX, MPI_COMM_WORLD, &req);
    wait_collective(&req, "the composite of a frame (distribute='bricks')");
    *wait_ms = cdvr_now_ms() - t0;
    if (all[0] >= 0 || all[1] != -all[2]) {
        if (the_group.rank == 0) {
            cdvr_image_free(*img);
            *img = NULL;
        }
        if (all[0] < 0)
            return cdvr_error_set(err, CDVR_ERR_ARG, "frame %zu: the ranks disagree on its camera (a camera "
                                  "path must give every rank the same camera)", row->frame + 1);
        return cdvr_error_set(err, CDVR_ERR_IO, "frame %zu failed on rank %d (its row has the "
                              "reason)", row->frame + 1, all[0]);
    }
    const cdvr_store_info *info = cdvr_store_get_info(dp->store);
    cdvr_dist_view view;
    cdvr_dist_view_of(info, cam, &view);
    cdvr_dist_order(info->dims, info->bricks, (size_t)the_group.size, &view, dp->order);
    icet_setup(cam->width, cam->height, dp->order);
    static const IceTDouble identity[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
    static const IceTFloat transparent[4] = {0, 0, 0, 0};
    the_group.draw_source = *img;
    IceTImage result = icetDrawFrame(identity, identity, transparent);
    the_group.draw_source = NULL;
    if (the_group.rank != 0)
        return CDVR_OK;
    if (icetImageIsNull(result) || icetImageGetWidth(result) != cam->width ||
        icetImageGetHeight(result) != cam->height || !*img)
        return cdvr_error_set(err, CDVR_ERR_UNSUPPORTED, "IceT returned no %dx%d image on rank 0",
                              cam->width, cam->height);
    const IceTFloat *px = icetImageGetColorcf(result);
    for (int y = 0; y < cam->height; y++)
        memcpy(cdvr_image_pixel(*img, 0, cam->height - 1 - y), px + 4 * (size_t)y * (size_t)cam->width,
               4 * sizeof(float) * (size_t)cam->width);
    return CDVR_OK;
}

/* IceT's context, made once per process (collective: every rank creates the same players in
 * the same order, running the same script) and kept until cdvr_dist_finalize, so that no
 * collective call happens when Lua's collector frees a player. */
static cdvr_status icet_context(cdvr_error *err)
{
    if (the_group.icet_ready)
        return CDVR_OK;
    the_group.icet_comm = icetCreateMPICommunicator(MPI_COMM_WORLD);
    if (!the_group.icet_comm)
        return cdvr_error_set(err, CDVR_ERR_UNSUPPORTED, "IceT: cannot create its communicator");
    the_group.icet_ctx = icetCreateContext(the_group.icet_comm);
    icetDiagnostics(ICET_DIAG_ERRORS | ICET_DIAG_ALL_NODES);
    the_group.icet_ready = 1;
    return CDVR_OK;
}

/* ---- distributed playback ---------------------------------------------------------------- */

cdvr_status cdvr_dist_play_create(cdvr_dist_mode mode, cdvr_player_opts *opts,
                                  cdvr_dist_play **out, cdvr_error *err)
{
    *out = NULL;
    int spatial = mode == CDVR_DIST_BRICKS && the_group.size > 1;
    uint32_t store_hash = opts->store ? cdvr_dist_store_hash(opts->store) : 0;
    uint32_t camera_hash = cdvr_dist_camera_hash(&opts->camera);
    if (the_group.joined && the_group.size > 1 && mode != CDVR_DIST_NONE) {
        /* before any other collective call (IceT's communicator): ranks in different modes
         * would otherwise wait in different calls */
        agree_item items[] = {{"the distribute mode", mode_names, 0, (int)mode},
                              {"the store", NULL, 1, (int)store_hash},
                              {"the camera", NULL, 1, (int)camera_hash}};
        cdvr_status st = agree("cdvr.player{distribute=...}", items, 3, err);
        if (st != CDVR_OK)
            return st;
    }
    if (spatial && icet_context(err) != CDVR_OK)
        return err ? err->status : CDVR_ERR_UNSUPPORTED;
    cdvr_dist_play *dp = calloc(1, sizeof *dp);
    if (!dp || !(dp->order = calloc((size_t)the_group.size, sizeof *dp->order))) {
        free(dp);
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "distribute: out of memory");
    }
    dp->mode = mode;
    dp->store = opts->store;
    dp->store_hash = store_hash;
    dp->camera_hash = camera_hash;
    cdvr_dist_share(mode, the_group.rank, the_group.size, opts);
    if (spatial) {
        opts->composite = composite_frame;
        opts->composite_ud = dp;
    }
    *out = dp;
    return CDVR_OK;
}

void cdvr_dist_play_free(cdvr_dist_play *dp)
{
    if (!dp)
        return;
    free(dp->order);
    free(dp->rows);
    free(dp);
}

cdvr_status cdvr_dist_play_begin(cdvr_dist_play *dp, size_t first, size_t frames, cdvr_error *err)
{
    if (!the_group.joined || the_group.size < 2 || dp->mode == CDVR_DIST_NONE)
        return CDVR_OK;
    int fp_first, fp_frames;
    int v_first = count_value(first + 1, &fp_first), v_frames = count_value(frames, &fp_frames);
    agree_item items[] = {{"the distribute mode", mode_names, 0, (int)dp->mode},
                          {"the store", NULL, 1, (int)dp->store_hash},
                          {"the camera", NULL, 1, (int)dp->camera_hash},
                          {"the first timestep", NULL, fp_first, v_first},
                          {"the frame count", NULL, fp_frames, v_frames}};
    return agree("p:run (distributed)", items, 5, err);
}

int cdvr_dist_play_shows_frames(const cdvr_dist_play *dp)
{
    return dp->mode != CDVR_DIST_BRICKS || the_group.rank == 0;
}

/* Inside a collective operation a rank cannot just fail: the others would wait for it. */
static void out_of_memory(const char *what)
{
    fprintf(stderr, "cdvr: rank %d: out of memory for %s\n", the_group.rank, what);
    cdvr_dist_abort(1);
    exit(1);
}

static size_t ok_rows(const cdvr_frame_row *rows, size_t n)
{
    size_t ok = 0;
    for (size_t i = 0; i < n; i++)
        ok += rows[i].status == CDVR_OK;
    return ok;
}

cdvr_status cdvr_dist_play_gather(cdvr_dist_play *dp, const cdvr_player *p, double wall_ms,
                                  const cdvr_frame_row **rows, size_t *count, double *fps,
                                  cdvr_error *err)
{
    size_t n;
    const cdvr_frame_row *mine = cdvr_player_rows(p, &n);
    *rows = mine;
    *count = n;
    if (dp->mode == CDVR_DIST_TIME)
        *fps = cdvr_dist_time_fps(ok_rows(mine, n), wall_ms);
    else
        *fps = cdvr_player_fps(p);
    if (!the_group.joined || the_group.size < 2 || dp->mode == CDVR_DIST_NONE)
        return CDVR_OK;
    size_t row_bytes = sizeof(cdvr_frame_row);
    if (n > (size_t)(0x7fffffff / row_bytes))
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "distribute: too many rows to gather (%zu)", n);
    int bytes = (int)(n * row_bytes), root = the_group.rank == 0, size = the_group.size;
    double slowest = wall_ms;
    MPI_Request req;
    MPI_Ireduce(&wall_ms, &slowest, 1, MPI_DOUBLE, MPI_MAX, 0, MPI_COMM_WORLD, &req);
    wait_collective(&req, "the end of a distributed run (gathering the rows)");
    int *counts = root ? calloc((size_t)size, 2 * sizeof *counts) : NULL;
    if (root && !counts)
        out_of_memory("the row counts");
    MPI_Igather(&bytes, 1, MPI_INT, counts, 1, MPI_INT, 0, MPI_COMM_WORLD, &req);
    wait_collective(&req, "the end of a distributed run (gathering the rows)");
    size_t total = 0;
    int *displs = root ? counts + size : NULL;
    for (int r = 0; root && r < size; r++) {
        displs[r] = (int)total;
        total += (size_t)counts[r];
    }
    free(dp->rows);
    dp->rows = NULL;
    dp->nrows = 0;
    if (root && (total > 0x7fffffff || !(dp->rows = malloc(total ? total : 1))))
        out_of_memory("the gathered rows");
    MPI_Igatherv(mine, bytes, MPI_BYTE, dp->rows, counts, displs, MPI_BYTE, 0, MPI_COMM_WORLD, &req);
    wait_collective(&req, "the end of a distributed run (gathering the rows)");
    free(counts);
    if (!root)
        return CDVR_OK;
    dp->nrows = total / row_bytes;
    cdvr_dist_sort_rows(dp->rows, dp->nrows);
    *rows = dp->rows;
    *count = dp->nrows;
    if (dp->mode == CDVR_DIST_TIME)
        *fps = cdvr_dist_time_fps(ok_rows(dp->rows, dp->nrows), slowest);
    return CDVR_OK;
}
