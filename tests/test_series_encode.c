/* tests/test_series_encode.c - an out-of-core encode from C (cdvr/series.h, core/io/series_view.c):
 * a series of NRRD files (f32, one of them 4D), opened lazily with cdvr_series_open from a
 * pattern (cdvr_series_pattern), encoded through cdvr_series_encode_source and
 * cdvr_store_encode_source, gives the same store, byte for byte, as the series loaded into
 * memory (cdvr_volume_load_series), quantised over its range and encoded with cdvr_store_encode
 * (two variants, pvtc and raw, bricked 2 x 1 x 1, so frames are read in encode order across
 * files). So does a quantized view over a given window against cdvr_volume_quantize over it,
 * and a u8 series against the u8 volume. The view's reads and scan agree with the volume in
 * memory (timestep ranges, window, clipped counts, code range). The source holds one file at a
 * time (cdvr/series.h). The pattern's refusals name the pattern or the missing file. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cdvr/format.h"
#include "cdvr/series.h"
#include "cdvr/store.h"
#include "check.h"

#define X 13
#define Y 9
#define Z 6

static char dir[] = "/tmp/cdvr_test_series_encode_XXXXXX";

static void write_nrrd(const char *path, const char *type, size_t timesteps, int seed)
{
    FILE *f = fopen(path, "wb");
    CHECK(f != NULL, "open %s", path);
    if (!f)
        return;
    if (timesteps > 1)
        fprintf(f, "NRRD0004\ntype: %s\ndimension: 4\nsizes: %d %d %d %zu\nendian: little\n"
                   "encoding: raw\n\n", type, X, Y, Z, timesteps);
    else
        fprintf(f, "NRRD0004\ntype: %s\ndimension: 3\nsizes: %d %d %d\nendian: little\n"
                   "encoding: raw\n\n", type, X, Y, Z);
    for (size_t t = 0; t < timesteps; t++)
        for (int i = 0; i < X * Y * Z; i++) {
            double v = 40 * sin(0.07 * i + seed + 0.9 * (double)t) + 0.3 * seed * i / (X * Y);
            if (strcmp(type, "float") == 0) {
                float fv = (float)v;
                fwrite(&fv, 4, 1, f);
            } else {
                unsigned char c = (unsigned char)(128 + v);
                fwrite(&c, 1, 1, f);
            }
        }
    fclose(f);
}

static int same_file(const char *a, const char *b)
{
    FILE *fa = fopen(a, "rb"), *fb = fopen(b, "rb");
    int same = fa && fb;
    while (same) {
        int ca = fgetc(fa), cb = fgetc(fb);
        same = ca == cb;
        if (ca == EOF || cb == EOF)
            break;
    }
    if (fa)
        fclose(fa);
    if (fb)
        fclose(fb);
    return same;
}

static cdvr_variant_spec variants[2];

static cdvr_encode_opts encode_opts(void)
{
    variants[0] = (cdvr_variant_spec){.codec = cdvr_codec_find("pvtc"), .lzo_min_saving = -1};
    variants[0].codec->params_default(&variants[0].params);
    variants[0].stage2 = CDVR_STAGE2_LZO;
    variants[1] = (cdvr_variant_spec){.codec = cdvr_codec_find("raw"), .lzo_min_saving = -1};
    variants[1].codec->params_default(&variants[1].params);
    cdvr_encode_opts o = {.variants = variants, .nvariants = 2, .bricks = {2, 1, 1},
                          .threads = 2};
    return o;
}

/* Encodes the series of names both ways (through the view, and loaded + quantised over the
 * view's window) and checks the stores are the same file. */
