/* core/codec/hvq/hvq_psh.c - perfect spatial hashes (Lefebvre & Hoppe 2006) for the hvq codec:
 * construction with offsets assigned in order of decreasing collision count, bounded retries
 * with larger tables, and the lookup the decoders share. The schedule and the layout are
 * documented in cdvr/hvq.h. */
#include "codec/hvq/hvq_internal.h"

#include <stdlib.h>
#include <string.h>

static uint32_t gcd_u32(uint32_t a, uint32_t b)
{
    while (b) {
        uint32_t t = a % b;
        a = b;
        b = t;
    }
    return a;
}

/* Smallest s >= 1 with s^3 >= v. */
static uint32_t cube_side(uint64_t v)
{
    uint32_t s = 1;
    while ((uint64_t)s * s * s < v)
        s++;
    return s;
}

void hvq_psh_sizes(size_t n, unsigned extent, int attempt, uint32_t *m, uint32_t *r)
{
    uint32_t mm = cube_side(n) + (uint32_t)(attempt / 2), rr;
    if (attempt >= HVQ_PSH_ATTEMPTS - 2) {
        rr = (extent + mm - 1) / mm; /* m*r >= extent: (h0, h1) one-to-one */
    } else {
        uint64_t target = ((uint64_t)n * (uint64_t)(15 + 5 * (attempt % 2)) + 59) / 60;
        rr = cube_side(target);
    }
    if (rr < 1)
        rr = 1;
    while (gcd_u32(mm, rr) != 1)
        rr++;
    *m = mm;
    *r = rr;
}

uint64_t hvq_psh_data_bytes(uint32_t m, uint32_t r, unsigned slot_bytes)
{
    uint64_t m3 = (uint64_t)m * m * m, r3 = (uint64_t)r * r * r;
    return r3 * 3u * hvq_offset_width(m) + m3 * slot_bytes;
}

uint64_t hvq_psh_bound(size_t n, unsigned extent, unsigned slot_bytes)
{
    uint64_t most = 0;
    for (int a = 0; n && a < HVQ_PSH_ATTEMPTS; a++) {
        uint32_t m, r;
        hvq_psh_sizes(n, extent, a, &m, &r);
        uint64_t b = hvq_psh_data_bytes(m, r, slot_bytes);
        most = b > most ? b : most;
    }
    return most;
}

static unsigned read_offset(const uint8_t *p, unsigned w)
{
    return w == 1 ? p[0] : (unsigned)hvq_rd16(p);
}

uint64_t hvq_psh_slot(const uint8_t *data, uint32_t m, uint32_t r, unsigned kx, unsigned ky,
                      unsigned kz)
{
    unsigned w = hvq_offset_width(m);
    uint64_t e = kx % r + (uint64_t)r * (ky % r + (uint64_t)r * (kz % r));
    const uint8_t *o = data + e * 3u * w;
    uint64_t sx = (kx % m + read_offset(o, w)) % m, sy = (ky % m + read_offset(o + w, w)) % m,
             sz = (kz % m + read_offset(o + 2 * w, w)) % m;
    return sx + m * (sy + (uint64_t)m * sz);
}

const uint8_t *hvq_psh_find(const uint8_t *data, uint32_t m, uint32_t r, unsigned slot_bytes,
                            unsigned kx, unsigned ky, unsigned kz)
{
    if (m == 0)
        return NULL;
    uint64_t r3 = (uint64_t)r * r * r;
    const uint8_t *slot = data + r3 * 3u * hvq_offset_width(m) +
                          hvq_psh_slot(data, m, r, kx, ky, kz) * slot_bytes;
    return (slot[0] == kx && slot[1] == ky && slot[2] == kz) ? slot + 3 : NULL;
}

void hvq_psh_map_open(hvq_psh_map *h, const uint8_t *data, uint32_t m, uint32_t r)
{
    h->m = m;
    h->r = r;
    h->w = hvq_offset_width(m);
    h->offsets = data;
    h->slots = m ? data + (uint64_t)r * r * r * 3u * h->w : data;
    uint16_t kr = 0, km = 0; /* k % r, k % m, counted up without a division */
    for (unsigned k = 0; m && k < 256; k++) {
        h->mod_r[k] = kr;
        h->mod_m[k] = km;
        kr = kr + 1u == r ? 0 : (uint16_t)(kr + 1);
        km = km + 1u == m ? 0 : (uint16_t)(km + 1);
    }
}

