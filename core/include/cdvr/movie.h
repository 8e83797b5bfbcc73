/* cdvr/movie.h - movies (mp4, webm, mkv, gif) written through FFmpeg's libraries.
 *
 *   cdvr_movie *m;
 *   cdvr_movie_opts o = cdvr_movie_defaults();
 *   o.fps = 30;
 *   if (cdvr_movie_open("out.mp4", &o, &m, err) != CDVR_OK) return err->status;
 *   for (...) if (cdvr_movie_add_image(m, img, err) != CDVR_OK) { cdvr_movie_abort(m); return ...; }
 *   return cdvr_movie_close(m, err);
 *
 * The container is the path's extension and picks the default codec:
 *   .mp4   H.264 (libx264), yuv420p, crf (default 18) and preset (default "medium")
 *   .webm  VP9 (libvpx-vp9), yuv420p, crf (default 31; constant quality)
 *   .mkv   FFV1 (lossless), 8-bit RGB (bgr0): the decoded frames are the RGB8 of the images
 *   .gif   GIF with a fixed 256-colour palette (a 6x6x6 colour cube and 40 greys), nearest
 *          colour, no dithering
 * codec= may name another of these encoders ("h264", "vp9", "ffv1", "gif") that the container
 * takes (mkv takes all four but gif; mp4 h264 and vp9; webm vp9; gif gif only).
 * Frames: an image is written as cdvr_image_to_rgb8 (the bytes of its PNG). yuv420p needs an
 * even width and height: an odd size is padded by one column or row repeating the last one
 * (the decoded movie is then 1 pixel wider or taller than the images). FFV1 and GIF take any
 * size. Every frame must have the size of the first (or of opts width/height).
 * Determinism: the muxer and encoders run in bit-exact mode (no version strings, dates or
 * random UIDs in the file) with a fixed thread count, so the same frames give the same file.
 * Threads: each movie converts, encodes and muxes on its own encoder thread, one frame behind
 * the caller (add returns once the frame is copied and the previous one is encoded), so a
 * capture renders while it encodes; an encoder failure is returned by the next add or by close.
 * Writing goes through cdvr_atomic_file (cdvr/atomicfile.h): the data goes to a temporary
 * file that close links in under path; abort, a failed write or close, a cleanup signal
 * (SIGINT, SIGTERM, ...) or the death of the process leaves nothing under path.
 * Builds without FFmpeg (CMake found no libavformat/libavcodec/libswscale/libavutil) keep the
 * functions: cdvr_movie_available() is 0 and cdvr_movie_open fails with CDVR_ERR_UNSUPPORTED.
 */
#ifndef CDVR_MOVIE_H
#define CDVR_MOVIE_H

#include <stdint.h>

#include "cdvr/error.h"
#include "cdvr/image.h"

typedef struct cdvr_movie cdvr_movie;

typedef struct cdvr_movie_opts {
    double fps;         /* frames per second, > 0 and <= 1000 (default 25) */
    const char *codec;  /* NULL: the container's default; else "h264", "vp9", "ffv1", "gif" */
    int crf;            /* H.264 0..51, VP9 0..63; -1: the codec's default (H.264 18, VP9 31) */
    const char *preset; /* H.264 preset (ultrafast .. veryslow); NULL: "medium" */
    int width, height;  /* frame size; 0 and 0: the first frame's size */
    int threads;        /* encoder threads, 1..64 (default 1). The same frames and thread count
                         * give the same file; FFV1 files do not depend on it, H.264 files do
                         * (x264's frame threads change its decisions: measured 1 vs 4) */
} cdvr_movie_opts;

/* 1 where this build writes movies (FFmpeg found), else 0. */
int cdvr_movie_available(void);
/* The defaults above. */
cdvr_movie_opts cdvr_movie_defaults(void);
/* 1 if path ends in a movie container's extension (.mp4, .webm, .mkv, .gif; any case), else
 * 0. Needs no FFmpeg (the player uses it to tell a movie from a PNG pattern). */
int cdvr_movie_is_movie_path(const char *path);
/* Checks the options and opens the temporary file of path (not yet the encoder when the size
 * comes from the first frame). Errors name path: an unknown container ("x.avi: unknown movie
 * container '.avi' ..."), a codec the container does not take, a bad fps/crf/preset/size, an
 * unwritable directory (the atomic file's message), a build without FFmpeg. */
cdvr_status cdvr_movie_open(const char *path, const cdvr_movie_opts *opts, cdvr_movie **out,
                            cdvr_error *err);
/* Adds one frame of 8-bit RGBA (alpha ignored; row 0 the top) of width x height; the size
 * must be the movie's. On failure the movie stays open: abort it. */
cdvr_status cdvr_movie_add_rgba8(cdvr_movie *m, const uint8_t *rgba, int width, int height,
                                 cdvr_error *err);
/* Adds img as its cdvr_image_to_rgb8 bytes (the colours of its PNG). */
cdvr_status cdvr_movie_add_image(cdvr_movie *m, const cdvr_image *img, cdvr_error *err);
/* Flushes the encoder, writes the trailer and commits the file under path. A movie with no
 * frame is refused (nothing is written). Always frees m, also on failure (then nothing stands
 * under path). */
cdvr_status cdvr_movie_close(cdvr_movie *m, cdvr_error *err);
/* Drops the movie: the temporary file is removed, nothing stands under path; frees m. NULL is
 * allowed. */
void cdvr_movie_abort(cdvr_movie *m);
/* Frames added so far. */
int64_t cdvr_movie_frames(const cdvr_movie *m);
/* The path given to open (valid until close or abort). */
const char *cdvr_movie_path(const cdvr_movie *m);
/* The codec in use ("h264", "vp9", "ffv1", "gif"). */
const char *cdvr_movie_codec(const cdvr_movie *m);

#endif
