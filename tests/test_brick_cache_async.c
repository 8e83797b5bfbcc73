/* tests/test_brick_cache_async.c - the brick cache's asynchronous residency
 * (cdvr_brick_cache_set_async, cdvr/brick_cache.h) on a bricked store with three levels:
 *   - the first frame renders every brick at the pinned coarsest level (bricks coarser than
 *     chosen, none missing): its dense frame is exactly the synchronous cache's frame with
 *     every brick at the coarsest level;
 *   - once the worker has finished, the same view is exactly the synchronous frame (a uniform
 *     level 1 here);
 *   - right after a jump to a near camera at lod_error 0 every brick is coarser than chosen and
 *     the frame is exactly the level-1 frame (the finest resident coarser level: no hole);
 *     after the worker it is exactly the assembled volume (cdvr_store_decode);
 *   - a new timestep pins its own coarsest level; named beforehand (cdvr_brick_cache_set_next)
 *     it is decoded during the frame before and its first frame is complete; the cache stays
 *     within its budget; a budget
 *     below the coarsest level is refused; switching async off returns to synchronous frames;
 *   - cdvr_brick_cache_dense assembles again exactly the bricks whose entry changed (none for
 *     a camera that moved without changing levels; all 12 at new levels or a new timestep;
 *     only the changed ones when a budget coarsens some), the frame always exact. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cdvr/brick_cache.h"
#include "cdvr/camera.h"
#include "cdvr/store.h"
#include "cdvr/volume.h"
#include "check.h"

static const size_t DIMS[3] = {29, 23, 17};
#define VOXELS (29 * 23 * 17)

static cdvr_store *make_store(const char *path)
{
    cdvr_volume *vol;
    cdvr_error err;
    CHECK_OK(cdvr_volume_create(DIMS, 2, CDVR_TYPE_U8, &vol, &err), err);
    uint32_t r = 4242;
    for (size_t i = 0; i < 2 * (size_t)VOXELS; i++) {
        r = r * 1103515245u + 12345u;
        size_t x = i % DIMS[0], y = i / DIMS[0] % DIMS[1], z = i / DIMS[0] / DIMS[1];
        ((uint8_t *)vol->data)[i] = (uint8_t)((x * 9 + y * 4 + z * 3 + (r >> 24) % 32) & 0xff);
    }
    cdvr_variant_spec spec = {.codec = cdvr_codec_find("raw")};
    spec.codec->params_default(&spec.params);
    cdvr_encode_opts o = {.variants = &spec, .nvariants = 1, .bricks = {3, 2, 2}, .levels = 3,
                          .threads = 1, .qhi = 255};
    CHECK_OK(cdvr_store_encode(vol, &o, path, &err), err);
    cdvr_volume_free(vol);
    cdvr_store *st = NULL;
    CHECK_OK(cdvr_store_open(path, &st, &err), err);
    return st;
}

/* ~300 voxels away: a pixel spans ~5 voxels, so lod_error 0.6 puts every brick at level 1 and
 * 1e6 at level 2 (checked on the synchronous cache). */
static cdvr_camera far_camera(void)
{
    cdvr_camera cam = {.eye = {14 + 300, 11, 8}, .center = {14, 11, 8}, .up = {0, 0, 1},
                       .fov = 30, .width = 40, .height = 32};
    return cam;
}

static cdvr_camera near_camera(void)
{
    cdvr_camera cam = far_camera();
    cam.eye[0] = 45;
    return cam;
}

/* Frame t of c at cam and lod; its dense frame copied into out and its stats into s. */
static void frame(cdvr_brick_cache *c, size_t t, const cdvr_camera *cam, double lod,
                  uint8_t *out, cdvr_brick_cache_stats *s)
{
    const uint8_t *payload, *dense;
    size_t bytes;
    cdvr_error err;
    memset(out, 0, VOXELS);
    CHECK_OK(cdvr_brick_cache_frame(c, t, cam, NULL, lod, &payload, &bytes, &err), err);
    CHECK_OK(cdvr_brick_cache_dense(c, &dense, &err), err);
    if (dense)
        memcpy(out, dense, VOXELS);
    cdvr_brick_cache_get_stats(c, s);
}

static uint8_t sync_level1[VOXELS], sync_level2[VOXELS], got[VOXELS];

static void synchronous_references(cdvr_store *st)
{
    cdvr_brick_cache *c;
    cdvr_brick_cache_stats s;
    cdvr_error err;
    cdvr_camera far = far_camera();
    CHECK_OK(cdvr_brick_cache_create(st, 0, 1u << 24, &c, &err), err);
    frame(c, 0, &far, 0.6, sync_level1, &s);
    CHECK(s.bricks_at[1] == 12, "lod_error 0.6 from afar: every brick at level 1 (%zu)",
          s.bricks_at[1]);
    CHECK(s.coarser == 0 && s.pending == 0, "synchronous: nothing coarser or pending");
    frame(c, 0, &far, 1e6, sync_level2, &s);
    CHECK(s.bricks_at[2] == 12, "lod_error 1e6: every brick at level 2 (%zu)", s.bricks_at[2]);
    CHECK(memcmp(sync_level1, sync_level2, VOXELS) != 0, "the levels differ");
    cdvr_brick_cache_free(c);
}