/* ---- construction ----------------------------------------------------------------------- */

typedef struct psh_build {
    const uint8_t *keys;
    size_t n;
    uint32_t m, r;
    uint64_t m3, r3;
    uint16_t (*home)[3];   /* n: h0 of each key */
    uint32_t *by_entry;    /* n: keys grouped by offset entry (input order inside one) */
    uint32_t *entry_start; /* r3 + 1 */
    uint32_t *order;       /* entries holding keys, in placement order */
    size_t nentries;
    uint32_t *next_free;   /* m3 + 1: union-find, smallest free slot >= i (m3: none) */
    uint8_t *used;         /* m3: slot taken */
    uint32_t *scratch;     /* largest group */
} psh_build;

static void psh_build_free(psh_build *b)
{
    free(b->home);
    free(b->by_entry);
    free(b->entry_start);
    free(b->order);
    free(b->next_free);
    free(b->used);
    free(b->scratch);
}

static uint32_t find_free(uint32_t *next, uint32_t i)
{
    uint32_t root = i;
    while (next[root] != root)
        root = next[root];
    while (next[i] != root) { /* path compression */
        uint32_t up = next[i];
        next[i] = root;
        i = up;
    }
    return root;
}

static int cmp_u32(const void *a, const void *b)
{
    uint32_t x = *(const uint32_t *)a, y = *(const uint32_t *)b;
    return x < y ? -1 : x > y;
}

/* Groups the keys by offset entry and orders the entries by decreasing key count (ties: the
 * lower entry first). 0: out of memory. */
static int group_keys(psh_build *b)
{
    size_t n = b->n, maxc = 0;
    uint32_t m = b->m, r = b->r;
    b->home = malloc(n * sizeof *b->home);
    b->by_entry = malloc(n * sizeof *b->by_entry);
    b->entry_start = calloc(b->r3 + 1, sizeof *b->entry_start);
    b->order = malloc(b->r3 * sizeof *b->order);
    uint32_t *entry_of = malloc(n * sizeof *entry_of), *cursor = malloc(b->r3 * sizeof *cursor);
    int ok = b->home && b->by_entry && b->entry_start && b->order && entry_of && cursor;
    for (size_t i = 0; ok && i < n; i++) {
        const uint8_t *k = b->keys + 3 * i;
        entry_of[i] = k[0] % r + r * (k[1] % r + r * (k[2] % r));
        for (int a = 0; a < 3; a++)
            b->home[i][a] = (uint16_t)(k[a] % m);
        b->entry_start[entry_of[i] + 1]++;
    }
    for (uint64_t e = 0; ok && e < b->r3; e++) {
        uint32_t c = b->entry_start[e + 1];
        maxc = c > maxc ? c : maxc;
        b->entry_start[e + 1] += b->entry_start[e];
        cursor[e] = b->entry_start[e];
    }
    for (size_t i = 0; ok && i < n; i++)
        b->by_entry[cursor[entry_of[i]]++] = (uint32_t)i;
    uint32_t *pos = ok ? calloc(maxc + 1, sizeof *pos) : NULL;
    b->scratch = ok ? malloc((maxc + 1) * sizeof *b->scratch) : NULL;
    ok = ok && pos && b->scratch;
    for (uint64_t e = 0; ok && e < b->r3; e++)
        pos[b->entry_start[e + 1] - b->entry_start[e]]++;
    uint32_t total = 0;
    for (size_t c = maxc; ok && c >= 1; c--) {
        uint32_t here = pos[c];
        pos[c] = total;
        total += here;
    }
    for (uint64_t e = 0; ok && e < b->r3; e++) {
        uint32_t c = b->entry_start[e + 1] - b->entry_start[e];
        if (c)
            b->order[pos[c]++] = (uint32_t)e;
    }
    b->nentries = total;
    free(pos);
    free(entry_of);
    free(cursor);
    return ok;
}

