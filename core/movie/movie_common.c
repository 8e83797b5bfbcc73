/* core/movie/movie_common.c - the parts of cdvr/movie.h that need no FFmpeg: the defaults and
 * the containers' table (the extension a path must end in). */
#include <stddef.h>
#include <string.h>
#include <strings.h>

#include "cdvr/movie.h"
#include "movie_table.h"

const cdvr_movie_container cdvr_movie_containers[] = {
    {".mp4", "mp4", "h264", {"h264", "vp9", NULL}},
    {".webm", "webm", "vp9", {"vp9", NULL}},
    {".mkv", "matroska", "ffv1", {"ffv1", "h264", "vp9", NULL}},
    {".gif", "gif", "gif", {"gif", NULL}},
    {NULL, NULL, NULL, {NULL}},
};

cdvr_movie_opts cdvr_movie_defaults(void)
{
    cdvr_movie_opts o = {25.0, NULL, -1, NULL, 0, 0, 1};
    return o;
}

const cdvr_movie_container *cdvr_movie_container_of(const char *path)
{
    size_t n = strlen(path);
    for (const cdvr_movie_container *c = cdvr_movie_containers; c->ext; c++) {
        size_t e = strlen(c->ext);
        if (n > e && strcasecmp(path + n - e, c->ext) == 0)
            return c;
    }
    return NULL;
}

int cdvr_movie_is_movie_path(const char *path)
{
    return path && cdvr_movie_container_of(path) != NULL;
}
