/* core/io/io_raw.c - headerless raw volumes: cdvr_volume_load_raw and cdvr_volume_save_raw. */
#include "cdvr/atomicfile.h"
#include "cdvr/regular_file.h"
#include "cdvr/volume.h"
#include "volume_io.h"
#include "cdvr/format.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

static cdvr_status check_raw_opts(const char *path, const cdvr_raw_opts *opts, size_t timesteps,
                                  size_t *data_bytes, cdvr_error *err)
{
    if (cdvr_type_size(opts->type) == 0)
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: unknown voxel type %d (u8, u16, i16, f32)",
                              path, (int)opts->type);
    if (opts->dims[0] == 0 || opts->dims[1] == 0 || opts->dims[2] == 0)
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: dims %zux%zux%zu: every dim must be positive",
                              path, opts->dims[0], opts->dims[1], opts->dims[2]);
    size_t total;
    if (!cdvr_volume_bytes_for(opts->dims, timesteps, opts->type, data_bytes) ||
        !cdvr_size_add(*data_bytes, opts->header_bytes, &total))
        return cdvr_error_set(err, CDVR_ERR_ARG,
                              "%s: dims %zux%zux%zu x %zu timesteps of %s overflow the address space",
                              path, opts->dims[0], opts->dims[1], opts->dims[2], timesteps,
                              cdvr_type_name(opts->type));
    if (*data_bytes > cdvr_load_max_bytes(opts))
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: dims %zux%zux%zu x %zu timesteps of %s are "
                              "%zu bytes, more than max_bytes %llu (a load option; the default is "
                              "half the physical memory)", path, opts->dims[0], opts->dims[1],
                              opts->dims[2], timesteps, cdvr_type_name(opts->type), *data_bytes,
                              (unsigned long long)cdvr_load_max_bytes(opts));
    return CDVR_OK;
}

/* Opens path and checks that it is a regular file of exactly header + data_bytes bytes. */
static cdvr_status open_raw(const char *path, const cdvr_raw_opts *opts, size_t timesteps,
                            size_t data_bytes, FILE **out, cdvr_error *err)
{
    FILE *f;
    struct stat sb;
    cdvr_status st = cdvr_fopen_regular_file(path, &f, &sb, err);
    if (st != CDVR_OK)
        return st;
    size_t expected = data_bytes + opts->header_bytes; /* overflow checked by check_raw_opts */
    unsigned long long actual = (unsigned long long)sb.st_size;
    if (actual != expected) {
        fclose(f);
        return cdvr_error_set(err, CDVR_ERR_FORMAT,
                              "%s: %s: dims %zux%zux%zu x %zu timesteps of %s + %zu header bytes "
                              "need %zu bytes, file has %llu",
                              path, actual < expected ? "file is truncated" : "dims do not match file size",
                              opts->dims[0], opts->dims[1], opts->dims[2], timesteps,
                              cdvr_type_name(opts->type), opts->header_bytes, expected, actual);
    }
    *out = f;
    return CDVR_OK;
}

static void apply_spacing(cdvr_volume *vol, const double spacing[3])
{
    for (int i = 0; i < 3; i++)
        if (spacing[i] > 0)
            vol->spacing[i] = spacing[i];
}

/* Checks opts against path and opens it: *timesteps and *data_bytes are what it holds. */
static cdvr_status open_checked(const char *path, const cdvr_raw_opts *opts, size_t *timesteps,
                                size_t *data_bytes, FILE **f, cdvr_error *err)
{
    *f = NULL;
    *timesteps = opts->timesteps ? opts->timesteps : 1;
    cdvr_status st = check_raw_opts(path, opts, *timesteps, data_bytes, err);
    if (st == CDVR_OK)
        st = open_raw(path, opts, *timesteps, *data_bytes, f, err);
    return st;
}

