/* cdvr/dist.h - beyond one machine: MPI ranks and sort-last compositing with IceT (DESIGN.md
 * section 12).
 *
 * Optional part: built with -DCDVR_WITH_MPI=ON (OpenMPI, IceT from ParaView), the functions
 * below use MPI and IceT; otherwise they describe a group of one process (rank 0 of 1) and
 * every distributed mode plays everything in this process. Scripts run unchanged either way.
 *
 * Process group. cdvr_dist_init joins MPI only when an MPI launcher started the process
 * (mpirun/mpiexec set OMPI_COMM_WORLD_SIZE, PMI_SIZE or PMIX_RANK in its environment): a
 * plain `cdvr script.lua` never starts MPI and is rank 0 of 1. MPI runs with
 * MPI_THREAD_FUNNELED: only the thread that called cdvr_dist_init makes MPI or IceT calls
 * (the player's reader and unzip threads never do). A fatal error on one rank must end every
 * rank: the host prints the failing rank's message, then calls cdvr_dist_abort (MPI_Abort),
 * so no rank waits forever in a collective call for a rank that has gone.
 *
 * No rank waits for ever where no other rank will come either: cdvr's own collective calls
 * (cdvr_dist_barrier, the agreement checks below, each frame's composite check and the
 * gathering of rows) are nonblocking calls polled against a deadline of cdvr_dist_timeout_s()
 * (CDVR_MPI_TIMEOUT seconds in the environment, default CDVR_DIST_TIMEOUT_DEFAULT); past it
 * the rank prints "cdvr: rank R of N: WHAT: the other ranks did not come within T s ..." and
 * ends the run (MPI_Abort). Set it above the longest time a rank may legitimately wait for
 * the others (e.g. rank 0 encoding the store while the others wait at a barrier).
 *
 * Distributed playback (cdvr.player{distribute=}):
 *  - CDVR_DIST_TIME: rank r of N plays the frames k = r, r+N, r+2N, ... of the run (frame
 *    numbers, timesteps and output names stay those of the whole run, so the frames of all
 *    ranks land in one numbered sequence); every rank reads, decodes, renders and writes its
 *    own frames, with no communication until the end of the run, when rank 0 gathers the rows.
 *  - CDVR_DIST_BRICKS (sort-last): the brick grid is split into N boxes of bricks by a k-d
 *    split (cdvr_dist_partition); rank r reads and decodes only its box's bricks (and, for a
 *    lossy variant, the bricks just below it whose voxels its cells interpolate: player.h) and
 *    renders its box's cells on the global sample grid (render.h, cdvr_render_clip). IceT
 *    then blends the N premultiplied RGBA32F images in visibility order to rank 0
 *    (ICET_COMPOSITE_MODE_BLEND, ICET_ORDERED_COMPOSITE, icetCompositeOrder from
 *    cdvr_dist_order, one tile displayed on rank 0, icetDrawFrame calling back into the rank's
 *    image); rank 0 writes the frames. Every rank plays every frame and evaluates the camera
 *    itself (camera paths must give every rank the same camera, as a script run on every rank
 *    does), and all ranks read the same variant (a policy that adapts per rank is refused).
 *    A frame that fails on any rank (a corrupt chunk) fails on rank 0 too, naming the rank.
 * The composite equals the one-process render up to float rounding of the blend: each box's
 * samples are exactly the one-process render's samples in its cells, and the boxes are
 * blended front to back in an order that is a visibility order for every ray. Early ray
 * termination acts per box, so with it on (term_alpha < 1) a pixel may differ by at most
 * 1 - term_alpha (0.01 by default) of its colour where the one-process ray stopped early.
 */
#ifndef CDVR_DIST_H
#define CDVR_DIST_H

#include <stddef.h>

#include "cdvr/camera.h"
#include "cdvr/error.h"
#include "cdvr/player.h"
#include "cdvr/store.h"

/* ---- process group ---------------------------------------------------------------------- */

/* Joins MPI when launched by an MPI launcher (see above); otherwise does nothing. */
cdvr_status cdvr_dist_init(int *argc, char ***argv, cdvr_error *err);
/* Leaves MPI (and IceT) if joined. */
void cdvr_dist_finalize(void);
/* 1 when this cdvr was built with MPI and IceT. */
int cdvr_dist_built(void);
/* This process's rank (0 .. size-1) and the number of processes (1 without MPI). */
int cdvr_dist_rank(void);
int cdvr_dist_size(void);
/* Waits until every process gets here (nothing in a group of one); a rank that waits longer
 * than cdvr_dist_timeout_s() reports itself and ends the run (see above). */
void cdvr_dist_barrier(void);
/* The deadline of a collective call: CDVR_MPI_TIMEOUT (seconds, > 0) or the default. */
#define CDVR_DIST_TIMEOUT_DEFAULT 1800.0
double cdvr_dist_timeout_s(void);
/* After a fatal error on this process, whose message is already printed: in a group of more
 * than one, ends every process with exit status `code` (MPI_Abort; does not return). In a
 * group of one it returns, and the caller exits as usual. */
