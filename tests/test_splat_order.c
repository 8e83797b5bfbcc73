/* tests/test_splat_order.c - voxel orders for splatting (cdvr/splat.h): every order is a
 * permutation of the listed voxels for 200 random directions and the axis-aligned, exactly
 * diagonal and zero-component ones on odd dims; the DDA's documented depth bound and dominance
 * guarantee; the two sorts agree and are sorted; filters; perspective; the wrong-order
 * fraction of the DDA against the axis order near 45 degrees. */
#include "check.h"
#include "cdvr/splat.h"

#include <stdint.h>
#include <string.h>

static uint64_t rng_state = 0x2545F4914F6CDD1Dull;

static double uniform(void)
{
    rng_state ^= rng_state << 13;
    rng_state ^= rng_state >> 7;
    rng_state ^= rng_state << 17;
    return (double)(rng_state >> 11) / 9007199254740992.0;
}

static void random_direction(double v[3])
{
    double len;
    do {
        for (int a = 0; a < 3; a++)
            v[a] = 2.0 * uniform() - 1.0;
        len = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    } while (len < 1e-3 || len > 1.0);
}

static cdvr_splat_order *build(const size_t dims[3], const double dir[3], cdvr_splat_how how,
                               const cdvr_splat_filter *filter)
{
    cdvr_splat_view view;
    memset(&view, 0, sizeof view);
    memcpy(view.dir, dir, sizeof view.dir);
    cdvr_splat_order *o = NULL;
    cdvr_error err;
    CHECK_OK(cdvr_splat_order_build(dims, &view, how, filter, &o, &err), err);
    return o;
}

static cdvr_splat_order *build_eye(const size_t dims[3], const double eye[3], cdvr_splat_how how)
{
    cdvr_splat_view view;
    memset(&view, 0, sizeof view);
    view.perspective = 1;
    memcpy(view.eye, eye, sizeof view.eye);
    cdvr_splat_order *o = NULL;
    cdvr_error err;
    CHECK_OK(cdvr_splat_order_build(dims, &view, how, NULL, &o, &err), err);
    return o;
}

static size_t voxels(const size_t dims[3])
{
    return dims[0] * dims[1] * dims[2];
}

/* 1 when o lists each voxel with listed[i] (NULL: all) exactly once. */
static int is_permutation(const cdvr_splat_order *o, const uint8_t *listed)
{
    size_t n = voxels(o->dims), want = 0;
    for (size_t i = 0; i < n; i++)
        want += listed ? listed[i] != 0 : 1;
    if (o->count != want)
        return 0;
    uint8_t *seen = calloc(n, 1);
    int ok = 1;
    for (size_t i = 0; i < o->count && ok; i++) {
        uint32_t v = o->index[i];
        ok = v < n && !seen[v] && (!listed || listed[v]);
        if (ok)
            seen[v] = 1;
    }
    free(seen);
    return ok;
}

static double phi_of(const size_t dims[3], const double v[3], uint32_t lin)
{
    double i = (double)(lin % dims[0]), j = (double)(lin / dims[0] % dims[1]),
           k = (double)(lin / (dims[0] * dims[1]));
    return v[0] * i + v[1] * j + v[2] * k;
}

/* Largest amount by which a voxel drawn later is farther than one drawn earlier
 * (0 for an exact back-to-front order), for unit v. */
static double max_inversion(const cdvr_splat_order *o, const double v[3])
{
    double lowest = HUGE_VAL, worst = 0.0;
    for (size_t i = 0; i < o->count; i++) {
        double phi = phi_of(o->dims, v, o->index[i]);
        if (phi - lowest > worst)
            worst = phi - lowest;
        if (phi < lowest)
            lowest = phi;
    }
    return worst;
}

static void unit(const double d[3], double v[3])
{
    double len = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    for (int a = 0; a < 3; a++)
        v[a] = d[a] / len;
}

/* The DDA bound of splat.h: 2 |v_n| (smallest nonzero |v| component, 1e-9 relative),
 * |v_m| when the smallest is zero, 0 along an axis. */
static double dda_bound(const double v[3])
{
    double m[3] = {fabs(v[0]), fabs(v[1]), fabs(v[2])}, top = fmax(m[0], fmax(m[1], m[2]));
    double smallest = HUGE_VAL;
    int zeros = 0;
    for (int a = 0; a < 3; a++) {
        if (m[a] < 1e-9 * top)
            zeros++;
        else if (m[a] < smallest)
            smallest = m[a];
    }
    if (zeros == 2)
        return 0.0;
    return (zeros == 1 ? 1.0 : 2.0) * smallest;
}

