/* plugins/dicom/dicom_helper.cpp - the GDCM side of the DICOM plugin: a small executable,
 * build/plugins/cdvr_dicom_helper, that the plugin (dicom.cpp, whose top documents what is read and
 * how) runs for every probe and read, so that GDCM's assertions (Debian builds it with assert()
 * on: a hostile file can abort it) and any crash in GDCM or its codecs end the helper, never
 * the program that loads the volume.
 *
 *   cdvr_dicom_helper probe|read PATH SELECT ALLOW_OUTSIDE MAX_BYTES
 *
 * writes to stdout either "ERR <cdvr_status>\n<message>" or
 *   "OK X Y Z TYPE sx sy sz ox oy oz d0 .. d8\n" (TYPE a cdvr_type; %.17g numbers), then for read
 *   one record "D <bytes>\n<bytes of one slice, host order>" per slice, z order, and "END\n"
 *   (or "ERR ..." where a slice fails).
 * It uses libcdvr's headers only (cdvr_plugin_error); it links GDCM, not libcdvr.
 */
#include <dirent.h>
#include <errno.h>
#include <stdarg.h>
#include <fcntl.h>
#include <limits.h>
#include <stdlib.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <map>
#include <memory>
#include <set>
#include <new>
#include <string>
#include <vector>

#include <gdcmImage.h>
#include <gdcmImageChangePhotometricInterpretation.h>
#include <gdcmImageReader.h>
#include <gdcmReader.h>
#include <gdcmSequenceOfItems.h>
#include <gdcmScanner.h>
#include <gdcmTag.h>
#include <gdcmTrace.h>
#include <gdcmTransferSyntax.h>

extern "C" {
#include "cdvr/plugin.h"
}

namespace {

const double kGapTolerance = 0.01;  /* relative: uneven slice gaps */

const gdcm::Tag tSeriesUID(0x0020, 0x000e), tSeriesDesc(0x0008, 0x103e),
    tIPP(0x0020, 0x0032), tIOP(0x0020, 0x0037), tRows(0x0028, 0x0010), tCols(0x0028, 0x0011),
    tPixelSpacing(0x0028, 0x0030), tSlope(0x0028, 0x1053), tIntercept(0x0028, 0x1052),
    tBitsAlloc(0x0028, 0x0100), tBitsStored(0x0028, 0x0101), tPixelRep(0x0028, 0x0103),
    tSamples(0x0028, 0x0002), tFrames(0x0028, 0x0008), tPhotometric(0x0028, 0x0004),
    tSliceThickness(0x0018, 0x0050), tSpacingBetween(0x0018, 0x0088),
    tTransferSyntax(0x0002, 0x0010), tPixelData(0x7fe0, 0x0010),
    /* multi-frame (enhanced) functional groups and the sequences in their items */
    tShared(0x5200, 0x9229), tPerFrame(0x5200, 0x9230), tPlanePosition(0x0020, 0x9113),
    tPlaneOrientation(0x0020, 0x9116), tPixelMeasures(0x0028, 0x9110),
    tValueTransform(0x0028, 0x9145);

const unsigned kFramesMax = 65535;

/* One slice of a series: a single-frame file, or frame `frame` of a multi-frame file of
 * `frames` frames, as its header says. */
struct Slice {
    std::string path;
    double ipp[3], iop[6], ps[2], slope, intercept, pos;
    unsigned rows, cols, bits_alloc, bits_stored, pixel_rep, samples;
    unsigned frame = 0, frames = 1;
    bool native; /* uncompressed transfer syntax */
    bool mono1;  /* MONOCHROME1: inverted on read (GDCM's filter, as ITK's GDCMImageIO does) */
};

struct Series {
    std::string uid, description;
    std::vector<Slice> slices;
};

/* What probe found: the series chosen, sorted, with its geometry and output type. */
struct Plan {
    Series series;
    size_t dims[3];
    double spacing[3], origin[3], direction[9];
    cdvr_type type;
};

std::string trim(const char *s)
{
    std::string v = s ? s : "";
    while (!v.empty() && (v.back() == ' ' || v.back() == '\0'))
        v.pop_back();
    size_t i = 0;
    while (i < v.size() && v[i] == ' ')
        i++;
    return v.substr(i);
}

/* A backslash-separated list of n decimal numbers (DS); false when it is not exactly that. */
bool parse_numbers(const std::string &s, double *out, size_t n)
{
    const char *p = s.c_str();
    for (size_t i = 0; i < n; i++) {
        char *end;
        out[i] = strtod(p, &end);
        if (end == p || !std::isfinite(out[i]))
            return false;
        while (*end == ' ')
            end++;
        if (i + 1 < n && *end != '\\')
            return false;
        p = end + (i + 1 < n);
    }
    return *p == '\0';
}

bool parse_uint(const std::string &s, unsigned *out)
{
    char *end;
    if (s.empty() || s[0] == '-')
        return false;
    unsigned long v = strtoul(s.c_str(), &end, 10);
    while (*end == ' ')
        end++;
    if (end == s.c_str() || *end || v > 0xffffffffUL)
        return false;
    *out = (unsigned)v;
    return true;
}

/* cdvr_load_max_bytes(opts) without libcdvr (cdvr/volume.h, core/io/format.c). */
uint64_t max_bytes(const cdvr_raw_opts *opts)
{
    if (opts && opts->max_bytes)
        return opts->max_bytes;
    long pages = sysconf(_SC_PHYS_PAGES), size = sysconf(_SC_PAGESIZE);
    if (pages <= 0 || size <= 0)
        return (uint64_t)1 << 40;
    uint64_t half = (uint64_t)pages * (uint64_t)size / 2;
    return half < ((uint64_t)64 << 20) ? (uint64_t)64 << 20 : half;
}

size_t type_size(cdvr_type t)
{
    return t == CDVR_TYPE_U8 ? 1 : t == CDVR_TYPE_F32 ? 4 : 2;
}

const char *type_name(cdvr_type t)
{
    return t == CDVR_TYPE_U8 ? "u8" : t == CDVR_TYPE_U16 ? "u16" : t == CDVR_TYPE_I16 ? "i16" : "f32";
}

/* The regular files of dir in name order (at most limit; 0: all). */
bool list_dir(const std::string &dir, size_t limit, std::vector<std::string> &out)
{
    DIR *d = opendir(dir.c_str());
    if (!d)
        return false;
    std::vector<std::string> names;
    while (struct dirent *e = readdir(d))
        if (e->d_name[0] != '.')
            names.push_back(e->d_name);
    closedir(d);
    std::sort(names.begin(), names.end());
    for (const std::string &n : names) {
        std::string p = dir + "/" + n;
        struct stat st;
        if (stat(p.c_str(), &st) == 0 && S_ISREG(st.st_mode))
            out.push_back(p);
        if (limit && out.size() >= limit)
            break;
    }
    return true;
}

std::string dir_of(const std::string &path)
{
    size_t slash = path.find_last_of('/');
    if (slash == std::string::npos)
        return ".";
    return slash == 0 ? "/" : path.substr(0, slash);
}

/* ---- the header of each file (gdcm::Scanner reads the tags, stops before the pixels) ------- */

class Reader {
  public:
    Reader(const char *path, const cdvr_raw_opts *opts, cdvr_error *err)
        : path_(path), opts_(opts), err_(err)
    {
    }
    cdvr_status plan(Plan &out);