cdvr_status cdvr_volume_load_raw(const char *path, const cdvr_raw_opts *opts, cdvr_volume **out,
                                 cdvr_error *err)
{
    *out = NULL;
    size_t timesteps, data_bytes;
    FILE *f;
    cdvr_status st = open_checked(path, opts, &timesteps, &data_bytes, &f, err);
    if (st != CDVR_OK)
        return st;
    cdvr_volume *vol;
    st = cdvr_volume_create(opts->dims, timesteps, opts->type, &vol, err);
    if (st != CDVR_OK) {
        fclose(f);
        return st;
    }
    int ok = fseeko(f, (off_t)opts->header_bytes, SEEK_SET) == 0 &&
             fread(vol->data, 1, data_bytes, f) == data_bytes;
    fclose(f);
    if (!ok) {
        cdvr_volume_free(vol);
        return cdvr_error_set(err, CDVR_ERR_IO, "%s: file is truncated: short read of %zu data bytes",
                              path, data_bytes);
    }
    size_t elem = cdvr_type_size(opts->type);
    if (elem > 1 && (opts->big_endian ? 1 : 0) == cdvr_host_is_little_endian())
        cdvr_swap_bytes(vol->data, data_bytes / elem, elem);
    apply_spacing(vol, opts->spacing);
    cdvr_volume_set_source_type(vol, cdvr_type_file_name(opts->type));
    *out = vol;
    return CDVR_OK;
}

cdvr_status cdvr_volume_probe_raw(const char *path, const cdvr_raw_opts *opts, cdvr_volume *head,
                                  cdvr_error *err)
{
    size_t timesteps, data_bytes;
    FILE *f;
    cdvr_status st = open_checked(path, opts, &timesteps, &data_bytes, &f, err);
    if (st != CDVR_OK)
        return st;
    fclose(f);
    memcpy(head->dims, opts->dims, sizeof head->dims);
    head->timesteps = timesteps;
    head->type = opts->type;
    cdvr_volume_set_source_type(head, cdvr_type_file_name(opts->type));
    apply_spacing(head, opts->spacing);
    return CDVR_OK;
}

/* Writes data (bytes long) to f, byte-swapped when swap, through a bounded buffer. */
static int write_data(FILE *f, const unsigned char *data, size_t bytes, size_t elem, int swap)
{
    if (!swap)
        return fwrite(data, 1, bytes, f) == bytes;
    unsigned char buf[1 << 16];
    for (size_t done = 0; done < bytes;) {
        size_t n = bytes - done < sizeof buf ? bytes - done : sizeof buf;
        memcpy(buf, data + done, n);
        cdvr_swap_bytes(buf, n / elem, elem);
        if (fwrite(buf, 1, n, f) != n)
            return 0;
        done += n;
    }
    return 1;
}

cdvr_status cdvr_volume_save_raw(const cdvr_volume *vol, const char *path, int big_endian,
                                 cdvr_error *err)
{
    size_t bytes;
    if (!cdvr_volume_bytes_for(vol->dims, vol->timesteps, vol->type, &bytes))
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: volume size overflows", path);
    cdvr_atomic_file af;
    cdvr_status st = cdvr_atomic_open(&af, path, err);
    if (st != CDVR_OK)
        return st;
    size_t elem = cdvr_type_size(vol->type);
    int swap = elem > 1 && (big_endian ? 1 : 0) == cdvr_host_is_little_endian();
    return cdvr_atomic_commit(&af, !write_data(af.f, vol->data, bytes, elem, swap), err);
}

/* ---- format table (cdvr/format.h) ----------------------------------------------------------- */

static cdvr_status raw_probe(const char *path, const cdvr_raw_opts *opts, cdvr_volume *head,
                             cdvr_error *err)
{
    return cdvr_volume_probe_raw(path, opts, head, err);
}

static cdvr_status raw_load(const char *path, const cdvr_raw_opts *opts, cdvr_volume **out,
                            cdvr_error *err)
{
    return cdvr_volume_load_raw(path, opts, out, err);
}

static const char *const raw_suffixes[] = {".raw", ".bin", ".dat", NULL};

/* No magic: a raw file is what the caller says it is (dims, type, endian, header, timesteps). */
const cdvr_format cdvr_format_raw = {
    .name = "raw",
    .description = "voxels without a header (or a header of header= bytes skipped), described "
                   "by dims, type, endian and timesteps",
    .suffixes = raw_suffixes,
    .flags = CDVR_FORMAT_DESCRIBED,
    .probe = raw_probe,
    .load = raw_load,
};