static void jump_and_refine(cdvr_store *st)
{
    cdvr_brick_cache *c;
    cdvr_brick_cache_stats s;
    cdvr_error err;
    cdvr_camera far = far_camera(), near = near_camera();
    uint64_t budget = 1u << 24;
    CHECK_OK(cdvr_brick_cache_create(st, 0, budget, &c, &err), err);
    CHECK_OK(cdvr_brick_cache_set_async(c, 1, &err), err);

    frame(c, 0, &far, 0.6, got, &s);
    CHECK(s.bricks_at[2] == 12 && s.coarser == 12, "first frame: all at the pinned coarsest "
          "level (%zu at level 2, %zu coarser)", s.bricks_at[2], s.coarser);
    CHECK(s.pending > 0 && s.arrived == 0, "level-1 bricks queued (%zu)", s.pending);
    CHECK(memcmp(got, sync_level2, VOXELS) == 0, "first frame = the synchronous coarsest frame");

    cdvr_brick_cache_wait(c);
    CHECK(cdvr_brick_cache_pending(c) > 0, "decoded bricks wait for the next frame");
    frame(c, 0, &far, 0.6, got, &s);
    CHECK(s.bricks_at[1] == 12 && s.coarser == 0 && s.pending == 0 && s.arrived > 0,
          "after the worker: level 1 everywhere (%zu), nothing coarser (%zu) or pending (%zu)",
          s.bricks_at[1], s.coarser, s.pending);
    CHECK(memcmp(got, sync_level1, VOXELS) == 0, "after the worker = the synchronous frame");

    frame(c, 0, &near, 0.0, got, &s); /* the jump: level 0 chosen, level 1 resident */
    CHECK(s.bricks_at[1] == 12 && s.coarser == 12 && s.pending == 12,
          "right after the jump: %zu at level 1, %zu coarser, %zu pending", s.bricks_at[1],
          s.coarser, s.pending);
    CHECK(memcmp(got, sync_level1, VOXELS) == 0, "right after the jump: the finest resident "
          "coarser level (level 1), no hole");
    cdvr_brick_cache_wait(c);
    frame(c, 0, &near, 0.0, got, &s);
    cdvr_volume *ref;
    CHECK_OK(cdvr_store_decode(st, 0, 0, &ref, &err), err);
    CHECK(s.bricks_at[0] == 12 && s.coarser == 0, "refined: level 0 everywhere");
    CHECK(memcmp(got, ref->data, VOXELS) == 0, "refined = the assembled volume, bit for bit");
    CHECK(s.cache_bytes <= budget, "within the budget");
    cdvr_volume_free(ref);

    frame(c, 1, &near, 0.0, got, &s); /* a new timestep: its coarsest level, then refined */
    CHECK(s.bricks_at[2] == 12 && s.coarser == 12, "t 2: at its coarsest level first");
    cdvr_brick_cache_wait(c);
    frame(c, 1, &near, 0.0, got, &s);
    CHECK_OK(cdvr_store_decode(st, 0, 1, &ref, &err), err);
    CHECK(memcmp(got, ref->data, VOXELS) == 0 && s.coarser == 0, "t 2 refined exactly");
    cdvr_volume_free(ref);

    /* playback: with the next timestep named, the worker decodes it during this frame, and
     * the next frame finds every brick resident at its chosen level (nothing decoded in it) */
    cdvr_brick_cache *play;
    CHECK_OK(cdvr_brick_cache_create(st, 0, budget, &play, &err), err);
    CHECK_OK(cdvr_brick_cache_set_async(play, 1, &err), err);
    cdvr_brick_cache_set_next(play, 1);
    frame(play, 0, &near, 0.0, got, &s);
    CHECK(s.coarser == 12 && s.pending > 24, "t 1 at its coarsest level; t 1's level 0 and t 2's "
          "coarsest and level 0 queued (%zu pending)", s.pending);
    cdvr_brick_cache_wait(play);
    frame(play, 1, &near, 0.0, got, &s);
    CHECK_OK(cdvr_store_decode(st, 0, 1, &ref, &err), err);
    CHECK(s.coarser == 0 && s.decoded == 0 && s.bricks_at[0] == 12 &&
          memcmp(got, ref->data, VOXELS) == 0, "the prefetched timestep: all resident, exact "
          "(%zu coarser, %zu decoded in the frame)", s.coarser, s.decoded);
    cdvr_volume_free(ref);
    cdvr_brick_cache_free(play);

    CHECK_OK(cdvr_brick_cache_set_async(c, 0, &err), err);
    frame(c, 0, &far, 0.6, got, &s);
    CHECK(memcmp(got, sync_level1, VOXELS) == 0 && s.coarser == 0 && s.pending == 0,
          "async off: synchronous frames again");
    cdvr_brick_cache_free(c);
}

/* A budget that holds the coarsest level and little more: frames stay within it, coarser
 * bricks fill in, and one below the coarsest level is refused. */
