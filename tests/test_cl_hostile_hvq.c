/* tests/test_cl_hostile_hvq.c - hostile hvq stores on the OpenCL device (issue 21, item 1):
 * stores whose hvq payload is patched and whose chunk and metadata CRC-32C are recomputed (so
 * only the codec can notice) are rendered by `cdvr.render(st, {variant=..., device="cl"})` and
 * played by the cl player, each in a child `cdvr` process under CPU-time, address-space and
 * wall-clock limits, so that a crash is counted, not fatal to the suite. The stores: one
 * crafted one (n1 = 0xffffffff, huge hash offsets, residual hash side m = 65535) and 40 with 4
 * random payload bytes changed (fixed seed). It proves that the device path refuses exactly
 * what the CPU path refuses (with a message naming the codec), that no child crashes or hangs,
 * and that a payload both accept renders on the device exactly as its CPU-decoded volume does
 * (fetch-mode render == dense render). It prints the counts (crashes, wrong images without
 * error, refusals). Skips (77) without an OpenCL device. */
#include <errno.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "cdvr/device.h"
#include "cdvr/hvq.h"
#include "cdvr/store.h"
#include "cdvr/volume.h"
#include "check.h"
#include "spec.h"

#if defined(__SANITIZE_ADDRESS__)
#define UNDER_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define UNDER_ASAN 1
#endif
#endif
#ifndef UNDER_ASAN
#define UNDER_ASAN 0
#endif

#define NRANDOM 40
#define CHILD_SECONDS 120

/* What the two children of one store reported and how they ended. */
typedef struct outcome {
    int crashed, timed_out;               /* the render child: killed by a signal or the limit */
    int player_crashed, player_timed_out; /* the player child */
    int cpu_ok, cl_ok, cl_said, same, player_ok, player_said;
    int cl_names_codec, player_names_codec;
    char out[4096], player_out[4096];
} outcome;

/* The child: arg[1] the store, arg[2] "render" (cpu, then cl, then the dense cl render of
 * the cpu-decoded volume when both render) or "player" (one frame of the cl player). */
static const char child_script[] =
    "io.stdout:setvbuf('line')\n"
    "local path, mode = arg[1], arg[2]\n"
    "local st = cdvr.open(path)\n"
    "local tf = cdvr.tf('hot')\n"
    "local cam = cdvr.camera{eye={-30,-40,50}, center={20,18,14}, up={0,0,1}, fov=40,\n"
    "                        width=40, height=32}\n"
    "local o = {variant='hvq', tf=tf, camera=cam}\n"
    "local function say(what, ok, e) print(what .. (ok and ' ok' or ' refused: ' .. tostring(e))) end\n"
    "if mode == 'render' then\n"
    "  o.device = 'cpu'\n"
    "  local okc, ec = pcall(cdvr.render, st, o)\n"
    "  say('cpu', okc, ec)\n"
    "  o.device = 'cl'\n"
    "  o.fetch = 'sample'\n" /* the fetch function on hostile payloads (bulk is the C decoder) */
    "  local okg, img = pcall(cdvr.render, st, o)\n"
    "  say('cl', okg, img)\n"
    "  if okc and okg then\n"
    "    local dense = cdvr.render(st:decode(1, 'hvq'), o)\n"
    "    local c = cdvr.compare(img, dense)\n"
    "    print(c.maxerr == 0 and 'same' or ('differ ' .. c.maxerr))\n"
    "  end\n"
    "else\n"
    "  local okp, e = pcall(function()\n"
    "    local p = cdvr.player{store=st, tf=tf, camera=cam, device='cl', variant='hvq',\n"
    "                          fetch='sample',\n"
    "                          width=40, height=32}\n"
    "    local r = p:run{frames=1}\n"
    "    local f = r.frames[1]\n"
    "    if not f or f.error then error(f and f.error or 'no frame') end\n"
    "  end)\n"
    "  say('player', okp, e)\n"
    "end\n";

static const char *binary_dir(void)
{
    const char *d = getenv("CDVR_BINARY_DIR");
    return d && *d ? d : ".";
}

/* Runs `cdvr script store mode` with limits: its output into out (n bytes); 1 when it
 * ended by a signal, a non-zero exit or the wall-clock limit (*timed_out). */