void cdvr_dist_abort(int code);

/* ---- bricks of the grid per process, and the order to blend them ----------------------- */

/* Box [lo, hi) of the brick grid that part `part` of `nparts` gets. The grid is split
 * recursively (a k-d tree): a box with several parts is cut across one axis, its parts
 * shared half and half (the lower side gets the floor) and its bricks in proportion, rounded
 * to whole slabs with at least one slab each side; of the three axes the cut giving the
 * least loaded parts wins (then the axis with more bricks, then the lower axis). A box of one
 * brick goes to the first of its parts, the others get nothing. Returns 1 if the part has
 * bricks, 0 if it has none (lo == hi). The parts' boxes are disjoint and cover the grid. */
int cdvr_dist_partition(const size_t grid[3], size_t nparts, size_t part, size_t lo[3],
                        size_t hi[3]);

/* Where the rays come from, in voxel index coordinates of the volume (world -> index through
 * the inverse of the index-to-world map of volume.h). */
typedef struct cdvr_dist_view {
    int orthographic;
    double eye[3];       /* perspective: the eye */
    double dir[3];       /* orthographic: the view direction */
} cdvr_dist_view;

/* The view of camera cam on a store's volume. */
void cdvr_dist_view_of(const cdvr_store_info *info, const cdvr_camera *cam,
                       cdvr_dist_view *view);

/* A visibility order of the parts of cdvr_dist_partition for a view: order[0] is the part
 * nearest the viewer (blended first). At every cut of the recursion the side holding the eye
 * (orthographic: the side the view direction leaves) comes first, so every ray meets the
 * parts' boxes in this order. The cut between bricks i-1 and i lies on voxel plane c_i of
 * the brick rule (store.h, cdvr_brick_box). Parts without bricks are listed too. */
void cdvr_dist_order(const size_t vol_dims[3], const size_t grid[3], size_t nparts,
                     const cdvr_dist_view *view, int *order);

/* ---- distributed playback --------------------------------------------------------------- */

typedef enum cdvr_dist_mode {
    CDVR_DIST_NONE = 0,    /* every process plays everything itself */
    CDVR_DIST_TIME,        /* rank r plays frames r, r+N, ... */
    CDVR_DIST_BRICKS       /* rank r plays its box of bricks; IceT composites to rank 0 */
} cdvr_dist_mode;

typedef struct cdvr_dist_play cdvr_dist_play;

/* Sets opts up for this process's share of a run in `mode` (frame stride and phase, or the
 * brick region and the composite hook; opts->rank) and creates what the run needs (the IceT
 * context, once per process). Collective over all processes. In CDVR_DIST_BRICKS mode the
 * caller makes every rank read the same variant: opts->decide, if any, must decide the same
 * on every rank (the Lua binding refuses a policy outside capture, where policies follow the
 * deterministic capture rule). */
cdvr_status cdvr_dist_play_create(cdvr_dist_mode mode, cdvr_player_opts *opts,
                                  cdvr_dist_play **out, cdvr_error *err);
/* Agreement. In a group of several processes and a mode other than CDVR_DIST_NONE,
 * cdvr_dist_play_create first checks, in one collective call before any other, that every
 * rank asks for the same mode, store (header, size and variants: cdvr_dist_store_hash) and
 * initial camera; cdvr_dist_play_begin, called by every rank before cdvr_player_run, checks
 * mode, store, camera, the first timestep (from 0) and the frame count again the same way. A
 * disagreement is the same CDVR_ERR_ARG on every rank, naming what differs and the ranks
 * ("distribute: the ranks disagree at ...: the distribute mode (rank 0: time, rank 1:
 * bricks)"); stores and cameras are compared by fingerprint. In CDVR_DIST_BRICKS every
 * frame's composite also checks that all ranks render the same camera (the frame fails
 * otherwise). A rank that never comes (it made no such player) is the timeout above. */
cdvr_status cdvr_dist_play_begin(cdvr_dist_play *dp, size_t first, size_t frames, cdvr_error *err);
void cdvr_dist_play_free(cdvr_dist_play *dp);
/* 1 if this process shows or writes the run's frames (CDVR_DIST_BRICKS: rank 0 only). */
int cdvr_dist_play_shows_frames(const cdvr_dist_play *dp);
/* After cdvr_player_run returned on every process (wall_ms: how long it took here):
 * gathers the rows of every process at rank 0, sorted by frame then rank. On rank 0 *rows
 * lists them (owned by dp, valid until the next gather or free), elsewhere this process's
 * own rows. *fps: frames per second of the whole group: CDVR_DIST_TIME counts the frames
 * without error of all ranks over the slowest rank's wall time; otherwise rank 0's
 * cdvr_player_fps. Collective over all processes. */
cdvr_status cdvr_dist_play_gather(cdvr_dist_play *dp, const cdvr_player *p, double wall_ms,
                                  const cdvr_frame_row **rows, size_t *count, double *fps,
                                  cdvr_error *err);

#endif