/* Rank of index i along an axis in the DDA's far-to-near traversal. */
static long far_rank(double va, size_t i, size_t n)
{
    return va > 0.0 ? (long)(n - 1 - i) : (long)i;
}

/* Dominance (all pairs): when q is at least as far as p along every axis, q comes first. */
static int dominance_holds(const cdvr_splat_order *o, const double v[3])
{
    size_t n = voxels(o->dims);
    uint32_t *rank = malloc(n * sizeof *rank);
    for (size_t i = 0; i < o->count; i++)
        rank[o->index[i]] = (uint32_t)i;
    int ok = 1;
    for (size_t p = 0; p < n && ok; p++)
        for (size_t q = 0; q < n && ok; q++) {
            if (p == q)
                continue;
            size_t pc[3] = {p % o->dims[0], p / o->dims[0] % o->dims[1], p / (o->dims[0] * o->dims[1])};
            size_t qc[3] = {q % o->dims[0], q / o->dims[0] % o->dims[1], q / (o->dims[0] * o->dims[1])};
            int farther = 1;
            for (int a = 0; a < 3; a++)
                farther &= far_rank(v[a], qc[a], o->dims[a]) <= far_rank(v[a], pc[a], o->dims[a]);
            if (farther && rank[q] > rank[p])
                ok = 0;
        }
    free(rank);
    return ok;
}

static const double special_dirs[][3] = {
    {1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1},
    {1, 1, 1}, {-1, 1, 1}, {1, -1, 1}, {1, 1, -1}, {-1, -1, 1}, {-1, 1, -1}, {1, -1, -1}, {-1, -1, -1},
    {1, 1, 0}, {1, -1, 0}, {0, 1, -1}, {-1, 0, -1}, {2, 1, 0}, {0, -0.3, 1}, {1, 0, 0.999},
    {3, 0, -2}, {1e-12, 1, 0.5}, {1, 1e-12, 1e-12}, {0.5, 0.5, 1}, {1, 2, 2}, {0.7071, 0.7071, 1e-7}};
#define NSPECIAL (sizeof special_dirs / sizeof special_dirs[0])

static void check_direction(const size_t dims[3], const double d[3], int with_sorts, int dominance)
{
    double v[3];
    unit(d, v);
    cdvr_splat_order *dda = build(dims, d, CDVR_SPLAT_DDA, NULL);
    cdvr_splat_order *axis = build(dims, d, CDVR_SPLAT_AXIS, NULL);
    if (!dda || !axis)
        return;
    CHECK(is_permutation(dda, NULL), "dda %zux%zux%zu dir (%g %g %g) not a permutation", dims[0],
          dims[1], dims[2], d[0], d[1], d[2]);
    CHECK(is_permutation(axis, NULL), "axis %zux%zux%zu dir (%g %g %g) not a permutation",
          dims[0], dims[1], dims[2], d[0], d[1], d[2]);
    double inv = max_inversion(dda, v), bound = dda_bound(v);
    CHECK(inv <= bound + 1e-9, "dda %zux%zux%zu dir (%g %g %g): inversion %g above bound %g",
          dims[0], dims[1], dims[2], d[0], d[1], d[2], inv, bound);
    if (dominance)
        CHECK(dominance_holds(dda, v), "dda dir (%g %g %g): dominance violated", d[0], d[1], d[2]);
    if (with_sorts) {
        cdvr_splat_order *s = build(dims, d, CDVR_SPLAT_SORT, NULL);
        cdvr_splat_order *q = build(dims, d, CDVR_SPLAT_QUICKSORT, NULL);
        if (s && q) {
            CHECK(is_permutation(s, NULL), "sort not a permutation");
            CHECK(s->count == q->count && memcmp(s->index, q->index, s->count * 4) == 0,
                  "radix sort and quicksort differ for dir (%g %g %g)", d[0], d[1], d[2]);
            double tol = 1e-6 * (fabs(v[0]) * dims[0] + fabs(v[1]) * dims[1] + fabs(v[2]) * dims[2]);
            CHECK(max_inversion(s, v) <= tol, "sort inversion %g", max_inversion(s, v));
        }
        cdvr_splat_order_free(s);
        cdvr_splat_order_free(q);
    }
    cdvr_splat_order_free(dda);
    cdvr_splat_order_free(axis);
}

