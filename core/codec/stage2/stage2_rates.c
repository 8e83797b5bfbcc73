/* core/codec/stage2/stage2_rates.c - this machine's single-thread unpack rates of the stage-2
 * codecs, measured once on a fixed calibration payload and remembered (cdvr/cache.h); the
 * encoder's AUTO model (store.h) reads them, so its choices depend on a chunk's packed sizes
 * and these rates only, and two encodes on one machine write the same store. */
#include "stage2.h"

#include <lz4.h>
#include <lzo/lzoconf.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <zstd.h>

#include "cdvr/cache.h"
#include "cdvr/timing.h"

#define CAL_SIDE 128                   /* calibration payload: a 128^3 u8 volume, 2 MiB */
#define CAL_SEGMENT (1u << 20)         /* as CDVR_STAGE2_SEGMENT */
#define CAL_RUNS 7                     /* unpacks per codec; the median counts */
#define RATES_FORMAT "lzo %.1f lz4 %.1f zstd %.1f"
#define RATES_SCAN "lzo %lf lz4 %lf zstd %lf"

/* A volume like the simulation and scan data stores hold: smooth ramps of about one step per
 * voxel (amplitude 90 about 45, clipped to 0 over a seventh of the volume), and a step of -1
 * or +1 at 60% of the voxels (a fixed xorshift). Its unpack rates come near those of the
 * viscous-fingers series' timesteps (EPYC Zen 5, one thread, one run: LZO 581 MB/s against
 * 427-489, LZ4 3229 against 2283-2660, zstd 1146 against 1066-1126), where smoother or
 * sparser payloads unpack 1.5-6x faster and would make stage 2 look cheaper than it is. */
