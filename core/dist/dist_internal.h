/* core/dist/dist_internal.h - what the two process-group implementations (dist_mpi.c with
 * MPI and IceT, dist_single.c without) share from dist_plan.c. */
#ifndef CDVR_DIST_INTERNAL_H
#define CDVR_DIST_INTERNAL_H

#include <stdint.h>

#include "cdvr/dist.h"

/* Fills opts for rank `rank` of `size` in `mode`: rank, frame stride and phase (time), or the
 * brick region of cdvr_dist_partition (bricks; a part without bricks gets an empty region). */
void cdvr_dist_share(cdvr_dist_mode mode, int rank, int size, cdvr_player_opts *opts);
/* Frames per second of a time-distributed run. */
double cdvr_dist_time_fps(size_t ok_frames, double slowest_wall_ms);
/* Sorts rows by frame, then rank. */
void cdvr_dist_sort_rows(cdvr_frame_row *rows, size_t n);
/* 30-bit fingerprints of what every rank of a distributed run must share (dist_mpi.c compares
 * them across ranks): a store (header fields, size, variants; not its path) and a camera. */
uint32_t cdvr_dist_store_hash(const cdvr_store *st);
uint32_t cdvr_dist_camera_hash(const cdvr_camera *cam);

#endif