static int run_child(const char *script, const char *store, const char *mode, char *out,
                     size_t cap, int *timed_out)
{
    char exe[1024];
    snprintf(exe, sizeof exe, "%s/cdvr", binary_dir());
    *timed_out = 0;
    out[0] = '\0';
    int fds[2];
    if (pipe(fds) != 0) {
        CHECK(0, "pipe: %s", strerror(errno));
        return 1;
    }
    pid_t pid = fork();
    if (pid == 0) {
        dup2(fds[1], 1);
        dup2(fds[1], 2);
        close(fds[0]);
        close(fds[1]);
        struct rlimit cpu = {CHILD_SECONDS, CHILD_SECONDS};
        setrlimit(RLIMIT_CPU, &cpu);
        if (!UNDER_ASAN) { /* ASan reserves terabytes of address space */
            struct rlimit as = {(rlim_t)16 << 30, (rlim_t)16 << 30};
            setrlimit(RLIMIT_AS, &as);
        }
        execl(exe, exe, script, store, mode, (char *)NULL);
        _exit(127);
    }
    close(fds[1]);
    size_t n = 0;
    ssize_t got;
    time_t start = time(NULL);
    int status = 0, done = 0;
    while (n < cap - 1 && (got = read(fds[0], out + n, cap - 1 - n)) > 0)
        n += (size_t)got;
    out[n] = '\0';
    close(fds[0]);
    while (!done) {
        pid_t w = waitpid(pid, &status, WNOHANG);
        if (w == pid || w < 0)
            done = 1;
        else if (time(NULL) - start > CHILD_SECONDS) {
            kill(pid, SIGKILL);
            *timed_out = 1;
        } else
            usleep(10000);
    }
    return *timed_out || !WIFEXITED(status) || WEXITSTATUS(status) != 0;
}

/* 1 if the line of out that starts with prefix names hvq. */
static int line_names_hvq(const char *out, const char *prefix)
{
    const char *l = strstr(out, prefix);
    if (!l)
        return 0;
    const char *end = strchr(l, '\n'), *hit = strstr(l, "hvq");
    return hit && (!end || hit < end);
}

static void run_store(const char *script, const char *store, outcome *o)
{
    memset(o, 0, sizeof *o);
    o->crashed = run_child(script, store, "render", o->out, sizeof o->out, &o->timed_out);
    o->player_crashed = run_child(script, store, "player", o->player_out, sizeof o->player_out,
                                  &o->player_timed_out);
    o->cpu_ok = strstr(o->out, "cpu ok") != NULL;
    o->cl_ok = strstr(o->out, "cl ok") != NULL;
    o->cl_said = o->cl_ok || strstr(o->out, "cl refused:") != NULL;
    o->same = strstr(o->out, "same") != NULL;
    o->player_ok = strstr(o->player_out, "player ok") != NULL;
    o->player_said = o->player_ok || strstr(o->player_out, "player refused:") != NULL;
    o->cl_names_codec = line_names_hvq(o->out, "cl refused:");
    o->player_names_codec = line_names_hvq(o->player_out, "player refused:");
}

/* ---- stores ----------------------------------------------------------------------------- */

typedef struct store_bytes {
    uint8_t *p;
    size_t n;
    uint64_t meta_bytes, chunk_record, payload_at, payload_bytes;
} store_bytes;

static uint64_t le(const uint8_t *p, int nbytes)
{
    uint64_t v = 0;
    for (int i = 0; i < nbytes; i++)
        v |= (uint64_t)p[i] << (8 * i);
    return v;
}

static void put_le(uint8_t *p, uint64_t v, int nbytes)
{
    for (int i = 0; i < nbytes; i++)
        p[i] = (uint8_t)(v >> (8 * i));
}

/* Encodes a 40x36x28 Marschner-Lobb volume with hvq (no stage 2) into path and reads it back;
 * the chunk of interest is the only one (layout: core/store/store.c). */
static int make_store(const char *path, store_bytes *sb)
{
    cdvr_generate_opts g = {{40, 36, 28}, 1, CDVR_TYPE_U8, 0, 0, 0, 0};
    cdvr_volume *vol = NULL;
    cdvr_error err;
    CHECK_OK(cdvr_volume_generate("ml", &g, &vol, &err), err);
    if (!vol)
        return 0;
    cdvr_variant_spec spec = spec_codec("hvq", CDVR_STAGE2_NONE, 0.0);
    cdvr_encode_opts opts = {.variants = &spec, .nvariants = 1, .qlo = 0, .qhi = 255,
                             .source_type = CDVR_TYPE_U8};
    cdvr_status st = cdvr_store_encode(vol, &opts, path, &err);
    cdvr_volume_free(vol);
    CHECK_OK(st, err);
    FILE *f = st == CDVR_OK ? fopen(path, "rb") : NULL;
    if (!f)
        return 0;
    fseek(f, 0, SEEK_END);
    sb->n = (size_t)ftell(f);
    fseek(f, 0, SEEK_SET);
    sb->p = malloc(sb->n);
    int ok = sb->p && fread(sb->p, 1, sb->n, f) == sb->n;
    fclose(f);
    if (!ok)
        return 0;
    uint32_t nvariants = (uint32_t)le(sb->p + 196, 4);
    sb->meta_bytes = le(sb->p + 16, 8);
    sb->chunk_record = 256 + 160 * (uint64_t)nvariants;
    const uint8_t *rec = sb->p + sb->chunk_record;
    sb->payload_at = le(rec + 80, 8);
    sb->payload_bytes = le(rec + 96, 8);
    CHECK(nvariants == 1 && le(rec + 72, 4) == 0 && le(rec + 88, 8) == sb->payload_bytes &&
              sb->payload_at + sb->payload_bytes <= sb->n,
          "store layout: %u variants, payload %llu bytes at %llu", nvariants,
          (unsigned long long)sb->payload_bytes, (unsigned long long)sb->payload_at);
    return 1;
}

