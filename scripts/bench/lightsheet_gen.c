/* scripts/bench/lightsheet_gen.c - a deterministic light-sheet-like test volume for the hvq
 * benchmark (scripts/bench/hvq.lua, issue 27): sparse smooth neurites (tubes) and cell bodies
 * (blobs) over a dark, slightly noisy background, like the cleared mouse-brain volumes of
 * seed 004 (Table 1). Written as NRRD (u8, raw), readable by cdvr.load.
 *
 *   cc -O2 -std=c11 lightsheet_gen.c -lm -o lightsheet_gen
 *   lightsheet_gen OUT.nrrd [SIDE=256] [SEED=1] [T=0]
 *
 * The volume (side N, x fastest):
 *   background  10 + Gaussian noise of sigma 1 (Box-Muller on splitmix64), rounded;
 *   tubes       N*N/768 neurites (85 at N = 256): each a random smooth path (a walk whose
 *               direction turns by at most ~0.15 rad per step of 0.5 voxels, reflected at the
 *               walls), 2N steps long, radius s in 0.9..2.0 voxels, peak 60..180 above the
 *               background, profile A*exp(-d^2 / (2 s^2)) (d: distance to the path);
 *   blobs       N*N/1024 cell bodies (64 at N = 256): ellipsoids with semi-axes 3..7 voxels,
 *               peak 100..220 above the background, profile A*exp(-q^2 * 1.5) with q the
 *               ellipsoidal radius (q = 1 on the semi-axes), each one a small bright nucleus;
 *   where objects overlap the larger contribution wins (no sums past 255 in crossings).
 * About 5% of the voxels lie more than 10 above the background (printed on stderr).
 * T > 0: timestep T of a series: the same objects, every tube and blob displaced by
 * (T * 0.25) voxels along a per-object direction, and fresh noise per timestep, so a series
 * has the statistics of one volume and codebooks trained on one timestep fit the others. */
#define _DEFAULT_SOURCE /* M_PI */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct rng {
    uint64_t s;
} rng;