static void encode_both(char **names, size_t n, const cdvr_series_view *view_in, const char *tag)
{
    cdvr_error err;
    cdvr_series *s = NULL;
    CHECK_OK(cdvr_series_open((const char *const *)names, n, NULL, &s, &err), err);
    if (!s)
        return;
    cdvr_series_view view = *view_in;
    view.series = s;
    char lazy[600], mem[600];
    snprintf(lazy, sizeof lazy, "%s/%s_lazy.cdv", dir, tag);
    snprintf(mem, sizeof mem, "%s/%s_mem.cdv", dir, tag);

    cdvr_encode_opts o = encode_opts();
    cdvr_series_source state;
    cdvr_encode_source src;
    CHECK_OK(cdvr_series_encode_source(&view, &state, &src, &o, NULL, NULL, &err), err);
    CHECK(src.timesteps == cdvr_series_get_info(s)->timesteps && src.dims[0] == X &&
              src.direction[0] == 1 && src.direction[4] == 1, "%s: source shape", tag);
    CHECK_OK(cdvr_store_encode_source(&src, &o, lazy, &err), err);

    cdvr_volume *all = NULL, *u8 = NULL;
    CHECK_OK(cdvr_volume_load_series((const char *const *)names, n, NULL, &all, &err), err);
    double w[2];
    cdvr_volume_window(all, w);
    double lo = view.quantized ? view.lo : w[0], hi = view.quantized ? view.hi : w[1];
    CHECK(o.qlo == lo && o.qhi == hi && o.source_type == all->type, "%s: opts window %g %g",
          tag, o.qlo, o.qhi);
    if (all->type == CDVR_TYPE_U8 && !view.quantized)
        u8 = all, all = NULL;
    else
        CHECK_OK(cdvr_volume_quantize(all, lo, hi, &u8, NULL, &err), err);
    cdvr_encode_opts m = encode_opts();
    m.qlo = lo, m.qhi = hi, m.source_type = o.source_type;
    CHECK_OK(cdvr_store_encode(u8, &m, mem, &err), err);
    CHECK(same_file(lazy, mem), "%s: the out-of-core store equals the in-memory one", tag);

    /* the view's reads of timestep ranges, as the volume in memory */
    cdvr_volume *part = NULL;
    CHECK_OK(cdvr_series_view_read(&view, 2, 3, &part, NULL, NULL, &err), err);
    const cdvr_volume *ref = view.quantized || !all ? u8 : all;
    size_t bytes = 3 * cdvr_volume_frame_bytes(ref);
    CHECK(part && part->timesteps == 3 && part->type == ref->type &&
              memcmp(part->data, cdvr_volume_frame(ref, 2), bytes) == 0 &&
              part->window[0] == lo && part->window[1] == hi,
          "%s: view_read of timesteps 3..5", tag);
    cdvr_volume_free(part);
    if (view.quantized) {
        cdvr_quantize_report r = {0}, want = {0};
        double clo, chi, rlo, rhi;
        cdvr_volume *again = NULL;
        CHECK_OK(cdvr_volume_quantize(all, lo, hi, &again, &want, &err), err);
        cdvr_volume_free(again);
        CHECK_OK(cdvr_series_view_scan(&view, &r, &clo, &chi, &err), err);
        cdvr_volume_range(u8, &rlo, &rhi);
        CHECK(r.clipped_low == want.clipped_low && r.clipped_high == want.clipped_high &&
                  r.clipped_low + r.clipped_high > 0 && clo == rlo && chi == rhi,
              "%s: scan: clipped %zu+%zu (want %zu+%zu), codes %g..%g", tag, r.clipped_low,
              r.clipped_high, want.clipped_low, want.clipped_high, clo, chi);
    } else {
        CHECK(cdvr_series_view_scan(&view, NULL, NULL, NULL, &err) == CDVR_ERR_ARG,
              "scan of an unquantized view");
    }
    cdvr_volume_free(all);
    cdvr_volume_free(u8);
    cdvr_series_close(s);
}

static void test_pattern(void)
{
    char pattern[600], **names = NULL;
    size_t n = 0;
    cdvr_error err;
    snprintf(pattern, sizeof pattern, "%s/f%%02d.nrrd", dir);
    CHECK_OK(cdvr_series_pattern(pattern, 3, 0, &names, &n, &err), err);
    CHECK(n == 5 && strstr(names[0], "/f03.nrrd") && strstr(names[4], "/f07.nrrd"),
          "while the files exist: %zu", n);
    cdvr_format_free_paths(names, n);
    CHECK_OK(cdvr_series_pattern(pattern, 99, 2, &names, &n, &err), err); /* need not exist */
    CHECK(n == 2 && strstr(names[1], "/f100.nrrd"), "count 2: %s", n ? names[1] : "");
    cdvr_format_free_paths(names, n);
    CHECK(cdvr_series_pattern(pattern, 40, 0, &names, &n, &err) == CDVR_ERR_IO &&
              strstr(err.msg, "f40.nrrd: no such file") && !names, "%s", err.msg);
    CHECK(cdvr_series_pattern("a%d%d", 0, 1, &names, &n, &err) == CDVR_ERR_ARG &&
              strstr(err.msg, "exactly one integer conversion"), "%s", err.msg);
    CHECK(cdvr_series_pattern("plain", 0, 1, &names, &n, &err) == CDVR_ERR_ARG &&
              strstr(err.msg, "'plain': no integer conversion"), "%s", err.msg);
    CHECK_OK(cdvr_series_pattern("100%%_%u.raw", 7, 1, &names, &n, &err), err);
    CHECK(n == 1 && strcmp(names[0], "100%_7.raw") == 0, "%%%%: %s", n ? names[0] : "");
    cdvr_format_free_paths(names, n);
}

int main(void)
{
    if (!mkdtemp(dir)) {
        perror("mkdtemp");
        return 1;
    }
    char path[600], **names = NULL;
    size_t n = 0;
    for (int i = 3; i <= 7; i++) {
        snprintf(path, sizeof path, "%s/f%02d.nrrd", dir, i);
        write_nrrd(path, "float", i == 5 ? 2 : 1, i);
        snprintf(path, sizeof path, "%s/u%02d.nrrd", dir, i);
        write_nrrd(path, "uchar", 1, i);
    }
    test_pattern();
    cdvr_error err;
    snprintf(path, sizeof path, "%s/f%%02d.nrrd", dir);
    CHECK_OK(cdvr_series_pattern(path, 3, 5, &names, &n, &err), err);
    encode_both(names, n, &(cdvr_series_view){NULL, 0, 0, 0}, "range");
    encode_both(names, n, &(cdvr_series_view){NULL, 1, -20, 25}, "window");
    cdvr_format_free_paths(names, n);
    snprintf(path, sizeof path, "%s/u%%02d.nrrd", dir);
    CHECK_OK(cdvr_series_pattern(path, 3, 0, &names, &n, &err), err);
    encode_both(names, n, &(cdvr_series_view){NULL, 0, 0, 0}, "u8");
    cdvr_format_free_paths(names, n);

    snprintf(path, sizeof path, "rm -rf '%s'", dir);
    if (system(path) != 0)
        fprintf(stderr, "could not remove %s\n", dir);
    return check_finish();
}