  private:
    const char *path_;
    const cdvr_raw_opts *opts_;
    cdvr_error *err_;
    gdcm::Scanner scanner_;

    cdvr_status fail(cdvr_status st, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
    cdvr_status files(std::string &dir, std::string &select, std::vector<std::string> &out);
    cdvr_status slice(const std::string &file, Slice &s, unsigned *frames);
    cdvr_status frames(const Slice &first, std::vector<Slice> &out);
    cdvr_status choose(std::map<std::string, Series> &all, const std::string &dir,
                       const std::string &select, Series &out);
    cdvr_status geometry(const std::string &dir, Plan &p);
    cdvr_status value_type(Plan &p);
};

cdvr_status Reader::fail(cdvr_status st, const char *fmt, ...)
{
    if (err_) {
        char msg[CDVR_ERRMSG_MAX];
        va_list ap;
        va_start(ap, fmt);
        vsnprintf(msg, sizeof msg, fmt, ap);
        va_end(ap);
        cdvr_plugin_error(err_, st, "%s", msg);
    }
    return st;
}

/* The files to scan, the directory they are in and the default select. */
cdvr_status Reader::files(std::string &dir, std::string &select, std::vector<std::string> &out)
{
    struct stat st;
    if (stat(path_, &st) != 0)
        return fail(CDVR_ERR_IO, "%s: cannot open (%s)", path_, strerror(errno));
    select = opts_ && opts_->select ? trim(opts_->select) : "";
    if (S_ISDIR(st.st_mode))
        dir = path_;
    else if (S_ISREG(st.st_mode)) {
        dir = dir_of(path_);
        if (select.empty()) { /* the file's own series */
            gdcm::Scanner one;
            one.AddTag(tSeriesUID);
            if (!one.Scan(std::vector<std::string>{path_}) || !one.IsKey(path_))
                return fail(CDVR_ERR_FORMAT, "%s: not a DICOM file GDCM can read", path_);
            select = trim(one.GetValue(path_, tSeriesUID));
            if (select.empty())
                return fail(CDVR_ERR_FORMAT, "%s: no SeriesInstanceUID (0020,000E)", path_);
        }
    } else
        return fail(CDVR_ERR_IO, "%s: not a regular file or directory", path_);
    std::vector<std::string> all;
    if (!list_dir(dir, 0, all))
        return fail(CDVR_ERR_IO, "%s: cannot list the directory %s", path_, dir.c_str());
    char *base = realpath(dir.c_str(), NULL);
    if (!base)
        return fail(CDVR_ERR_IO, "%s: cannot resolve %s", path_, dir.c_str());
    std::string root = std::string(base) + (strcmp(base, "/") ? "/" : "");
    free(base);
    for (const std::string &f : all) {
        char *real = realpath(f.c_str(), NULL);
        bool inside = real && strncmp(real, root.c_str(), root.size()) == 0;
        free(real);
        if (inside || (opts_ && opts_->allow_outside))
            out.push_back(f);
        else if (!real && (!opts_ || !opts_->allow_outside))
            return fail(CDVR_ERR_IO, "%s: cannot resolve %s", path_, f.c_str());
        else
            return fail(CDVR_ERR_IO, "%s: %s lies outside the directory (a symlink; allow_outside "
                        "reads it)", path_, f.c_str());
    }
    return CDVR_OK;
}

/* The header fields of one scanned file; *frames its NumberOfFrames (a multi-frame file's
 * geometry tags may be missing here: Reader::frames reads them from its functional groups). */
cdvr_status Reader::slice(const std::string &file, Slice &s, unsigned *frames)
{
    const char *f = file.c_str();
    auto tag = [&](const gdcm::Tag &t) { return trim(scanner_.GetValue(f, t)); };
    auto bad = [&](const char *name, const gdcm::Tag &t, const std::string &v) {
        return fail(CDVR_ERR_FORMAT, "%s: %s (%04X,%04X) is %s%s%s", f, name, t.GetGroup(),
                    t.GetElement(), v.empty() ? "missing" : "'", v.c_str(), v.empty() ? "" : "'");
    };
    s.path = file;
    std::string v;
    *frames = 1;
    v = tag(tFrames);
    if (!v.empty() && (!parse_uint(v, frames) || *frames < 1 || *frames > kFramesMax))
        return fail(CDVR_ERR_FORMAT, "%s: NumberOfFrames (0028,0008) is '%s' (1 to %u)", f,
                    v.c_str(), kFramesMax);
    bool multi = *frames > 1;
    static const double identity[6] = {1, 0, 0, 0, 1, 0};
    memcpy(s.ipp, identity + 1, sizeof s.ipp); /* (0, 0, 0) */
    memcpy(s.iop, identity, sizeof s.iop);
    s.ps[0] = s.ps[1] = 1;
    if (!parse_numbers(v = tag(tIPP), s.ipp, 3) && !(multi && v.empty()))
        return bad("ImagePositionPatient", tIPP, v);
    if (!parse_numbers(v = tag(tIOP), s.iop, 6) && !(multi && v.empty()))
        return bad("ImageOrientationPatient", tIOP, v);
    if ((!parse_numbers(v = tag(tPixelSpacing), s.ps, 2) || !(s.ps[0] > 0) || !(s.ps[1] > 0)) &&
        !(multi && v.empty()))
        return bad("PixelSpacing", tPixelSpacing, v);
    if (!parse_uint(v = tag(tRows), &s.rows) || s.rows == 0 || s.rows > 65535)
        return bad("Rows", tRows, v);
    if (!parse_uint(v = tag(tCols), &s.cols) || s.cols == 0 || s.cols > 65535)
        return bad("Columns", tCols, v);
    if (!parse_uint(v = tag(tBitsAlloc), &s.bits_alloc) ||
        (s.bits_alloc != 8 && s.bits_alloc != 16 && s.bits_alloc != 32))
        return bad("BitsAllocated (8, 16 or 32)", tBitsAlloc, v);
    if (!parse_uint(v = tag(tBitsStored), &s.bits_stored) || s.bits_stored == 0 ||
        s.bits_stored > s.bits_alloc)
        return bad("BitsStored", tBitsStored, v);
    if (!parse_uint(v = tag(tPixelRep), &s.pixel_rep) || s.pixel_rep > 1)
        return bad("PixelRepresentation", tPixelRep, v);
    v = tag(tSamples);
    if (!parse_uint(v, &s.samples) || s.samples != 1)
        return bad("SamplesPerPixel (only 1: grey values)", tSamples, v);
    v = tag(tPhotometric);
    if (v != "MONOCHROME2" && v != "MONOCHROME1")
        return bad("PhotometricInterpretation (MONOCHROME1 or 2)", tPhotometric, v);
    s.mono1 = v == "MONOCHROME1";
    s.slope = 1;
    s.intercept = 0;
    if (!(v = tag(tSlope)).empty() && (!parse_numbers(v, &s.slope, 1) || s.slope == 0))
        return bad("RescaleSlope", tSlope, v);
    if (!(v = tag(tIntercept)).empty() && !parse_numbers(v, &s.intercept, 1))
        return bad("RescaleIntercept", tIntercept, v);
    gdcm::TransferSyntax ts(gdcm::TransferSyntax::GetTSType(tag(tTransferSyntax).c_str()));
    s.native = ts.IsValid() && !ts.IsEncapsulated();
    if (s.native) { /* the pixels it claims must fit in the file */
        struct stat st;
        double need = (double)s.rows * s.cols * (s.bits_alloc / 8) * *frames;
        if (stat(f, &st) != 0 || (double)st.st_size < need)
            return fail(CDVR_ERR_FORMAT, "%s: Rows %u x Columns %u x %u bits x %u frames claim "
                        "%.0f bytes of pixels, the file holds %lld bytes", f, s.rows, s.cols,
                        s.bits_alloc, *frames, need, (long long)st.st_size);
    }
    return CDVR_OK;
}

/* ---- multi-frame files ------------------------------------------------------------------------ */

/* The trimmed text of tag t in ds ("" when absent or not text). */
std::string ds_text(const gdcm::DataSet &ds, const gdcm::Tag &t)
{
    if (!ds.FindDataElement(t))
        return "";
    const gdcm::ByteValue *bv = ds.GetDataElement(t).GetByteValue();
    return bv ? trim(std::string(bv->GetPointer(), bv->GetLength()).c_str()) : "";
}

/* Item i (from 1) of sequence t in ds, copied into out; false when there is none. */
bool ds_item(const gdcm::DataSet &ds, const gdcm::Tag &t, size_t i, gdcm::DataSet &out)
{
    if (!ds.FindDataElement(t))
        return false;
    gdcm::SmartPointer<gdcm::SequenceOfItems> sq = ds.GetDataElement(t).GetValueAsSQ();
    if (!sq || i < 1 || sq->GetNumberOfItems() < i)
        return false;
    out = sq->GetItem(i).GetNestedDataSet();
    return true;
}

/* Numbers of tag t inside the first item of sequence seq of a functional-group item g. */
bool group_numbers(const gdcm::DataSet &g, const gdcm::Tag &seq, const gdcm::Tag &t, double *out,
                   size_t n)
{
    gdcm::DataSet item;
    return ds_item(g, seq, 1, item) && parse_numbers(ds_text(item, t), out, n);
}

/* The frames of a multi-frame file as slices (first: its top-level header, first.frames set).
 * Each frame's position, orientation, pixel spacing and rescale come from its item of the
 * Per-frame Functional Groups (5200,9230), else the Shared Functional Groups (5200,9229), else
 * the top-level tags; a frame without any position lies SpacingBetweenSlices (else
 * SliceThickness, else 1 mm) further along the normal than the one before (a multi-frame
 * secondary capture: from ImagePositionPatient, else 0, with identity orientation). */
cdvr_status Reader::frames(const Slice &first, std::vector<Slice> &out)
{
    const char *f = first.path.c_str();
    gdcm::Reader r;
    r.SetFileName(f);
    std::set<gdcm::Tag> skip;
    skip.insert(tPixelData);
    if (!r.ReadUpToTag(tPixelData, skip))
        return fail(CDVR_ERR_FORMAT, "%s: GDCM cannot read the multi-frame header", f);
    const gdcm::DataSet &ds = r.GetFile().GetDataSet();
    gdcm::DataSet shared, frame;
    bool has_shared = ds_item(ds, tShared, 1, shared);
    Slice base = first;
    double dz = 1, t;
    std::string v = ds_text(ds, tSpacingBetween);
    if (v.empty())
        v = ds_text(ds, tSliceThickness);
    if (!v.empty() && parse_numbers(v, &t, 1) && t > 0)
        dz = t;
    if (has_shared) {
        group_numbers(shared, tPlanePosition, tIPP, base.ipp, 3);
        group_numbers(shared, tPlaneOrientation, tIOP, base.iop, 6);
        group_numbers(shared, tPixelMeasures, tPixelSpacing, base.ps, 2);
        if (group_numbers(shared, tPixelMeasures, tSpacingBetween, &t, 1) && t > 0)
            dz = t;
        group_numbers(shared, tValueTransform, tSlope, &base.slope, 1);
        group_numbers(shared, tValueTransform, tIntercept, &base.intercept, 1);
    }
    gdcm::SmartPointer<gdcm::SequenceOfItems> per;
    if (ds.FindDataElement(tPerFrame))
        per = ds.GetDataElement(tPerFrame).GetValueAsSQ();
    if (per && per->GetNumberOfItems() != 0 && per->GetNumberOfItems() != first.frames)
        return fail(CDVR_ERR_FORMAT, "%s: %zu Per-frame Functional Group items (5200,9230) for "
                    "NumberOfFrames %u", f, (size_t)per->GetNumberOfItems(), first.frames);
    double prev[3];
    for (unsigned k = 0; k < first.frames; k++) {
        Slice s = base;
        s.frame = k;
        bool placed = false;
        if (per && per->GetNumberOfItems() == first.frames) {
            const gdcm::DataSet &g = per->GetItem(k + 1).GetNestedDataSet();
            placed = group_numbers(g, tPlanePosition, tIPP, s.ipp, 3);
            group_numbers(g, tPlaneOrientation, tIOP, s.iop, 6);
            group_numbers(g, tPixelMeasures, tPixelSpacing, s.ps, 2);
            group_numbers(g, tValueTransform, tSlope, &s.slope, 1);
            group_numbers(g, tValueTransform, tIntercept, &s.intercept, 1);
        }
        if (!(s.ps[0] > 0 && s.ps[1] > 0) || s.slope == 0)
            return fail(CDVR_ERR_FORMAT, "%s: frame %u: PixelSpacing %g\\%g or RescaleSlope %g "
                        "is not usable", f, k + 1, s.ps[0], s.ps[1], s.slope);
        if (!placed && k > 0) { /* the next position along the normal */
            const double *a = s.iop;
            double n[3] = {a[1] * a[5] - a[2] * a[4], a[2] * a[3] - a[0] * a[5],
                           a[0] * a[4] - a[1] * a[3]};
            for (int i = 0; i < 3; i++)
                s.ipp[i] = prev[i] + dz * n[i];
        }
        memcpy(prev, s.ipp, sizeof prev);
        out.push_back(s);
    }
    return CDVR_OK;
}

/* The series select names (or the only one); a refusal lists the series. */
cdvr_status Reader::choose(std::map<std::string, Series> &all, const std::string &dir,
                           const std::string &select, Series &out)
{
    if (all.empty())
        return fail(CDVR_ERR_FORMAT, "%s: no DICOM image series in %s", path_, dir.c_str());
    std::vector<Series *> hits;
    for (auto &kv : all)
        if (select.empty() || kv.second.uid == select || kv.second.description == select)
            hits.push_back(&kv.second);
    if (hits.size() == 1) {
        out = std::move(*hits[0]);
        return CDVR_OK;
    }
    std::string list;
    for (auto &kv : all) {
        const Series &s = kv.second;
        char one[320];
        snprintf(one, sizeof one, "%s%s '%s' %zu slices %ux%ux%zu", list.empty() ? "" : "; ",
                 s.uid.c_str(), s.description.c_str(), s.slices.size(), s.slices[0].cols,
                 s.slices[0].rows, s.slices.size());
        list += one;
    }
    if (select.empty())
        return fail(CDVR_ERR_ARG, "%s: holds %zu DICOM series; choose one with select "
                    "(SeriesInstanceUID or SeriesDescription): %s", path_, all.size(),
                    list.c_str());
    if (hits.empty())
        return fail(CDVR_ERR_ARG, "%s: no DICOM series '%s' (select); the series: %s", path_,
                    select.c_str(), list.c_str());
    return fail(CDVR_ERR_ARG, "%s: %zu series have the SeriesDescription '%s'; select one by "
                "its SeriesInstanceUID: %s", path_, hits.size(), select.c_str(), list.c_str());
}

double dot(const double *a, const double *b)
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/* A slice in messages: its file, and its frame for a multi-frame file. */
std::string name(const Slice &s)
{
    return s.frames > 1 ? s.path + " frame " + std::to_string(s.frame + 1) : s.path;
}

/* Sorting, spacing and the direction matrix (the top of this file). */
cdvr_status Reader::geometry(const std::string &dir, Plan &p)
{
    std::vector<Slice> &sl = p.series.slices;
    const Slice &a = sl[0];
    double r[3] = {a.iop[0], a.iop[1], a.iop[2]}, c[3] = {a.iop[3], a.iop[4], a.iop[5]};
    double lr = std::sqrt(dot(r, r)), lc = std::sqrt(dot(c, c));
    if (std::fabs(lr - 1) > 1e-3 || std::fabs(lc - 1) > 1e-3 || std::fabs(dot(r, c)) > 1e-3)
        return fail(CDVR_ERR_FORMAT, "%s: ImageOrientationPatient (0020,0037) %g\\%g\\%g\\%g\\%g\\%g "
                    "is not two orthogonal unit vectors", name(a).c_str(), a.iop[0], a.iop[1],
                    a.iop[2], a.iop[3], a.iop[4], a.iop[5]);
    for (int i = 0; i < 3; i++) {
        r[i] /= lr;
        c[i] /= lc;
    }
    double n[3] = {r[1] * c[2] - r[2] * c[1], r[2] * c[0] - r[0] * c[2], r[0] * c[1] - r[1] * c[0]};
    for (Slice &s : sl) {
        for (int i = 0; i < 6; i++)
            if (std::fabs(s.iop[i] - a.iop[i]) > 1e-4)
                return fail(CDVR_ERR_FORMAT, "%s: ImageOrientationPatient (0020,0037) differs "
                            "from %s's in the same series", name(s).c_str(), name(a).c_str());
        if (s.rows != a.rows || s.cols != a.cols)
            return fail(CDVR_ERR_FORMAT, "%s: Rows x Columns %ux%u differ from %s's %ux%u",
                        name(s).c_str(), s.rows, s.cols, name(a).c_str(), a.rows, a.cols);
        if (std::fabs(s.ps[0] - a.ps[0]) > 1e-4 * a.ps[0] ||
            std::fabs(s.ps[1] - a.ps[1]) > 1e-4 * a.ps[1])
            return fail(CDVR_ERR_FORMAT, "%s: PixelSpacing (0028,0030) %g\\%g differs from %s's",
                        name(s).c_str(), s.ps[0], s.ps[1], name(a).c_str());
        if (s.bits_alloc != a.bits_alloc || s.pixel_rep != a.pixel_rep)
            return fail(CDVR_ERR_FORMAT, "%s: BitsAllocated / PixelRepresentation %u/%u differ "
                        "from %s's %u/%u", name(s).c_str(), s.bits_alloc, s.pixel_rep,
                        name(a).c_str(), a.bits_alloc, a.pixel_rep);
        s.pos = dot(s.ipp, n);
    }
    std::sort(sl.begin(), sl.end(), [](const Slice &x, const Slice &y) {
        if (x.pos != y.pos)
            return x.pos < y.pos;
        return x.path < y.path || (x.path == y.path && x.frame < y.frame);
    });
    size_t k = sl.size();
    double dz = 1;
    if (k > 1) {
        dz = (sl[k - 1].pos - sl[0].pos) / (double)(k - 1);
        size_t worst = 0;
        double off = -1;
        for (size_t i = 0; i + 1 < k; i++) {
            double gap = sl[i + 1].pos - sl[i].pos;
            if (gap <= 1e-6 * (std::fabs(dz) + 1))
                return fail(CDVR_ERR_FORMAT, "%s: %s and %s lie at the same position %g along "
                            "the slice normal (ImagePositionPatient)", path_, name(sl[i]).c_str(),
                            name(sl[i + 1]).c_str(), sl[i].pos);
            if (std::fabs(gap - dz) > off) {
                off = std::fabs(gap - dz);
                worst = i;
            }
        }
        if (off > kGapTolerance * dz)
            return fail(CDVR_ERR_FORMAT, "%s: uneven slice spacing: %s and %s are %g mm apart, "
                        "the mean gap is %g mm (more than 1%% off)", path_,
                        name(sl[worst]).c_str(), name(sl[worst + 1]).c_str(),
                        sl[worst + 1].pos - sl[worst].pos, dz);
        /* the slices must lie on a line: ipp_i = ipp_0 + i * step; an in-plane part of step
         * is a gantry tilt, kept exactly as a sheared grid (the third direction column along
         * step, not n): no resampling, every voxel where its file puts it */
        double tol = 0.01 * std::min(a.ps[0], a.ps[1]), step[3], inplane = 0;
        for (int j = 0; j < 3; j++)
            step[j] = (sl[k - 1].ipp[j] - sl[0].ipp[j]) / (double)(k - 1);
        for (size_t i = 1; i < k; i++) {
            double off = 0;
            for (int j = 0; j < 3; j++) {
                double e = sl[i].ipp[j] - sl[0].ipp[j] - (double)i * step[j];
                off += e * e;
            }
            if (std::sqrt(off) > tol)
                return fail(CDVR_ERR_FORMAT, "%s: %s is %g mm off the line through the first and "
                            "last slice positions (ImagePositionPatient): the slices are not one "
                            "evenly tilted stack, which cdvr does not resample", path_,
                            name(sl[i]).c_str(), std::sqrt(off));
        }
        double along = dot(step, n);
        for (int j = 0; j < 3; j++)
            inplane += (step[j] - along * n[j]) * (step[j] - along * n[j]);
        if (std::sqrt(inplane) * (double)(k - 1) > tol) { /* tilted: the step is the z axis */
            double len = std::sqrt(dot(step, step));
            for (int j = 0; j < 3; j++)
                n[j] = step[j] / len;
            dz = len;
        }
    } else { /* one slice: the thickness the header gives */
        std::string v = trim(scanner_.GetValue(a.path.c_str(), tSpacingBetween));
        if (v.empty())
            v = trim(scanner_.GetValue(a.path.c_str(), tSliceThickness));
        double t;
        if (!v.empty() && parse_numbers(v, &t, 1) && t > 0)
            dz = t;
    }
    (void)dir;
    p.dims[0] = a.cols;
    p.dims[1] = a.rows;
    p.dims[2] = k;
    p.spacing[0] = a.ps[1];
    p.spacing[1] = a.ps[0];
    p.spacing[2] = dz;
    for (int i = 0; i < 3; i++) {
        p.origin[i] = sl[0].ipp[i];
        p.direction[3 * i + 0] = r[i];
        p.direction[3 * i + 1] = c[i];
        p.direction[3 * i + 2] = n[i];
    }
    return CDVR_OK;
}

/* The output type (the top of this file), from the header only. */
cdvr_status Reader::value_type(Plan &p)
{
    const Slice &a = p.series.slices[0];
    bool rescaled = false, integral = true, fits = true;
    for (const Slice &s : p.series.slices) {
        if (s.bits_stored != a.bits_stored)
            return fail(CDVR_ERR_FORMAT, "%s: BitsStored (0028,0101) %u differs from %s's %u",
                        s.path.c_str(), s.bits_stored, a.path.c_str(), a.bits_stored);
        rescaled |= s.slope != 1 || s.intercept != 0;
        integral &= s.slope == std::floor(s.slope) && s.intercept == std::floor(s.intercept) &&
                    std::fabs(s.slope) < 65536 && std::fabs(s.intercept) < 65536;
        double lo = s.pixel_rep ? -std::ldexp(1, (int)s.bits_stored - 1) : 0;
        double hi = s.pixel_rep ? std::ldexp(1, (int)s.bits_stored - 1) - 1
                                : std::ldexp(1, (int)s.bits_stored) - 1;
        double y0 = s.slope * lo + s.intercept, y1 = s.slope * hi + s.intercept;
        fits &= std::min(y0, y1) >= -32768 && std::max(y0, y1) <= 32767;
        if (std::max(std::fabs(y0), std::fabs(y1)) > 3.40282346638528859812e+38)
            return fail(CDVR_ERR_FORMAT, "%s: RescaleSlope %g and RescaleIntercept %g map stored "
                        "values to %g, beyond the range of f32 (cdvr refuses such values; the "
                        "f32_overflow option does not reach DICOM)", name(s).c_str(), s.slope,
                        s.intercept, std::fabs(y0) > std::fabs(y1) ? y0 : y1);
    }
    if (a.bits_alloc == 32)
        p.type = CDVR_TYPE_F32;
    else if (rescaled)
        p.type = integral && fits ? CDVR_TYPE_I16 : CDVR_TYPE_F32;
    else if (a.pixel_rep)
        p.type = CDVR_TYPE_I16;
    else
        p.type = a.bits_alloc == 8 ? CDVR_TYPE_U8 : CDVR_TYPE_U16;
    double bytes = (double)p.dims[0] * p.dims[1] * p.dims[2] * type_size(p.type);
    uint64_t cap = max_bytes(opts_);
    if (bytes > (double)cap)
        return fail(CDVR_ERR_FORMAT, "%s: the DICOM series claims %.0f bytes of voxels (%zux%zux%zu "
                    "%s), more than max_bytes %llu (a load option; the default is half the "
                    "physical memory)", path_, bytes, p.dims[0], p.dims[1], p.dims[2],
                    type_name(p.type), (unsigned long long)cap);
    return CDVR_OK;
}

cdvr_status Reader::plan(Plan &out)
{
    std::string dir, select;
    std::vector<std::string> list;
    cdvr_status st = files(dir, select, list);
    if (st != CDVR_OK)
        return st;
    for (const gdcm::Tag &t : {tSeriesUID, tSeriesDesc, tIPP, tIOP, tRows, tCols, tPixelSpacing,
                               tSlope, tIntercept, tBitsAlloc, tBitsStored, tPixelRep, tSamples,
                               tFrames, tPhotometric, tSliceThickness, tSpacingBetween,
                               tTransferSyntax})
        scanner_.AddTag(t);
    if (!scanner_.Scan(list))
        return fail(CDVR_ERR_IO, "%s: GDCM cannot scan the files of %s", path_, dir.c_str());
    std::map<std::string, Series> all;
    for (const std::string &f : list) {
        if (!scanner_.IsKey(f.c_str()))
            continue; /* not DICOM */
        std::string uid = trim(scanner_.GetValue(f.c_str(), tSeriesUID));
        if (uid.empty() || !scanner_.GetValue(f.c_str(), tRows))
            continue; /* not an image of a series (DICOMDIR, a report) */
        Series &s = all[uid];
        s.uid = uid;
        if (s.slices.empty())
            s.description = trim(scanner_.GetValue(f.c_str(), tSeriesDesc));
        Slice one;
        unsigned n = 1;
        if ((st = slice(f, one, &n)) != CDVR_OK)
            return st;
        one.frames = n;
        if (n == 1)
            s.slices.push_back(one);
        else if ((st = frames(one, s.slices)) != CDVR_OK)
            return st;
    }
    Plan p;
    if ((st = choose(all, dir, select, p.series)) != CDVR_OK ||
        (st = geometry(dir, p)) != CDVR_OK || (st = value_type(p)) != CDVR_OK)
        return st;
    out = std::move(p);
    return CDVR_OK;
}

/* ---- voxels ----------------------------------------------------------------------------------- */

/* One decoded slice (s's header) into out, count values of type t. */
template <typename T>
void convert(const char *buf, const Slice &s, size_t count, T *out)
{
    unsigned bytes = s.bits_alloc / 8;
    uint32_t mask = s.bits_stored >= 32 ? 0xffffffffu : (1u << s.bits_stored) - 1;
    uint32_t sign = s.bits_stored >= 32 ? 0x80000000u : 1u << (s.bits_stored - 1);
    for (size_t i = 0; i < count; i++) {
        uint32_t u = 0;
        if (bytes == 1)
            u = (uint8_t)buf[i];
        else if (bytes == 2) {
            uint16_t v;
            memcpy(&v, buf + 2 * i, 2);
            u = v;
        } else
            memcpy(&u, buf + 4 * i, 4);
        u &= mask;
        double x = s.pixel_rep && (u & sign) ? (double)u - std::ldexp(1, (int)s.bits_stored)
                                             : (double)u;
        out[i] = (T)(s.slope * x + s.intercept);
    }
}

/* The decoded pixels of one file (all its frames), kept while the slices of one multi-frame
 * file are read, so a file is decoded once whatever the slice order. */
struct Decoded {
    std::string path;
    std::vector<char> pixels;
};

/* Decodes s's file into d (MONOCHROME1 turned into MONOCHROME2 by GDCM's own filter, as ITK's
 * GDCMImageIO does, before the rescale). */
cdvr_status decode_file(const Slice &s, Decoded &d, cdvr_error *err)
{
    d.path.clear();
    gdcm::ImageReader reader;
    reader.SetFileName(s.path.c_str());
    if (!reader.Read())
        return cdvr_plugin_error(err, CDVR_ERR_FORMAT, "%s: GDCM cannot read the image",
                                 s.path.c_str());
    const gdcm::Image *im = &reader.GetImage();
    gdcm::ImageChangePhotometricInterpretation icpi;
    if (s.mono1) {
        icpi.SetInput(*im);
        icpi.SetPhotometricInterpretation(gdcm::PhotometricInterpretation::MONOCHROME2);
        if (!icpi.Change())
            return cdvr_plugin_error(err, CDVR_ERR_FORMAT, "%s: GDCM cannot invert the "
                                     "MONOCHROME1 image", s.path.c_str());
        im = &icpi.GetOutput();
    }
    const unsigned *d3 = im->GetDimensions();
    size_t count = (size_t)s.rows * s.cols, want = count * (s.bits_alloc / 8) * s.frames;
    unsigned depth = im->GetNumberOfDimensions() > 2 ? d3[2] : 1;
    gdcm::PixelFormat pf = im->GetPixelFormat();
    if (d3[0] != s.cols || d3[1] != s.rows || depth != s.frames ||
        pf.GetBitsAllocated() != s.bits_alloc || pf.GetSamplesPerPixel() != 1)
        return cdvr_plugin_error(err, CDVR_ERR_FORMAT, "%s: the image GDCM decodes (%ux%ux%u, %u "
                                 "bits) is not the %ux%u x %u frames, %u bits its header gave",
                                 s.path.c_str(), d3[0], d3[1], depth,
                                 (unsigned)pf.GetBitsAllocated(), s.cols, s.rows, s.frames,
                                 s.bits_alloc);
    if (im->GetBufferLength() != want)
        return cdvr_plugin_error(err, CDVR_ERR_FORMAT, "%s: the pixel data holds %lu bytes, Rows "
                                 "x Columns x BitsAllocated x frames claim %zu", s.path.c_str(),
                                 im->GetBufferLength(), want);
    d.pixels.resize(want);
    if (!im->GetBuffer(d.pixels.data()))
        return cdvr_plugin_error(err, CDVR_ERR_FORMAT, "%s: GDCM cannot decode the pixel data "
                                 "(transfer syntax %s)", s.path.c_str(),
                                 gdcm::TransferSyntax::GetTSString(im->GetTransferSyntax()));
    d.path = s.path;
    return CDVR_OK;
}

cdvr_status read_slice(const Slice &s, cdvr_type type, void *dst, Decoded &d, cdvr_error *err)
{
    if (d.path != s.path) {
        cdvr_status st = decode_file(s, d, err);
        if (st != CDVR_OK)
            return st;
    }
    size_t count = (size_t)s.rows * s.cols;
    const char *buf = d.pixels.data() + (size_t)s.frame * count * (s.bits_alloc / 8);
    switch (type) {
    case CDVR_TYPE_U8: convert(buf, s, count, (uint8_t *)dst); break;
    case CDVR_TYPE_U16: convert(buf, s, count, (uint16_t *)dst); break;
    case CDVR_TYPE_I16: convert(buf, s, count, (int16_t *)dst); break;
    case CDVR_TYPE_F32: convert(buf, s, count, (float *)dst); break;
    }
    return CDVR_OK;
}

/* ---- the protocol (plugins/dicom/dicom.cpp reads it) -------------------------------------------- */

int report(const cdvr_error &err)
{
    printf("ERR %d\n%s", (int)err.status, err.msg);
    return fflush(stdout) == 0 ? 0 : 1;
}

int run(const char *mode, const char *path, const cdvr_raw_opts *opts)
{
    cdvr_error err;
    memset(&err, 0, sizeof err);
    Plan p;
    cdvr_status st = Reader(path, opts, &err).plan(p);
    if (st != CDVR_OK)
        return report(err);
    printf("OK %zu %zu %zu %d", p.dims[0], p.dims[1], p.dims[2], (int)p.type);
    for (double v : p.spacing)
        printf(" %.17g", v);
    for (double v : p.origin)
        printf(" %.17g", v);
    for (double v : p.direction)
        printf(" %.17g", v);
    printf("\n");
    if (strcmp(mode, "read") != 0)
        return fflush(stdout) == 0 ? 0 : 1;
    size_t frame = p.dims[0] * p.dims[1] * type_size(p.type);
    std::vector<char> buf(frame);
    Decoded decoded;
    for (size_t k = 0; k < p.dims[2]; k++) {
        if ((st = read_slice(p.series.slices[k], p.type, buf.data(), decoded, &err)) != CDVR_OK)
            return report(err);
        printf("D %zu\n", frame);
        if (fwrite(buf.data(), 1, frame, stdout) != frame)
            return 1;
    }
    printf("END\n");
    return fflush(stdout) == 0 ? 0 : 1;
}

} // namespace

/* cdvr_dicom_helper probe|read PATH SELECT ALLOW_OUTSIDE MAX_BYTES (the plugin runs it). */
int main(int argc, char **argv)
{
    if (argc != 6 || (strcmp(argv[1], "probe") != 0 && strcmp(argv[1], "read") != 0)) {
        fprintf(stderr, "usage: cdvr_dicom_helper probe|read PATH SELECT ALLOW_OUTSIDE "
                "MAX_BYTES (run by the cdvr dicom plugin)\n");
        return 2;
    }
    gdcm::Trace::SetWarning(false); /* GDCM's warnings would only fill the plugin's stderr tail */
    struct rlimit no_core = {0, 0};   /* an assertion on a hostile file leaves no core file */
    setrlimit(RLIMIT_CORE, &no_core);
    cdvr_raw_opts opts;
    memset(&opts, 0, sizeof opts);
    opts.select = argv[3];
    opts.allow_outside = atoi(argv[4]);
    opts.max_bytes = strtoull(argv[5], NULL, 10);
    try {
        return run(argv[1], argv[2], &opts);
    } catch (const std::bad_alloc &) {
        cdvr_error err;
        cdvr_plugin_error(&err, CDVR_ERR_NOMEM, "%s: out of memory", argv[2]);
        return report(err);
    } catch (const std::exception &e) {
        cdvr_error err;
        cdvr_plugin_error(&err, CDVR_ERR_FORMAT, "%s: GDCM: %s", argv[2], e.what());
        return report(err);
    }
}