static void test_permutations(void)
{
    static const size_t dims_list[][3] = {{1, 1, 1}, {5, 3, 7}, {64, 48, 33}};
    for (size_t di = 0; di < 3; di++) {
        const size_t *dims = dims_list[di];
        int small = voxels(dims) < 1000;
        for (size_t s = 0; s < NSPECIAL; s++)
            check_direction(dims, special_dirs[s], 1, small);
        for (int r = 0; r < 200; r++) {
            double d[3];
            random_direction(d);
            check_direction(dims, d, small || r < 10, small);
        }
    }
}

/* Exactly diagonal and axis views: the DDA order is exact (no inversion at all). */
static void test_exact_views(void)
{
    size_t dims[3] = {9, 6, 11};
    double diag[3] = {-1, 1, 1}, v[3], axisdir[3] = {0, 0, -2}, w[3];
    unit(diag, v);
    unit(axisdir, w);
    cdvr_splat_order *o = build(dims, diag, CDVR_SPLAT_DDA, NULL);
    cdvr_splat_order *a = build(dims, axisdir, CDVR_SPLAT_DDA, NULL);
    if (o && a) {
        CHECK(max_inversion(o, v) < 1e-12, "diagonal dda inversion %g", max_inversion(o, v));
        CHECK(max_inversion(a, w) < 1e-12, "axis dda inversion %g", max_inversion(a, w));
        /* first voxel: the far corner (x = 0, y = 5, z = 10) */
        CHECK(o->index[0] == 0 + 9 * (5 + 6 * 10), "diagonal starts at the far corner: %u",
              o->index[0]);
        CHECK(o->index[o->count - 1] == 8, "diagonal ends at the near corner: %u",
              o->index[o->count - 1]);
    }
    cdvr_splat_order_free(o);
    cdvr_splat_order_free(a);
}

/* The seed's Fig. 5: 2D, dx/dy = 0.5 (view (0.5, 1) in the plane, z one voxel). */
static void test_fig5(void)
{
    size_t dims[3] = {4, 4, 1};
    double d[3] = {1.0, 0.5, 0.0}; /* far end at x = 3, y = 3 */
    cdvr_splat_order *o = build(dims, d, CDVR_SPLAT_DDA, NULL);
    if (!o)
        return;
    /* major x (|1|), unit |0.5|: T_P(x') = 2 x'; t = 2 x' + y'. Steps: t0: (3,3); t1: (3,2);
     * t2: (3,1) (2,3); t3: (3,0) (2,2); t4: (2,1) (1,3); ... planes in order of entry. */
    static const uint32_t want[16][2] = {{3, 3}, {3, 2}, {3, 1}, {2, 3}, {3, 0}, {2, 2},
                                         {2, 1}, {1, 3}, {2, 0}, {1, 2}, {1, 1}, {0, 3},
                                         {1, 0}, {0, 2}, {0, 1}, {0, 0}};
    int same = o->count == 16;
    for (int i = 0; i < 16 && same; i++)
        same = o->index[i] == want[i][0] + 4 * want[i][1];
    CHECK(same, "Fig. 5 order");
    cdvr_splat_order_free(o);
}

static void test_filter(void)
{
    size_t dims[3] = {13, 7, 9}, n = voxels(dims);
    uint8_t *vox = malloc(n), keep[256], *listed = malloc(n);
    for (size_t i = 0; i < n; i++) {
        vox[i] = (uint8_t)((i * 37u) % 251u);
        listed[i] = vox[i] > 100;
    }
    for (int v = 0; v < 256; v++)
        keep[v] = v > 100;
    cdvr_splat_filter filter = {vox, keep};
    double d[3] = {0.3, -0.8, 0.45};
    for (int h = 0; h < 4; h++) {
        cdvr_splat_order *all = build(dims, d, (cdvr_splat_how)h, NULL);
        cdvr_splat_order *some = build(dims, d, (cdvr_splat_how)h, &filter);
        if (!all || !some)
            continue;
        CHECK(is_permutation(some, listed), "%s filtered order lists the kept voxels",
              cdvr_splat_how_name((cdvr_splat_how)h));
        size_t j = 0; /* the filtered order is the full order restricted */
        for (size_t i = 0; i < all->count && j < some->count; i++)
            if (listed[all->index[i]])
                j += all->index[i] == some->index[j];
        CHECK(j == some->count, "%s filter keeps the relative order",
              cdvr_splat_how_name((cdvr_splat_how)h));
        cdvr_splat_order_free(all);
        cdvr_splat_order_free(some);
    }
    for (int v = 0; v < 256; v++)
        keep[v] = 0;
    cdvr_splat_order *none = build(dims, d, CDVR_SPLAT_DDA, &filter);
    CHECK(none && none->count == 0, "a filter keeping nothing lists nothing");
    cdvr_splat_order_free(none);
    free(vox);
    free(listed);
}