/* Writes sb with the chunk's and the metadata's CRC-32C recomputed. */
static int write_store(const char *path, store_bytes *sb)
{
    uint8_t *rec = sb->p + sb->chunk_record;
    put_le(rec + 76, cdvr_crc32c(0, sb->p + sb->payload_at, sb->payload_bytes), 4);
    put_le(sb->p + sb->meta_bytes, cdvr_crc32c(0, sb->p, sb->meta_bytes), 4);
    FILE *f = fopen(path, "wb");
    int ok = f && fwrite(sb->p, 1, sb->n, f) == sb->n;
    if (f)
        ok = fclose(f) == 0 && ok;
    CHECK(ok, "cannot write %s", path);
    return ok;
}

/* The crafted payload: n1 = 0xffffffff, region 0's hash offsets huge, residual side 65535. */
static void craft(uint8_t *payload, uint64_t bytes)
{
    const size_t dims[3] = {40, 36, 28};
    uint64_t nb = 1;
    for (int a = 0; a < 3; a++)
        nb *= (dims[a] + 3) / 4;
    uint64_t n1 = le(payload + 16, 4), n2 = le(payload + 20, 4);
    uint64_t c1 = (32 + nb + 7) & ~(uint64_t)7;
    uint64_t dir = (c1 + 16 * n1 + 128 * n2 + 7) & ~(uint64_t)7;
    CHECK(dir + 32 <= bytes, "crafted payload: directory at %llu of %llu bytes",
          (unsigned long long)dir, (unsigned long long)bytes);
    if (dir + 32 > bytes)
        return;
    put_le(payload + 16, 0xffffffffu, 4);
    put_le(payload + dir + 8, 0x7ffffffffff00000ull, 8);  /* index hash offset */
    put_le(payload + dir + 16, 65535, 2);                  /* residual hash m */
    put_le(payload + dir + 24, 0x7fffffff00000000ull, 8); /* residual hash offset */
}

static uint32_t rng_next(uint32_t *s)
{
    *s ^= *s << 13;
    *s ^= *s >> 17;
    *s ^= *s << 5;
    return *s;
}

typedef struct totals {
    int stores, crashed, timed_out, cpu_refused, cl_refused, cl_wrong, both_ok, differ;
    int player_crashed, player_refused, player_wrong, unnamed;
} totals;

static void tally(totals *t, const outcome *o, const char *what)
{
    t->stores++;
    t->crashed += o->crashed;
    t->timed_out += o->timed_out + o->player_timed_out;
    t->cpu_refused += !o->cpu_ok;
    t->cl_refused += o->cl_said && !o->cl_ok;
    t->cl_wrong += !o->cpu_ok && o->cl_ok;
    t->both_ok += o->cpu_ok && o->cl_ok;
    t->differ += o->cpu_ok && o->cl_ok && !o->same;
    t->player_crashed += o->player_crashed;
    t->player_refused += o->player_said && !o->player_ok;
    t->player_wrong += !o->cpu_ok && o->player_ok;
    t->unnamed += (o->cl_said && !o->cl_ok && !o->cl_names_codec) ||
                  (o->player_said && !o->player_ok && !o->player_names_codec);
    CHECK(!o->crashed && o->cl_said, "%s: the render child crashed or hung%s; output:\n%s", what,
          o->timed_out ? " (killed after the time limit)" : "", o->out);
    CHECK(!o->player_crashed && o->player_said, "%s: the player child crashed or hung%s; "
          "output:\n%s", what, o->player_timed_out ? " (killed after the time limit)" : "",
          o->player_out);
    CHECK(o->cpu_ok == o->cl_ok, "%s: cpu %s, cl %s:\n%s", what, o->cpu_ok ? "renders" : "refuses",
          o->cl_ok ? "renders" : "refuses", o->out);
    CHECK(!(o->cpu_ok && o->cl_ok) || o->same, "%s: the cl image differs from the dense one:\n%s",
          what, o->out);
    CHECK(o->cpu_ok == o->player_ok, "%s: cpu %s, cl player %s:\n%s", what,
          o->cpu_ok ? "renders" : "refuses", o->player_ok ? "plays" : "refuses", o->player_out);
    CHECK(o->cl_ok || !o->cl_said || o->cl_names_codec, "%s: the refusal does not name hvq:\n%s",
          what, o->out);
    CHECK(o->player_ok || !o->player_said || o->player_names_codec, "%s: the player's refusal "
          "does not name hvq:\n%s", what, o->player_out);
}

