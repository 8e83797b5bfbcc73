/* core/dist/dist_single.c - cdvr/dist.h in a build without MPI: a group of one process, which
 * plays every distributed mode in full itself. */
#include "cdvr/dist.h"
#include "dist_internal.h"

#include <stdlib.h>

struct cdvr_dist_play {
    cdvr_dist_mode mode;
};

cdvr_status cdvr_dist_init(int *argc, char ***argv, cdvr_error *err)
{
    (void)argc, (void)argv, (void)err;
    return CDVR_OK;
}

void cdvr_dist_finalize(void)
{
}

int cdvr_dist_built(void)
{
    return 0;
}

int cdvr_dist_rank(void)
{
    return 0;
}

int cdvr_dist_size(void)
{
    return 1;
}

void cdvr_dist_barrier(void)
{
}

void cdvr_dist_abort(int code)
{
    (void)code;
}

cdvr_status cdvr_dist_play_create(cdvr_dist_mode mode, cdvr_player_opts *opts,
                                  cdvr_dist_play **out, cdvr_error *err)
{
    *out = calloc(1, sizeof **out);
    if (!*out)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "distribute: out of memory");
    (*out)->mode = mode;
    cdvr_dist_share(mode, 0, 1, opts);
    return CDVR_OK;
}

cdvr_status cdvr_dist_play_begin(cdvr_dist_play *dp, size_t first, size_t frames, cdvr_error *err)
{
    (void)dp, (void)first, (void)frames, (void)err;
    return CDVR_OK;
}

double cdvr_dist_timeout_s(void)
{
    return CDVR_DIST_TIMEOUT_DEFAULT;
}

void cdvr_dist_play_free(cdvr_dist_play *dp)
{
    free(dp);
}

int cdvr_dist_play_shows_frames(const cdvr_dist_play *dp)
{
    (void)dp;
    return 1;
}

cdvr_status cdvr_dist_play_gather(cdvr_dist_play *dp, const cdvr_player *p, double wall_ms,
                                  const cdvr_frame_row **rows, size_t *count, double *fps,
                                  cdvr_error *err)
{
    (void)err;
    *rows = cdvr_player_rows(p, count);
    size_t ok = 0;
    for (size_t i = 0; i < *count; i++)
        ok += (*rows)[i].status == CDVR_OK;
    *fps = dp->mode == CDVR_DIST_TIME ? cdvr_dist_time_fps(ok, wall_ms) : cdvr_player_fps(p);
    return CDVR_OK;
}
