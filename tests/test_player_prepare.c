/* tests/test_player_prepare.c - what the player's pipeline prepares off the device thread
 * (core/player/player.c): frames decoded on the host into decode slots and skip grids made
 * from the store's range tables. Every frame of a run equals, pixel for pixel, the render of
 * that decoded timestep by itself: on the cpu device (host decode in the pipeline), and on
 * the cl device with the recorded ranges (grids uploaded), without them (the store rewritten
 * as an older one: the device's min/max kernel), with the host decode forced and with the
 * decode kernel forced; serial and pipelined; a PVTC variant, raw, and a bricked store; and
 * with brick skipping on a lossless variant (skipped bricks filled, the device's grid). */
#include "check.h"
#include "player_frames.h"

#include "cdvr/device.h"
#include "cdvr/player.h"
#include "cdvr/pvtc.h"
#include "store/store_format.h"

#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define W 48
#define H 40

static cdvr_volume *make_series(void)
{
    size_t dims[3] = {37, 30, 26};
    cdvr_volume *v = NULL;
    cdvr_error err;
    if (cdvr_volume_create(dims, 7, CDVR_TYPE_U8, &v, &err) != CDVR_OK)
        return NULL;
    uint8_t *p = v->data;
    for (size_t t = 0; t < 7; t++)
        for (size_t z = 0; z < 26; z++)
            for (size_t y = 0; y < 30; y++)
                for (size_t x = 0; x < 37; x++) {
                    double dx = (double)x - 12 - 2.0 * t, dy = (double)y - 15, dz = (double)z - 13;
                    double r = dx * dx + dy * dy + dz * dz;
                    *p++ = (uint8_t)(r < 90 ? 230 - 2 * r : (x + y) % 7 == 0 ? 40 : 0);
                }
    return v;
}

static void make_tf(cdvr_tf *tf)
{
    cdvr_tf_point pts[] = {{0, 0, 0, 0, 0}, {60, 0.2, 0.3, 0.9, 0}, {120, 0.9, 0.5, 0.2, 0.3},
                           {255, 1, 1, 1, 0.9}};
    cdvr_error err;
    CHECK_OK(cdvr_tf_init(tf, pts, 4, 0, &err), err);
}

static cdvr_camera make_camera(void)
{
    cdvr_camera cam = {.eye = {95, -60, 70}, .center = {18, 14.5, 12.5}, .up = {0, 0, 1},
                       .fov = 30, .width = W, .height = H};
    return cam;
}

/* Plays every timestep of variant v and compares each frame with its reference. With
 * brick_skip, some brick must have been skipped. */
static void play_and_compare(const cdvr_store *st, size_t v, cdvr_device_kind device,
                             int pipelined, int brick_skip, const char *what)
{
    const cdvr_store_info *in = cdvr_store_get_info(st);
    size_t n = in->timesteps, px = (size_t)W * H * 4;
    capture cap = {calloc(n * px, sizeof(float)), n, px};
    float *ref = malloc(px * sizeof(float));
    cdvr_tf tf;
    make_tf(&tf);
    cdvr_player_opts o = {.store = st, .device = device, .tf = &tf, .camera = make_camera(),
                          .variant = (int)v, .pipelined = pipelined, .ring = 2,
                          .empty_skip = 1, .brick_skip = brick_skip, .frame_fn = keep_frame,
                          .frame_ud = &cap};
    cdvr_player *p = NULL;
    cdvr_error err;
    cdvr_status s = cdvr_player_create(&o, &p, &err);
    CHECK_OK(s, err);
    if (s == CDVR_OK) {
        CHECK_OK(cdvr_player_run(p, 0, n, &err), err);
        size_t nrows = 0;
        const cdvr_frame_row *rows = cdvr_player_rows(p, &nrows);
        size_t skipped = 0;
        for (size_t i = 0; i < nrows; i++) {
            CHECK(rows[i].status == CDVR_OK, "%s: frame %zu: %s", what, i, rows[i].error);
            skipped += rows[i].bricks_skipped;
        }
        CHECK(!brick_skip || skipped > 0, "%s: no brick skipped", what);
        cdvr_camera cam = make_camera();
        for (size_t t = 0; t < n; t++)
            if (render_alone(st, v, t, device, &tf, &cam, ref))
                CHECK(memcmp(ref, cap.pixels + t * px, px * sizeof(float)) == 0,
                      "%s: timestep %zu differs from its render alone", what, t + 1);
    }
    cdvr_player_free(p);
    free(cap.pixels);
    free(ref);
}