static void report(const char *name, const totals *t)
{
    printf("%s: %d stores; cpu refuses %d; cl render: refuses %d, crashes %d, renders without "
           "error where the cpu refuses %d, both render %d (cl image differs %d); cl player: "
           "crashes %d, refuses %d, plays where the cpu refuses %d; timeouts %d; refusals not "
           "naming hvq %d\n",
           name, t->stores, t->cpu_refused, t->cl_refused, t->crashed, t->cl_wrong, t->both_ok,
           t->differ, t->player_crashed, t->player_refused, t->player_wrong, t->timed_out,
           t->unnamed);
}

/* The byte range of the payload's structure fields: the codebook sizes and the region
 * directory (where a changed byte moves every later read). */
static void structure_range(const uint8_t *payload, uint64_t *dir, uint64_t *dir_end)
{
    uint64_t nb = 10 * 9 * 7; /* blocks of 40x36x28 */
    uint64_t n1 = le(payload + 16, 4), n2 = le(payload + 20, 4);
    uint64_t c1 = (32 + nb + 7) & ~(uint64_t)7;
    *dir = (c1 + 16 * n1 + 128 * n2 + 7) & ~(uint64_t)7;
    *dir_end = *dir + 32; /* one region */
}

int main(void)
{
#if CDVR_HAVE_OPENCL
    cdvr_cl *cl;
    cdvr_error err;
    if (cdvr_cl_open(&cl, &err) != CDVR_OK) {
        return check_opencl_unavailable(err.msg);
    }
    cdvr_cl_close(cl);
#else
    return check_opencl_unavailable("built without OpenCL");
#endif
    char dir[] = "/tmp/cdvr_hostile_hvq_XXXXXX";
    if (!mkdtemp(dir)) {
        CHECK(0, "mkdtemp: %s", strerror(errno));
        return check_finish();
    }
    char script[256], clean[256], path[256];
    snprintf(script, sizeof script, "%s/child.lua", dir);
    snprintf(clean, sizeof clean, "%s/clean.cdv", dir);
    snprintf(path, sizeof path, "%s/hostile.cdv", dir);
    FILE *f = fopen(script, "w");
    CHECK(f && fputs(child_script, f) >= 0 && fclose(f) == 0, "cannot write %s", script);
    store_bytes sb = {0};
    if (make_store(clean, &sb)) {
        uint8_t *orig = malloc(sb.payload_bytes);
        memcpy(orig, sb.p + sb.payload_at, sb.payload_bytes);
        outcome o;
        /* the clean store renders the same on both devices */
        run_store(script, clean, &o);
        CHECK(!o.crashed && o.cpu_ok && o.cl_ok && o.same && o.player_ok, "clean store:\n%s%s",
              o.out, o.player_out);
        totals crafted = {0}, random = {0}, structure = {0};
        craft(sb.p + sb.payload_at, sb.payload_bytes);
        if (write_store(path, &sb)) {
            run_store(script, path, &o);
            tally(&crafted, &o, "crafted store");
        }
        uint64_t dir, dir_end;
        structure_range(orig, &dir, &dir_end);
        uint32_t rng = 0x21u;
        for (int i = 0; i < 2 * NRANDOM; i++) {
            /* 4 bytes anywhere past the 32-byte header (magic and dims are not the point),
             * then 4 bytes among the codebook sizes and the directory */
            memcpy(sb.p + sb.payload_at, orig, sb.payload_bytes);
            for (int k = 0; k < 4; k++) {
                uint32_t u = rng_next(&rng);
                uint64_t at = i < NRANDOM ? 32 + u % (sb.payload_bytes - 32)
                                          : (u & 1 ? 16 + u / 2 % 8 : dir + u / 2 % (dir_end - dir));
                uint8_t v = (uint8_t)rng_next(&rng);
                sb.p[sb.payload_at + at] = v == orig[at] ? (uint8_t)~v : v;
            }
            if (!write_store(path, &sb))
                break;
            char what[64];
            snprintf(what, sizeof what, "%s store %d", i < NRANDOM ? "random" : "structure",
                     i % NRANDOM);
            run_store(script, path, &o);
            tally(i < NRANDOM ? &random : &structure, &o, what);
        }
        report("crafted", &crafted);
        report("4 random payload bytes", &random);
        report("4 random structure bytes (n1, n2, directory)", &structure);
        free(orig);
    }
    free(sb.p);
    unlink(script);
    unlink(clean);
    unlink(path);
    rmdir(dir);
    return check_finish();
}