static double dist2(const size_t dims[3], const double e[3], uint32_t lin)
{
    double c[3] = {(double)(lin % dims[0]), (double)(lin / dims[0] % dims[1]),
                   (double)(lin / (dims[0] * dims[1]))};
    return (c[0] - e[0]) * (c[0] - e[0]) + (c[1] - e[1]) * (c[1] - e[1]) +
           (c[2] - e[2]) * (c[2] - e[2]);
}

/* Perspective: permutations for eyes outside, inside and on a voxel; the sort is by distance;
 * inside each octant of the DDA, a voxel farther from the eye along every axis comes first. */
static void test_perspective(void)
{
    size_t dims[3] = {5, 3, 7};
    static const double eyes[][3] = {{-10, -4, 30}, {2.5, 1.2, 3.7}, {2, 1, 3}, {40, 1, -9},
                                     {0, 0, 0}, {4, 2, 6}, {2, -50, 3}};
    for (size_t e = 0; e < sizeof eyes / sizeof eyes[0]; e++) {
        for (int h = 0; h < 4; h++) {
            cdvr_splat_order *o = build_eye(dims, eyes[e], (cdvr_splat_how)h);
            if (!o)
                continue;
            CHECK(is_permutation(o, NULL), "perspective %s eye %zu not a permutation",
                  cdvr_splat_how_name((cdvr_splat_how)h), e);
            if (h == CDVR_SPLAT_SORT) {
                int sorted = 1;
                for (size_t i = 1; i < o->count; i++)
                    sorted &= dist2(dims, eyes[e], o->index[i]) <=
                              dist2(dims, eyes[e], o->index[i - 1]) + 1e-9;
                CHECK(sorted, "perspective sort by decreasing distance (eye %zu)", e);
            }
            if (h == CDVR_SPLAT_DDA) {
                size_t n = voxels(dims);
                uint32_t *rank = malloc(n * sizeof *rank);
                for (size_t i = 0; i < o->count; i++)
                    rank[o->index[i]] = (uint32_t)i;
                int ok = 1;
                for (size_t p = 0; p < n; p++)
                    for (size_t q = 0; q < n; q++) {
                        double pc[3] = {(double)(p % 5), (double)(p / 5 % 3), (double)(p / 15)};
                        double qc[3] = {(double)(q % 5), (double)(q / 5 % 3), (double)(q / 15)};
                        int same_octant = 1, farther = 1;
                        for (int a = 0; a < 3; a++) {
                            same_octant &= (pc[a] >= eyes[e][a]) == (qc[a] >= eyes[e][a]);
                            farther &= fabs(qc[a] - eyes[e][a]) >= fabs(pc[a] - eyes[e][a]);
                        }
                        if (p != q && same_octant && farther && rank[q] > rank[p])
                            ok = 0;
                    }
                CHECK(ok, "perspective dda dominance inside octants (eye %zu)", e);
                free(rank);
            }
            cdvr_splat_order_free(o);
        }
    }
}

static double wrong_fraction(const size_t dims[3], const double d[3], cdvr_splat_how how,
                             double *max_inversion)
{
    cdvr_splat_order *o = build(dims, d, how, NULL);
    cdvr_splat_quality q;
    cdvr_error err;
    double f = -1.0;
    if (o) {
        CHECK_OK(cdvr_splat_order_quality(o, d, CDVR_SPLAT_DEFAULT_RADIUS, (uint64_t)1 << 22, &q,
                                          &err),
                 err);
        CHECK(q.pairs > 1000000, "quality found %llu pairs", (unsigned long long)q.pairs);
        f = q.fraction;
        if (max_inversion)
            *max_inversion = q.max_inversion;
    }
    cdvr_splat_order_free(o);
    return f;
}

/* Near 45 degrees the axis order draws many overlapping pairs wrong, the DDA very few; the
 * exact sort none. */