static void tight_budget(cdvr_store *st)
{
    cdvr_brick_cache *c;
    cdvr_brick_cache_stats s;
    cdvr_error err;
    cdvr_camera near = near_camera();
    uint64_t budget = 4000;
    CHECK_OK(cdvr_brick_cache_create(st, 0, budget, &c, &err), err);
    CHECK_OK(cdvr_brick_cache_set_async(c, 1, &err), err);
    for (int i = 0; i < 4; i++) {
        cdvr_brick_cache_set_next(c, (size_t)(i + 1) % 2);
        frame(c, (size_t)i % 2, &near, 0.0, got, &s);
        CHECK(s.cache_bytes <= budget && s.resident_bytes <= budget,
              "frame %d within the budget: %llu", i, (unsigned long long)s.cache_bytes);
        CHECK(s.bricks_at[0] + s.bricks_at[1] + s.bricks_at[2] == 12, "every brick has a level");
        /* what the worker decodes waits outside the budget until the next frame: the queue
         * (this frame's missing bricks and the next timestep's) fits the budget too */
        CHECK(s.requested_bytes > 0 && s.requested_bytes <= budget,
              "frame %d: %llu bytes queued", i, (unsigned long long)s.requested_bytes);
        cdvr_brick_cache_wait(c);
    }
    cdvr_brick_cache_free(c);
    CHECK_OK(cdvr_brick_cache_create(st, 0, 100, &c, &err), err);
    cdvr_status bad = cdvr_brick_cache_set_async(c, 1, &err);
    CHECK(bad == CDVR_ERR_NOMEM && strstr(err.msg, "coarsest level"), "a budget below the "
          "coarsest level: %s", err.msg);
    cdvr_brick_cache_free(c);
}

static void dense_reuse(cdvr_store *st)
{
    cdvr_brick_cache *c;
    cdvr_brick_cache_stats s;
    cdvr_error err;
    cdvr_camera far = far_camera(), turned = far_camera(), near = near_camera();
    turned.eye[1] += 3; /* another view, the same levels */
    CHECK_OK(cdvr_brick_cache_create(st, 0, 1u << 24, &c, &err), err);
    frame(c, 0, &far, 0.6, got, &s);
    CHECK(s.dense_bricks == 12 && memcmp(got, sync_level1, VOXELS) == 0, "first dense frame");
    frame(c, 0, &turned, 0.6, got, &s);
    CHECK(s.dense_bricks == 0 && s.bricks_at[1] == 12 && memcmp(got, sync_level1, VOXELS) == 0,
          "a turned camera at the same levels: %zu bricks assembled, the same voxels",
          s.dense_bricks);
    frame(c, 0, &near, 0.0, got, &s);
    cdvr_volume *ref;
    CHECK_OK(cdvr_store_decode(st, 0, 0, &ref, &err), err);
    CHECK(s.dense_bricks == 12 && memcmp(got, ref->data, VOXELS) == 0, "new levels: all again");
    cdvr_volume_free(ref);
    frame(c, 1, &near, 0.0, got, &s);
    CHECK_OK(cdvr_store_decode(st, 0, 1, &ref, &err), err);
    CHECK(s.dense_bricks == 12 && memcmp(got, ref->data, VOXELS) == 0, "a new timestep: all");
    cdvr_volume_free(ref);
    frame(c, 0, &far, 0.6, got, &s);
    CHECK(s.dense_bricks == 12 && memcmp(got, sync_level1, VOXELS) == 0, "back: all again");
    cdvr_brick_cache_free(c);
    /* a budget that holds level 0 for only some bricks: the near frame mixes levels, and
     * after a level-1 frame only the bricks whose level changed are assembled again */
    uint8_t mixed[VOXELS];
    cdvr_brick_cache *fresh;
    CHECK_OK(cdvr_brick_cache_create(st, 0, 9000, &c, &err), err);
    CHECK_OK(cdvr_brick_cache_create(st, 0, 9000, &fresh, &err), err);
    frame(c, 0, &far, 0.6, got, &s);
    frame(c, 0, &near, 0.0, got, &s);
    size_t changed = s.dense_bricks, at0 = s.bricks_at[0], at2 = s.bricks_at[2];
    frame(fresh, 0, &near, 0.0, mixed, &s);
    CHECK(at0 > 0 && at0 < 12 && changed == at0 + at2, "mixed levels: %zu at level 0, %zu at "
          "level 2, %zu assembled", at0, at2, changed);
    CHECK(memcmp(got, mixed, VOXELS) == 0, "incremental frame = a whole assembly");
    cdvr_brick_cache_free(fresh);
    cdvr_brick_cache_free(c);
}

int main(void)
{
    char path[256];
    snprintf(path, sizeof path, "/tmp/cdvr_test_brick_cache_async_%ld.cdv", (long)getpid());
    cdvr_store *st = make_store(path);
    if (st) {
        synchronous_references(st);
        jump_and_refine(st);
        tight_budget(st);
        dense_reuse(st);
        cdvr_store_close(st);
    }
    unlink(path);
    return check_finish();
}