/* Rewrites the metadata of a store as a writer without range tables did. */
static void drop_tables(const char *path)
{
    cdvr_store *st = NULL;
    cdvr_error err;
    CHECK_OK(cdvr_store_open(path, &st, &err), err);
    if (!st)
        return;
    for (size_t c = 0; c < st->nchunks_total; c++) {
        cdvr_chunk_info *ci = &st->chunks[c];
        ci->ranges_shift = 0;
        ci->ranges_stage2 = 0;
        ci->ranges_crc32c = 0;
        ci->ranges_offset = ci->ranges_stored_bytes = 0;
    }
    uint64_t meta = cdvr_store_meta_bytes(st->info.nvariants, st->nchunks_total);
    uint8_t *buf = malloc((size_t)meta + 4);
    cdvr_store_serialize_meta(st, buf);
    cdvr_store_close(st);
    FILE *f = fopen(path, "r+b");
    CHECK(f && fwrite(buf, 1, (size_t)meta + 4, f) == meta + 4, "rewrite metadata");
    if (f)
        fclose(f);
    free(buf);
}

int main(void)
{
    cdvr_volume *vol = make_series();
    char path[] = "/tmp/cdvr_test_player_prepare_XXXXXX";
    int fd = mkstemp(path);
    if (fd >= 0)
        close(fd);
    cdvr_variant_spec vs[2] = {{.codec = cdvr_codec_find("pvtc"), .lzo_min_saving = -1},
                               {.codec = cdvr_codec_find("raw"), .stage2 = CDVR_STAGE2_LZO,
                                .lzo_min_saving = 0}};
    cdvr_pvtc_params pp = {4, 3, CDVR_PACK_TIME};
    cdvr_pvtc_params_to_blob(&pp, CDVR_ENCODER_BBOX, &vs[0].params);
    vs[1].codec->params_default(&vs[1].params);
    int have_cl = 0;
#if CDVR_HAVE_OPENCL
    cdvr_cl *probe = NULL;
    cdvr_error perr;
    have_cl = cdvr_cl_open(&probe, &perr) == CDVR_OK;
    cdvr_cl_close(probe);
#endif
    static const size_t grids[3][3] = {{1, 1, 1}, {2, 1, 2}, {4, 1, 1}};
    for (int g = 0; g < 3 && vol; g++) {
        cdvr_encode_opts o = {.variants = vs, .nvariants = 2, .qhi = 255};
        memcpy(o.bricks, grids[g], sizeof o.bricks);
        cdvr_error err;
        CHECK_OK(cdvr_store_encode(vol, &o, path, &err), err);
        for (int tables = 1; tables >= 0; tables--) {
            if (!tables)
                drop_tables(path);
            cdvr_store *st = NULL;
            CHECK_OK(cdvr_store_open(path, &st, &err), err);
            if (!st)
                continue;
            char what[96];
            /* grid 2: brick skipping on the raw variant (lossless: no pixel changes; the
               sphere leaves the last column of bricks transparent in early timesteps) */
            int brick_skip = g == 2;
            for (size_t v = brick_skip ? 1 : 0; v < 2; v++)
                for (int pipelined = 0; pipelined < 2; pipelined++) {
                    snprintf(what, sizeof what, "bricks %d, tables %d, variant %zu, %s%s", g,
                             tables, v + 1, pipelined ? "pipelined" : "serial",
                             brick_skip ? ", brick skipping" : "");
                    if (tables)
                        play_and_compare(st, v, CDVR_DEVICE_CPU, pipelined, brick_skip, what);
                    static const char *const paths[] = {"host", "kernel"};
                    for (int k = 0; have_cl && k < 2; k++) {
                        setenv("CDVR_CL_DECODE", paths[k], 1);
                        char what_cl[128];
                        snprintf(what_cl, sizeof what_cl, "cl, %s decode, %s", paths[k], what);
                        play_and_compare(st, v, CDVR_DEVICE_CL, pipelined, brick_skip,
                                         what_cl);
                        unsetenv("CDVR_CL_DECODE");
                    }
                }
            cdvr_store_close(st);
        }
    }
    unlink(path);
    cdvr_volume_free(vol);
    if (!have_cl)
        printf("no OpenCL device: the cpu device only\n");
    return check_finish();
}
