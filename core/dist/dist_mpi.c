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

void cdvr_dist_barrier(void)
{
    if (the_group.joined)
        MPI_Barrier(MPI_COMM_WORLD);
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
    int mine = row->status != CDVR_OK ? the_group.rank : -1, failed = -1;
    double t0 = cdvr_now_ms(); /* the reduction completes when the last rank's frame is ready */
    MPI_Allreduce(&mine, &failed, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
    *wait_ms = cdvr_now_ms() - t0;
    if (failed >= 0) {
        if (the_group.rank == 0) {
            cdvr_image_free(*img);
            *img = NULL;
        }
        return cdvr_error_set(err, CDVR_ERR_IO, "frame %zu failed on rank %d (its row has the "
                              "reason)", row->frame + 1, failed);
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
    if (spatial && icet_context(err) != CDVR_OK)
        return err ? err->status : CDVR_ERR_UNSUPPORTED;
    cdvr_dist_play *dp = calloc(1, sizeof *dp);
    if (!dp || !(dp->order = calloc((size_t)the_group.size, sizeof *dp->order))) {
        free(dp);
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "distribute: out of memory");
    }
    dp->mode = mode;
    dp->store = opts->store;
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
    MPI_Reduce(&wall_ms, &slowest, 1, MPI_DOUBLE, MPI_MAX, 0, MPI_COMM_WORLD);
    int *counts = root ? calloc((size_t)size, 2 * sizeof *counts) : NULL;
    if (root && !counts)
        out_of_memory("the row counts");
    MPI_Gather(&bytes, 1, MPI_INT, counts, 1, MPI_INT, 0, MPI_COMM_WORLD);
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
    MPI_Gatherv(mine, bytes, MPI_BYTE, dp->rows, counts, displs, MPI_BYTE, 0, MPI_COMM_WORLD);
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