/* 1 if two keys of the group share h0 (no offset can separate them). */
static int group_has_twins(psh_build *b, const uint32_t *keys, uint32_t count)
{
    uint32_t m = b->m;
    for (uint32_t i = 0; i < count; i++) {
        const uint16_t *h = b->home[keys[i]];
        b->scratch[i] = h[0] + m * (h[1] + m * (uint32_t)h[2]);
    }
    qsort(b->scratch, count, sizeof *b->scratch, cmp_u32);
    for (uint32_t i = 1; i < count; i++)
        if (b->scratch[i] == b->scratch[i - 1])
            return 1;
    return 0;
}

/* Slot of key i under offset o (components of h and o are below m). */
static uint32_t slot_with(const psh_build *b, uint32_t i, const uint32_t o[3])
{
    uint32_t m = b->m, c[3];
    const uint16_t *h = b->home[i];
    for (int a = 0; a < 3; a++) {
        c[a] = h[a] + o[a];
        c[a] -= c[a] >= m ? m : 0;
    }
    return c[0] + m * (c[1] + m * c[2]);
}

/* Tries offset o = f - h0(first key): 1 and marks the group's slots used if all are free. */
static int try_offset(psh_build *b, const uint32_t *keys, uint32_t count, uint32_t f,
                      uint32_t o[3])
{
    uint32_t m = b->m, fx = f % m, fyz = f / m, fy = fyz % m, fz = fyz / m;
    const uint16_t *h = b->home[keys[0]];
    o[0] = fx >= h[0] ? fx - h[0] : fx + m - h[0];
    o[1] = fy >= h[1] ? fy - h[1] : fy + m - h[1];
    o[2] = fz >= h[2] ? fz - h[2] : fz + m - h[2];
    uint32_t i = 1;
    while (i < count && !b->used[slot_with(b, keys[i], o)])
        i++;
    if (i < count)
        return 0;
    for (i = 0; i < count; i++) {
        uint32_t s = slot_with(b, keys[i], o);
        b->used[s] = 1;
        b->next_free[s] = s + 1;
    }
    return 1;
}

/* Finds the offset of one group (cdvr/hvq.h: pseudo-random free slots, then every free slot
 * from its first key's home, wrapping) and marks its slots used. 0 when no offset fits. */
static int place_group(psh_build *b, const uint32_t *keys, uint32_t count, uint32_t o[3])
{
    uint32_t m = b->m, m3 = (uint32_t)b->m3;
    const uint16_t *h = b->home[keys[0]];
    uint32_t s0 = h[0] + m * (h[1] + m * (uint32_t)h[2]);
    uint32_t f = find_free(b->next_free, s0);
    if (f < m3 && try_offset(b, keys, count, f, o))
        return 1; /* offset 0 when its home is free: keeps neighbours coherent */
    uint32_t x = 0x9E3779B9u ^ (uint32_t)(keys[0] * 2654435761u);
    for (int t = 0; t < HVQ_PSH_RANDOM_TRIES; t++) {
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        f = find_free(b->next_free, (uint32_t)(((uint64_t)x * m3) >> 32));
        if (f < m3 && try_offset(b, keys, count, f, o))
            return 1;
    }
    f = find_free(b->next_free, s0);
    int wrapped = 0;
    for (;;) {
        if (f == m3) {
            if (wrapped)
                return 0;
            wrapped = 1;
            f = find_free(b->next_free, 0);
            continue;
        }
        if (wrapped && f >= s0)
            return 0;
        if (try_offset(b, keys, count, f, o))
            return 1;
        f = find_free(b->next_free, f + 1);
    }
}

