/* core/movie/movie_table.h - the movie containers (private to core/movie). */
#ifndef CDVR_MOVIE_TABLE_H
#define CDVR_MOVIE_TABLE_H

typedef struct cdvr_movie_container {
    const char *ext;         /* ".mp4" */
    const char *format;      /* libavformat's muxer name */
    const char *codec;       /* the default codec */
    const char *codecs[4];   /* the codecs it takes, NULL-terminated */
} cdvr_movie_container;

/* Terminated by an entry with ext NULL. */
extern const cdvr_movie_container cdvr_movie_containers[];
/* The container path's extension names (any case), or NULL. */
const cdvr_movie_container *cdvr_movie_container_of(const char *path);

#endif