static uint64_t rng_next(rng *r)
{
    uint64_t z = (r->s += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

static double rng_unit(rng *r) { return (double)(rng_next(r) >> 11) * (1.0 / 9007199254740992.0); }
static double rng_range(rng *r, double a, double b) { return a + (b - a) * rng_unit(r); }

static double rng_gauss(rng *r)
{
    double u = rng_unit(r), v = rng_unit(r);
    return sqrt(-2.0 * log(u + 1e-300)) * cos(2 * M_PI * v);
}

typedef struct vol {
    int n;
    float *fg; /* foreground above the background, max of the objects */
} vol;

static void put_max(vol *v, int x, int y, int z, float a)
{
    if (x < 0 || y < 0 || z < 0 || x >= v->n || y >= v->n || z >= v->n)
        return;
    float *p = &v->fg[(size_t)x + (size_t)v->n * ((size_t)y + (size_t)v->n * (size_t)z)];
    if (a > *p)
        *p = a;
}

/* A Gaussian ball of sigma s and peak a centred at c. */
static void splat(vol *v, const double c[3], double s, double a)
{
    int r = (int)ceil(3 * s);
    int cx = (int)floor(c[0]), cy = (int)floor(c[1]), cz = (int)floor(c[2]);
    for (int z = cz - r; z <= cz + r + 1; z++)
        for (int y = cy - r; y <= cy + r + 1; y++)
            for (int x = cx - r; x <= cx + r + 1; x++) {
                double dx = x - c[0], dy = y - c[1], dz = z - c[2];
                double d2 = dx * dx + dy * dy + dz * dz;
                put_max(v, x, y, z, (float)(a * exp(-d2 / (2 * s * s))));
            }
}

static void unit(double d[3])
{
    double l = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    for (int i = 0; i < 3; i++)
        d[i] /= l > 0 ? l : 1;
}

static void random_dir(rng *r, double d[3])
{
    for (int i = 0; i < 3; i++)
        d[i] = rng_gauss(r);
    unit(d);
}

static void tube(vol *v, rng *r, double shift)
{
    int n = v->n;
    double p[3], d[3], m[3];
    for (int i = 0; i < 3; i++)
        p[i] = rng_range(r, 0, n);
    random_dir(r, d);
    random_dir(r, m);
    double s = rng_range(r, 0.9, 2.0), a = rng_range(r, 60, 180);
    for (int i = 0; i < 3; i++)
        p[i] += shift * m[i];
    for (int step = 0; step < 2 * n; step++) {
        double t[3];
        random_dir(r, t);
        for (int i = 0; i < 3; i++)
            d[i] += 0.15 * t[i];
        unit(d);
        for (int i = 0; i < 3; i++) {
            p[i] += 0.5 * d[i];
            if (p[i] < 0 || p[i] > n - 1) { /* reflect at the walls */
                d[i] = -d[i];
                p[i] = p[i] < 0 ? -p[i] : 2.0 * (n - 1) - p[i];
            }
        }
        splat(v, p, s, a);
    }
}

static void blob(vol *v, rng *r, double shift)
{
    double c[3], ax[3], m[3];
    for (int i = 0; i < 3; i++) {
        c[i] = rng_range(r, 8, v->n - 8);
        ax[i] = rng_range(r, 3, 7);
    }
    random_dir(r, m);
    for (int i = 0; i < 3; i++)
        c[i] += shift * m[i];
    double a = rng_range(r, 100, 220);
    int rad = 9;
    for (int z = (int)c[2] - rad; z <= (int)c[2] + rad; z++)
        for (int y = (int)c[1] - rad; y <= (int)c[1] + rad; y++)
            for (int x = (int)c[0] - rad; x <= (int)c[0] + rad; x++) {
                double qx = (x - c[0]) / ax[0], qy = (y - c[1]) / ax[1], qz = (z - c[2]) / ax[2];
                double q2 = qx * qx + qy * qy + qz * qz;
                put_max(v, x, y, z, (float)(a * exp(-1.5 * q2)));
            }
}

int main(int argc, char **argv)
{
    if (argc < 2) {
        fprintf(stderr, "usage: %s OUT.nrrd [SIDE=256] [SEED=1] [T=0]\n", argv[0]);
        return 2;
    }
    int n = argc > 2 ? atoi(argv[2]) : 256;
    uint64_t seed = argc > 3 ? strtoull(argv[3], NULL, 10) : 1;
    int t = argc > 4 ? atoi(argv[4]) : 0;
    if (n < 16 || n > 1024 || t < 0) {
        fprintf(stderr, "lightsheet_gen: SIDE must be 16..1024, T >= 0\n");
        return 2;
    }
    size_t nv = (size_t)n * n * n;
    vol v = {n, calloc(nv, sizeof(float))};
    uint8_t *out = malloc(nv);
    if (!v.fg || !out) {
        fprintf(stderr, "lightsheet_gen: out of memory\n");
        return 1;
    }
    rng objects = {seed * 0x2545F4914F6CDD1Dull + 1};
    double shift = 0.25 * t;
    for (int i = 0; i < n * n / 768; i++)
        tube(&v, &objects, shift);
    for (int i = 0; i < n * n / 1024; i++)
        blob(&v, &objects, shift);
    rng noise = {seed * 0x9E3779B97F4A7C15ull + 7919u * (uint64_t)t + 3};
    size_t fg = 0;
    for (size_t i = 0; i < nv; i++) {
        double val = 10 + rng_gauss(&noise) + v.fg[i];
        val = floor(val + 0.5);
        out[i] = (uint8_t)(val < 0 ? 0 : val > 255 ? 255 : val);
        fg += v.fg[i] > 10;
    }
    FILE *f = fopen(argv[1], "wb");
    if (!f) {
        perror(argv[1]);
        return 1;
    }
    fprintf(f, "NRRD0004\ntype: uint8\ndimension: 3\nsizes: %d %d %d\nencoding: raw\n\n", n, n, n);
    int ok = fwrite(out, 1, nv, f) == nv;
    ok = (fclose(f) == 0) && ok;
    fprintf(stderr, "lightsheet_gen: %s %d^3 seed %llu t %d: %.2f%% foreground (> 10 above "
            "the background)\n", argv[1], n, (unsigned long long)seed, t, 100.0 * fg / nv);
    free(v.fg);
    free(out);
    return ok ? 0 : 1;
}