static void test_quality(void)
{
    size_t dims[3] = {64, 48, 33};
    const double pi = 3.14159265358979323846;
    for (int deg = 40; deg <= 50; deg += 2) {
        for (int el = 0; el <= 20; el += 20) {
            double az = deg * pi / 180.0, e = el * pi / 180.0;
            double d[3] = {cos(e) * cos(az), cos(e) * sin(az), sin(e)};
            double ia, id;
            double fa = wrong_fraction(dims, d, CDVR_SPLAT_AXIS, &ia);
            double fd = wrong_fraction(dims, d, CDVR_SPLAT_DDA, &id);
            printf("azimuth %d elevation %d: wrong pairs axis %.5f (worst %.2f voxels) "
                   "dda %.5f (worst %.2f)\n", deg, el, fa, ia, fd, id);
            /* measured (64x48x33, default radius 2.0): axis 0.023-0.029 (worst 2.4-3.5
             * voxels), dda 0.0004-0.0033 (worst 0.33-0.67); ratio 8.2 (40 degrees, elevation
             * 20) to 59 (46, 0) */
            CHECK(fa > 0.01, "axis order near 45 degrees is often wrong: %g", fa);
            CHECK(fd < fa / 6.0,
                  "dda wrong fraction %g far below axis %g (az %d el %d)", fd, fa, deg, el);
            CHECK(id <= dda_bound(d) / sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) + 1e-9 &&
                      ia > 2.0 * id,
                  "worst inversion dda %g (bound %g), axis %g", id, dda_bound(d), ia);
        }
    }
    double d[3] = {0.6, -0.5, 0.62};
    size_t small[3] = {20, 17, 15};
    CHECK(wrong_fraction(small, d, CDVR_SPLAT_SORT, NULL) == 0.0,
          "the exact sort has no wrong pair");
    cdvr_splat_order *o = build(small, d, CDVR_SPLAT_DDA, NULL);
    cdvr_splat_quality q;
    cdvr_error err;
    if (o) {
        CHECK_OK(cdvr_splat_order_quality(o, d, 1.0, 1000, &q, &err), err);
        CHECK(q.sampled && q.pairs > 0, "small budget samples");
        CHECK(cdvr_splat_order_quality(o, d, -1.0, 0, &q, &err) == CDVR_ERR_ARG,
              "negative radius rejected");
        double zero[3] = {0, 0, 0};
        CHECK(cdvr_splat_order_quality(o, zero, 1.0, 0, &q, &err) == CDVR_ERR_ARG,
              "zero direction rejected");
    }
    cdvr_splat_order_free(o);
}

static void test_errors(void)
{
    size_t dims[3] = {4, 4, 4}, zero[3] = {4, 0, 4}, huge[3] = {65536, 65536, 2};
    cdvr_splat_view view;
    memset(&view, 0, sizeof view);
    cdvr_splat_order *o = NULL;
    cdvr_error err;
    CHECK(cdvr_splat_order_build(dims, &view, CDVR_SPLAT_DDA, NULL, &o, &err) == CDVR_ERR_ARG &&
              strstr(err.msg, "direction"),
          "zero direction: %s", err.msg);
    view.dir[0] = NAN;
    CHECK(cdvr_splat_order_build(dims, &view, CDVR_SPLAT_DDA, NULL, &o, &err) == CDVR_ERR_ARG,
          "NaN direction");
    view.dir[0] = 1.0;
    CHECK(cdvr_splat_order_build(zero, &view, CDVR_SPLAT_DDA, NULL, &o, &err) == CDVR_ERR_ARG,
          "zero dim");
    CHECK(cdvr_splat_order_build(huge, &view, CDVR_SPLAT_DDA, NULL, &o, &err) == CDVR_ERR_ARG &&
              strstr(err.msg, "2^32"),
          "too many voxels: %s", err.msg);
    CHECK(cdvr_splat_order_build(dims, &view, (cdvr_splat_how)9, NULL, &o, &err) == CDVR_ERR_ARG,
          "unknown how");
    view.perspective = 1;
    view.eye[1] = INFINITY;
    CHECK(cdvr_splat_order_build(dims, &view, CDVR_SPLAT_DDA, NULL, &o, &err) == CDVR_ERR_ARG,
          "infinite eye");
    CHECK(o == NULL, "no order on error");
    cdvr_splat_how how;
    CHECK(cdvr_splat_how_parse("quicksort", &how) && how == CDVR_SPLAT_QUICKSORT, "parse");
    CHECK(!cdvr_splat_how_parse("bubble", &how), "parse rejects");
    CHECK(strcmp(cdvr_splat_how_name(CDVR_SPLAT_AXIS), "axis") == 0, "name");
}

int main(void)
{
    test_permutations();
    test_exact_views();
    test_fig5();
    test_filter();
    test_perspective();
    test_quality();
    test_errors();
    return check_finish();
}