static void calibration_payload(uint8_t *v)
{
    uint32_t rng = 2463534242u;
    const double f = 0.025;
    for (int z = 0; z < CAL_SIDE; z++)
        for (int y = 0; y < CAL_SIDE; y++)
            for (int x = 0; x < CAL_SIDE; x++) {
                rng ^= rng << 13;
                rng ^= rng >> 17;
                rng ^= rng << 5;
                double smooth = 45 + 90 * (sin(x * f + 0.5) * sin(y * f * 1.3 + 1) *
                                               cos(z * f * 0.7) +
                                           0.5 * sin((x + y) * f * 2.1));
                unsigned r = rng % 10;
                double val = smooth + (r < 3 ? -1 : r < 6 ? 1 : 0);
                v[((size_t)z * CAL_SIDE + y) * CAL_SIDE + x] =
                    (uint8_t)(val < 0 ? 0 : val > 255 ? 255 : val);
            }
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* The median single-thread unpack of codec over the payload, MB/s of payload. */
static cdvr_status measure_codec(unsigned codec, const uint8_t *payload, size_t n, uint8_t *packed,
                                 size_t packed_cap, uint8_t *out, double *mbps, cdvr_error *err)
{
    size_t packed_n = 0;
    double ms[CAL_RUNS];
    cdvr_status s = cdvr_s2_pack(codec, payload, n, CAL_SEGMENT, packed, packed_cap, &packed_n,
                                 err);
    for (int run = 0; run < CAL_RUNS && s == CDVR_OK; run++) {
        double t0 = cdvr_now_ms();
        s = cdvr_s2_unpack(codec, packed, packed_n, out, n, 1, err);
        ms[run] = cdvr_now_ms() - t0;
    }
    if (s != CDVR_OK)
        return s;
    if (memcmp(out, payload, n) != 0)
        return cdvr_error_set(err, CDVR_ERR_IO, "stage 2 %s does not give the calibration "
                              "payload back (internal error)", cdvr_s2_name(codec));
    qsort(ms, CAL_RUNS, sizeof *ms, cmp_double);
    double median = ms[CAL_RUNS / 2] > 1e-6 ? ms[CAL_RUNS / 2] : 1e-6;
    *mbps = (double)n / (median * 1e3);
    return CDVR_OK;
}

static cdvr_status measure_rates(cdvr_s2_rates *r, cdvr_error *err)
{
    size_t n = (size_t)CAL_SIDE * CAL_SIDE * CAL_SIDE, cap = 0;
    for (unsigned c = CDVR_S2_LZO; c < CDVR_S2_CODECS; c++) {
        size_t b = cdvr_s2_bound(c, n, CAL_SEGMENT);
        cap = b > cap ? b : cap;
    }
    uint8_t *payload = malloc(n), *out = malloc(n), *packed = malloc(cap);
    cdvr_status s = payload && out && packed && cap
                        ? CDVR_OK
                        : cdvr_error_set(err, CDVR_ERR_NOMEM, "stage 2: no memory to measure "
                                         "the unpack rates");
    if (s == CDVR_OK)
        calibration_payload(payload);
    for (unsigned c = CDVR_S2_LZO; c < CDVR_S2_CODECS && s == CDVR_OK; c++)
        s = measure_codec(c, payload, n, packed, cap, out, &r->mbps[c], err);
    free(payload);
    free(out);
    free(packed);
    return s;
}

/* The first "model name" line of /proc/cpuinfo, or "" (the key then covers the rest). */
static void cpu_model(char *model, size_t n)
{
    char line[256];
    FILE *f = fopen("/proc/cpuinfo", "r");
    model[0] = '\0';
    while (f && fgets(line, sizeof line, f))
        if (!strncmp(line, "model name", 10)) {
            snprintf(model, n, "%s", line);
            break;
        }
    if (f)
        fclose(f);
}

int cdvr_s2_rates_parse(const unsigned char *content, size_t n, cdvr_s2_rates *out)
{
    char text[128];
    double *m = out->mbps;
    memset(out, 0, sizeof *out);
    if (n >= sizeof text)
        return 0;
    memcpy(text, content, n);
    text[n] = '\0';
    int ok = sscanf(text, RATES_SCAN, &m[CDVR_S2_LZO], &m[CDVR_S2_LZ4], &m[CDVR_S2_ZSTD]) == 3;
    for (unsigned c = CDVR_S2_LZO; ok && c < CDVR_S2_CODECS; c++)
        ok = m[c] > 0 && m[c] < 1e9; /* NaN fails too */
    if (!ok)
        memset(out, 0, sizeof *out);
    return ok;
}

cdvr_status cdvr_s2_unpack_rates(cdvr_s2_rates *out, cdvr_error *err)
{
    char model[256], key[33], path[512], text[128];
    cpu_model(model, sizeof model);
    const char *parts[] = {"stage2 unpack rates 1", CDVR_VERSION, model, lzo_version_string(),
                           LZ4_versionString(), ZSTD_versionString()};
    cdvr_cache_key(parts, sizeof parts / sizeof *parts, key);
    int cached = cdvr_cache_path(key, "s2rates", path, sizeof path);
    size_t size = 0;
    unsigned char *content = cached ? cdvr_cache_load(path, key, &size) : NULL;
    out->from_cache = content && cdvr_s2_rates_parse(content, size, out);
    free(content);
    if (out->from_cache)
        return CDVR_OK;
    cdvr_status s = measure_rates(out, err);
    if (s != CDVR_OK)
        return s;
    int len = snprintf(text, sizeof text, RATES_FORMAT, out->mbps[CDVR_S2_LZO],
                       out->mbps[CDVR_S2_LZ4], out->mbps[CDVR_S2_ZSTD]);
    if (len <= 0 || (size_t)len >= sizeof text)
        return cdvr_error_set(err, CDVR_ERR_IO, "stage 2: unpack rates out of range");
    /* the rates as the cache holds them, so this encode chooses as the later ones will */
    if (!cdvr_s2_rates_parse((const unsigned char *)text, (size_t)len, out))
        return cdvr_error_set(err, CDVR_ERR_IO, "stage 2: unpack rates out of range");
    if (cached)
        cdvr_cache_store(path, key, (const unsigned char *)text, (size_t)len);
    return CDVR_OK;
}