/* One attempt with sides m, r: 1 = built into out, 0 = does not fit, -1 = out of memory. */
static int psh_try(const uint8_t *keys, const uint8_t *values, size_t n, unsigned vbytes,
                   uint32_t m, uint32_t r, hvq_psh *out)
{
    psh_build b = {.keys = keys, .n = n, .m = m, .r = r};
    b.m3 = (uint64_t)m * m * m;
    b.r3 = (uint64_t)r * r * r;
    unsigned slot_bytes = 3 + vbytes, w = hvq_offset_width(m);
    uint64_t bytes = hvq_psh_data_bytes(m, r, slot_bytes);
    uint8_t *data = NULL;
    uint32_t *offset = NULL;
    int result = -1;
    if (!group_keys(&b))
        goto done;
    b.next_free = malloc((b.m3 + 1) * sizeof *b.next_free);
    b.used = calloc(b.m3, 1);
    offset = calloc(b.r3 * 3, sizeof *offset);
    data = calloc(1, (size_t)bytes);
    if (!b.next_free || !b.used || !offset || !data)
        goto done;
    for (uint64_t s = 0; s <= b.m3; s++)
        b.next_free[s] = (uint32_t)s;
    result = 0;
    for (size_t g = 0; g < b.nentries; g++) {
        uint32_t e = b.order[g];
        const uint32_t *group = b.by_entry + b.entry_start[e];
        uint32_t count = b.entry_start[e + 1] - b.entry_start[e];
        if (group_has_twins(&b, group, count) || !place_group(&b, group, count, offset + 3 * e))
            goto done;
    }
    /* write offsets and slots; free slots hold the first key and value 0 */
    uint8_t *slots = data + b.r3 * 3 * w;
    for (uint64_t e = 0; e < b.r3; e++)
        for (int a = 0; a < 3; a++) {
            uint8_t *p = data + (e * 3 + (uint64_t)a) * w;
            if (w == 1)
                p[0] = (uint8_t)offset[3 * e + a];
            else
                hvq_wr16(p, offset[3 * e + a]);
        }
    for (uint64_t s = 0; s < b.m3; s++)
        memcpy(slots + s * slot_bytes, keys, 3);
    for (size_t i = 0; i < n; i++) {
        const uint8_t *k = keys + 3 * i;
        uint32_t e = k[0] % r + r * (k[1] % r + r * (k[2] % r));
        uint8_t *slot = slots + (uint64_t)slot_with(&b, (uint32_t)i, offset + 3 * e) * slot_bytes;
        memcpy(slot, k, 3);
        memcpy(slot + 3, values + (size_t)vbytes * i, vbytes);
    }
    out->m = m;
    out->r = r;
    out->n = (uint32_t)n;
    out->slot_bytes = slot_bytes;
    out->data = data;
    out->bytes = (size_t)bytes;
    data = NULL;
    result = 1;
done:
    free(data);
    free(offset);
    psh_build_free(&b);
    return result;
}

cdvr_status hvq_psh_build(const uint8_t *keys, const uint8_t *values, size_t n, unsigned vbytes,
                          int max_attempts, hvq_psh *out, cdvr_error *err)
{
    memset(out, 0, sizeof *out);
    out->slot_bytes = 3 + vbytes;
    if (n == 0)
        return CDVR_OK;
    if (n > (size_t)CDVR_HVQ_REGION * CDVR_HVQ_REGION * CDVR_HVQ_REGION)
        return cdvr_error_set(err, CDVR_ERR_ARG, "perfect spatial hash of %zu keys: more than "
                              "a region holds", n);
    unsigned extent = 1;
    for (size_t i = 0; i < 3 * n; i++)
        extent = keys[i] + 1u > extent ? keys[i] + 1u : extent;
    if (max_attempts < 1 || max_attempts > HVQ_PSH_ATTEMPTS)
        max_attempts = HVQ_PSH_ATTEMPTS;
    uint32_t m = 0, r = 0;
    for (int a = 0; a < max_attempts; a++) {
        hvq_psh_sizes(n, extent, a, &m, &r);
        int got = psh_try(keys, values, n, vbytes, m, r, out);
        if (got < 0)
            return cdvr_error_set(err, CDVR_ERR_NOMEM, "perfect spatial hash of %zu keys: out "
                                  "of memory for a %u^3 table", n, m);
        if (got > 0) {
            out->attempts = a + 1;
            return CDVR_OK;
        }
    }
    return cdvr_error_set(err, CDVR_ERR_UNSUPPORTED, "perfect spatial hash of %zu keys could not "
                          "be built in %d attempts (last: %u^3 slots, %u^3 offsets)", n,
                          max_attempts, m, r);
}

void hvq_psh_free(hvq_psh *h)
{
    free(h->data);
    h->data = NULL;
}
