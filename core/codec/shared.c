/* core/codec/shared.c - the shared-blob table (cdvr/codec.h): blobs a variant's chunks share
 * (hvqc's codebooks), by id, reference counted; and the dispatch to the built-in codecs that
 * train one. */
#include "cdvr/codec.h"
#include "cdvr/hvq.h"

#include <pthread.h>
#include <stdlib.h>
#include <string.h>

typedef struct shared_entry {
    uint64_t id;
    uint8_t *blob;
    size_t bytes;
    size_t refs;
    struct shared_entry *next;
} shared_entry;

/* The shared-blob table context: one per process. */
static struct {
    pthread_mutex_t mu;
    shared_entry *head;
} shared_table = {PTHREAD_MUTEX_INITIALIZER, NULL};

uint64_t cdvr_shared_id(const uint8_t *blob, size_t bytes)
{
    uint64_t h = 0xcbf29ce484222325ull;
    for (size_t i = 0; i < bytes; i++)
        h = (h ^ blob[i]) * 0x100000001b3ull;
    return h ? h : 1;
}

static shared_entry *find_locked(uint64_t id)
{
    shared_entry *e = shared_table.head;
    while (e && e->id != id)
        e = e->next;
    return e;
}

cdvr_status cdvr_shared_put(const uint8_t *blob, size_t bytes, uint64_t *id, cdvr_error *err)
{
    uint64_t h = cdvr_shared_id(blob, bytes);
    cdvr_status s = CDVR_OK;
    pthread_mutex_lock(&shared_table.mu);
    shared_entry *e = find_locked(h);
    if (e) {
        e->refs++;
    } else {
        e = calloc(1, sizeof *e);
        uint8_t *copy = e ? malloc(bytes ? bytes : 1) : NULL;
        if (!copy) {
            free(e);
            s = cdvr_error_set(err, CDVR_ERR_NOMEM, "shared blob of %zu bytes: out of memory",
                               bytes);
        } else {
            memcpy(copy, blob, bytes);
            *e = (shared_entry){h, copy, bytes, 1, shared_table.head};
            shared_table.head = e;
        }
    }
    pthread_mutex_unlock(&shared_table.mu);
    if (s == CDVR_OK)
        *id = h;
    return s;
}

void cdvr_shared_drop(uint64_t id)
{
    pthread_mutex_lock(&shared_table.mu);
    shared_entry **at = &shared_table.head;
    while (*at && (*at)->id != id)
        at = &(*at)->next;
    shared_entry *e = *at;
    if (e && --e->refs == 0) {
        *at = e->next;
        free(e->blob);
        free(e);
    }
    pthread_mutex_unlock(&shared_table.mu);
}

cdvr_status cdvr_shared_borrow(uint64_t id, const uint8_t **blob, size_t *bytes,
                               cdvr_error *err)
{
    pthread_mutex_lock(&shared_table.mu);
    shared_entry *e = find_locked(id);
    if (e) {
        e->refs++;
        *blob = e->blob;
        *bytes = e->bytes;
    }
    pthread_mutex_unlock(&shared_table.mu);
    if (!e)
        return cdvr_error_set(err, CDVR_ERR_UNSUPPORTED, "shared blob %016llx is not loaded (the "
                              "store variant that holds it is not open)", (unsigned long long)id);
    return CDVR_OK;
}

/* ---- built-in trainers -------------------------------------------------------------------- */

extern const cdvr_codec cdvr_codec_hvqc;

int cdvr_codec_wants_shared(const cdvr_codec *codec, const cdvr_codec_params *p)
{
    return codec == &cdvr_codec_hvqc && cdvr_hvqc_wants_shared(p);
}

cdvr_status cdvr_codec_train_shared(const cdvr_codec *codec, cdvr_codec_params *p,
                                    const size_t dims[3], const uint8_t *const *frames,
                                    size_t nframes, uint8_t **blob, size_t *bytes,
                                    cdvr_error *err)
{
    if (!cdvr_codec_wants_shared(codec, p))
        return cdvr_error_set(err, CDVR_ERR_ARG, "codec %s: no shared data to train",
                              codec->name);
    return cdvr_hvqc_train_shared(p, dims, frames, nframes, blob, bytes, err);
}
