/* core/movie/movie_off.c - cdvr/movie.h in a build without FFmpeg: every open fails clearly. */
#include "cdvr/movie.h"

int cdvr_movie_available(void) { return 0; }

cdvr_status cdvr_movie_open(const char *path, const cdvr_movie_opts *opts, cdvr_movie **out,
                            cdvr_error *err)
{
    (void)opts;
    *out = NULL;
    return cdvr_error_set(err, CDVR_ERR_UNSUPPORTED,
                          "%s: this cdvr was built without FFmpeg (libavformat, libavcodec, libswscale, "
                          "libavutil: install them, e.g. scripts/setup.sh, and rebuild) and writes no movies",
                          path);
}

cdvr_status cdvr_movie_add_rgba8(cdvr_movie *m, const uint8_t *rgba, int width, int height, cdvr_error *err)
{
    (void)m, (void)rgba, (void)width, (void)height;
    return cdvr_error_set(err, CDVR_ERR_UNSUPPORTED, "movie: built without FFmpeg");
}

cdvr_status cdvr_movie_add_image(cdvr_movie *m, const cdvr_image *img, cdvr_error *err)
{
    (void)m, (void)img;
    return cdvr_error_set(err, CDVR_ERR_UNSUPPORTED, "movie: built without FFmpeg");
}

cdvr_status cdvr_movie_close(cdvr_movie *m, cdvr_error *err)
{
    (void)m;
    return cdvr_error_set(err, CDVR_ERR_UNSUPPORTED, "movie: built without FFmpeg");
}

void cdvr_movie_abort(cdvr_movie *m) { (void)m; }
int64_t cdvr_movie_frames(const cdvr_movie *m) { (void)m; return 0; }
const char *cdvr_movie_path(const cdvr_movie *m) { (void)m; return ""; }
const char *cdvr_movie_codec(const cdvr_movie *m) { (void)m; return ""; }
