/* plugins/dicom/dicom.cpp - DICOM series as a cdvr format plugin, written in C++ against GDCM
 * (libgdcm-dev). The project is C; only this plugin is C++ (plugins/dicom/CMakeLists.txt enables
 * CXX for it and skips it, with a message, where there is no C++ compiler or no GDCM). It uses no
 * libcdvr symbol (cdvr/plugin.h): it gives `read`, not `load`, reports errors with
 * cdvr_plugin_error, and exports only cdvr_plugin_v1 (extern "C"); -z defs checks it.
 *
 * Two parts. This file is the plugin: the format table, the magic and accepts_dir tests (its own
 * few bytes of reading), and probe/read, which run the helper build/plugins/cdvr_dicom_helper
 * (dicom_helper.cpp, found beside this .so through dladdr) and read its answer from a pipe: the
 * header, or the header then the voxels slice by slice straight into the registry's buffer.
 * The probe also names the world: cdvr_volume.space "LPS". All
 * of GDCM runs in the helper, because Debian's GDCM is built with assert() enabled and aborts on
 * some hostile files (a mutated file meta group, an element length past the end; measured: about
 * one mutated file in four aborted a process that called GDCM directly); a helper that aborts,
 * crashes or answers out of protocol is an error naming the path, GDCM's last stderr line and the
 * signal, never the end of the program. The cost is one process per probe and per read (the
 * registry probes then reads: each scans the headers once).
 *
 * Format "dicom": suffix .dcm; magic "DICM" at byte 128 (the Part 10 preamble); accepts_dir: a
 * directory of which one of its first 64 regular files (name order) has that preamble (nothing
 * else is read there, no voxels). What it reads:
 *  - a directory: its regular files (not recursive; others and files GDCM cannot parse as DICOM
 *    are skipped) grouped by SeriesInstanceUID (0020,000E). One series: that one. Several:
 *    cdvr_raw_opts.select (Lua: select=) names one by its SeriesInstanceUID or by its
 *    SeriesDescription (0008,103E), exactly (trailing blanks ignored); without select the load is
 *    refused listing each series (UID, description, number of slices, dims). A select the
 *    directory does not hold is refused listing those it does; so is a description two series
 *    share (use the UID).
 *  - a file (.dcm, or any name with the DICM magic): the series it belongs to, read from the
 *    file's directory, as ParaView does: select defaults to the file's own SeriesInstanceUID (an
 *    explicit select still names a series of that directory).
 *  - multi-frame files (NumberOfFrames (0028,0008) > 1, up to 65535): each frame is a slice of
 *    the file's series (sorted with the others like any slice). A frame's position, orientation,
 *    PixelSpacing and RescaleSlope/Intercept come from its item of the Per-frame Functional
 *    Groups (5200,9230) (PlanePositionSequence, PlaneOrientationSequence, PixelMeasuresSequence,
 *    PixelValueTransformationSequence), else the Shared Functional Groups (5200,9229), else the
 *    top-level tags (enhanced CT/MR/... images); a frame with no position lies
 *    SpacingBetweenSlices (else SliceThickness, else 1 mm) along the normal from the one before,
 *    and a file without any geometry (a multi-frame secondary capture) gets position 0,
 *    identity orientation and PixelSpacing 1. The file is decoded once for all its frames.
 *
 * Geometry (DICOM patient space is LPS; cdvr keeps a file's world as it is, as for a NRRD with
 * `space: left-posterior-superior`, cdvr/volume.h). The result is what ITK's GDCMImageIO /
 * ImageSeriesReader gives for the same series, which is also the rule in the project (the same
 * world box and direction matrix as ITK's or VTK's reader): with r and c the row and column
 * direction cosines of ImageOrientationPatient (0020,0037) and n = r x c,
 *   - slices are sorted by ImagePositionPatient (0020,0032) projected on n, ascending; file
 *     names and order in the directory do not matter;
 *   - voxel (i,j,k) is column i, row j of slice k; direction = [r c n] (columns), origin = the
 *     ImagePositionPatient of slice 0 (LPS, mm);
 *   - spacing x = PixelSpacing[1] (between columns), y = PixelSpacing[0] (between rows),
 *     z = the mean gap between slice positions (one slice: SpacingBetweenSlices, else
 *     SliceThickness, else 1). A gap more than 1% off that mean is refused naming the worst gap
 *     (its two files); so are two slices at one position, and orientation, Rows, Columns,
 *     PixelSpacing or pixel format differing between slices.
 *   - gantry tilt: slices whose positions move in their plane by the same amount per slice
 *     (the step from one position to the next has a component along r or c over 1% of a pixel
 *     across the stack) are kept exactly, not resampled: the third direction column is the
 *     step's direction and spacing z its length (a sheared grid; cdvr's direction matrix need
 *     not be orthonormal, cdvr/volume.h), so every voxel lies where its file puts it. ITK would
 *     drop the shift (it cannot represent a shear) and Slicer resamples. Slices that are not on
 *     one line (a position more than 1% of a pixel off the line through the first and last) are
 *     refused naming the file.
 * VTK's old vtkDICOMImageReader (the one python3-vtk9 has) differs: it ignores
 * ImageOrientationPatient (identity direction) and flips each slice vertically (its row 0 is the
 * DICOM's last row) with its origin at ImagePositionPatient; its voxel (i, R-1-j, k) is cdvr's
 * (i, j, k). tests/test_dicom.sh checks this.
 *
 * Values: RescaleSlope (0028,1053) and RescaleIntercept (0028,1052) (per slice, default 1 and 0)
 * are applied (CT: Hounsfield units). Type: without a rescale, the stored type (u8, u16, i16;
 * signed 8-bit as i16, 32-bit as f32); with one, i16 when every slope and intercept is an integer
 * and the range BitsStored and PixelRepresentation allow maps into [-32768, 32767] on every slice
 * (decided from the header, before any voxel is read), else f32 (value = slope * stored +
 * intercept rounded to float). Bits above BitsStored are masked (and the value sign-extended for
 * PixelRepresentation 1). MONOCHROME1 (lowest value white) is turned into MONOCHROME2 by GDCM's
 * ImageChangePhotometricInterpretation before the rescale, as ITK's GDCMImageIO does (unsigned:
 * 2^BitsStored - 1 - stored). A rescale that maps the stored range beyond f32 is refused (the
 * f32 rule of core/io; the f32_overflow load option does not reach the helper); SamplesPerPixel other
 * than 1 (colour), and other PhotometricInterpretations, are refused. Compressed transfer syntaxes
 * (JPEG, JPEG-LS, JPEG 2000, RLE) are decoded by gdcm::ImageReader as far as this GDCM supports
 * them; an unsupported one is refused naming the file.
 *
 * Limits: missing or bad tags are refused naming the tag and its value. A native (uncompressed)
 * file shorter than Rows * Columns * BitsAllocated / 8 is refused before GDCM reads it; every
 * decoded slice must have exactly that size. The total claim, columns * rows * slices * output
 * bytes, is checked in probe against opts->max_bytes, or when it is 0 the default of
 * cdvr_load_max_bytes_default() (half the physical memory, at least 64 MiB; replicated here, as a
 * plugin cannot call libcdvr; the registry checks the same claim again before it allocates). The
 * path given must be a regular file or a directory (special files refused); in a directory only
 * regular files are read, and each must resolve (realpath) under the directory unless
 * opts->allow_outside. Every entry point catches C++ exceptions (the helper's and the plugin's).
 */
#include <dirent.h>
#include <dlfcn.h>
#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstring>
#include <new>
#include <string>
#include <vector>

extern "C" {
#include "cdvr/plugin.h"
}

extern char **environ;

namespace {

const size_t kDirProbeEntries = 64; /* accepts_dir looks at this many regular files, at most */
const size_t kLineMax = 1024;       /* the helper's header line, at most */

/* ---- what the plugin reads itself: the preamble ------------------------------------------------ */

/* 1 when the regular file at path has "DICM" at byte 128 (opened non-blocking: a FIFO that
 * slipped in between the stat and the open never blocks). */
bool has_preamble(const char *path)
{
    int fd = open(path, O_RDONLY | O_NONBLOCK | O_CLOEXEC);
    if (fd < 0)
        return false;
    struct stat st;
    char buf[4];
    bool ok = fstat(fd, &st) == 0 && S_ISREG(st.st_mode) && st.st_size >= 132 &&
              pread(fd, buf, 4, 128) == 4 && memcmp(buf, "DICM", 4) == 0;
    close(fd);
    return ok;
}

/* The first `limit` regular files of dir in name order. */
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
        if (out.size() >= limit)
            break;
    }
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

size_t type_size(int t)
{
    return t == CDVR_TYPE_U8 ? 1 : t == CDVR_TYPE_F32 ? 4 : 2;
}

/* build/plugins/cdvr_dicom_helper: beside this shared object. */
std::string helper_path()
{
    Dl_info info;
    if (!dladdr((void *)&has_preamble, &info) || !info.dli_fname)
        return "cdvr_dicom_helper";
    std::string so = info.dli_fname;
    size_t slash = so.find_last_of('/');
    return (slash == std::string::npos ? std::string(".") : so.substr(0, slash)) +
           "/cdvr_dicom_helper";
}

/* ---- the helper: one process, its stdout read through a buffer, its stderr's tail kept -------- */

class Helper {
  public:
    ~Helper() { finish(); }
    cdvr_status start(const char *mode, const char *path, const cdvr_raw_opts *opts,
                      cdvr_error *err);
    bool line(std::string &out);             /* up to '\n' (dropped); false at EOF or too long */
    bool exact(char *dst, size_t n);         /* n bytes */
    std::string rest();                      /* what is left, up to EOF (bounded) */
    /* Waits for the process; the failure as text ("" when it exited 0). */
    std::string finish();

  private:
    pid_t pid_ = -1;
    int out_ = -1, err_ = -1;
    std::vector<char> buf_;
    size_t pos_ = 0;
    bool eof_ = false;
    std::string tail_;
    bool fill();
};

cdvr_status Helper::start(const char *mode, const char *path, const cdvr_raw_opts *opts,
                          cdvr_error *err)
{
    int po[2], pe[2];
    if (pipe2(po, O_CLOEXEC) != 0)
        return cdvr_plugin_error(err, CDVR_ERR_IO, "%s: pipe: %s", path, strerror(errno));
    if (pipe2(pe, O_CLOEXEC) != 0) {
        close(po[0]);
        close(po[1]);
        return cdvr_plugin_error(err, CDVR_ERR_IO, "%s: pipe: %s", path, strerror(errno));
    }
    std::string helper = helper_path(), allow = opts && opts->allow_outside ? "1" : "0",
                cap = std::to_string((unsigned long long)max_bytes(opts)),
                select = opts && opts->select ? opts->select : "";
    std::string m = mode, p = path;
    char *argv[] = {&helper[0], &m[0], &p[0], &select[0], &allow[0], &cap[0], NULL};
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_addopen(&fa, 0, "/dev/null", O_RDONLY, 0);
    posix_spawn_file_actions_adddup2(&fa, po[1], 1);
    posix_spawn_file_actions_adddup2(&fa, pe[1], 2);
    int rc = posix_spawn(&pid_, helper.c_str(), &fa, NULL, argv, environ);
    posix_spawn_file_actions_destroy(&fa);
    close(po[1]);
    close(pe[1]);
    out_ = po[0];
    err_ = pe[0];
    if (rc != 0) {
        pid_ = -1;
        return cdvr_plugin_error(err, CDVR_ERR_UNSUPPORTED, "%s: cannot run the dicom plugin's "
                                 "helper %s (%s; it is built beside the plugin)", path,
                                 helper.c_str(), strerror(rc));
    }
    return CDVR_OK;
}

/* More of stdout into buf_ (false at EOF), keeping the last line of stderr meanwhile. */
bool Helper::fill()
{
    while (!eof_) {
        struct pollfd fds[2] = {{out_, POLLIN, 0}, {err_, POLLIN, 0}};
        if (poll(fds, err_ >= 0 ? 2 : 1, -1) < 0) {
            if (errno == EINTR)
                continue;
            return false;
        }
        char chunk[65536];
        if (err_ >= 0 && (fds[1].revents & (POLLIN | POLLHUP | POLLERR))) {
            ssize_t n = read(err_, chunk, sizeof chunk);
            if (n > 0) {
                tail_.append(chunk, (size_t)n);
                if (tail_.size() > 4096)
                    tail_.erase(0, tail_.size() - 4096);
            } else if (n == 0 || errno != EINTR) {
                close(err_);
                err_ = -1;
            }
        }
        if (fds[0].revents & (POLLIN | POLLHUP | POLLERR)) {
            ssize_t n = read(out_, chunk, sizeof chunk);
            if (n > 0) {
                if (pos_ == buf_.size()) {
                    buf_.clear();
                    pos_ = 0;
                }
                buf_.insert(buf_.end(), chunk, chunk + n);
                return true;
            }
            if (n == 0 || errno != EINTR)
                eof_ = true;
        }
    }
    return false;
}

bool Helper::line(std::string &out)
{
    for (;;) {
        auto begin = buf_.begin() + (long)pos_;
        auto nl = std::find(begin, buf_.end(), '\n');
        if (nl != buf_.end()) {
            out.assign(begin, nl);
            pos_ = (size_t)(nl - buf_.begin()) + 1;
            return true;
        }
        if (buf_.size() - pos_ > kLineMax || !fill())
            return false;
    }
}

bool Helper::exact(char *dst, size_t n)
{
    while (n > 0) {
        if (pos_ == buf_.size() && !fill())
            return false;
        size_t k = std::min(n, buf_.size() - pos_);
        memcpy(dst, buf_.data() + pos_, k);
        pos_ += k;
        dst += k;
        n -= k;
    }
    return true;
}

std::string Helper::rest()
{
    while (buf_.size() - pos_ < CDVR_ERRMSG_MAX && fill()) {
    }
    return std::string(buf_.begin() + (long)pos_,
                       buf_.begin() + (long)std::min(buf_.size(), pos_ + CDVR_ERRMSG_MAX));
}

std::string Helper::finish()
{
    if (pid_ < 0)
        return "";
    if (!eof_)
        kill(pid_, SIGKILL); /* stopped reading early: it has nothing more to say */
    if (out_ >= 0)
        close(out_);
    while (err_ >= 0) { /* the rest of stderr (bounded by the process ending) */
        char chunk[4096];
        ssize_t n = read(err_, chunk, sizeof chunk);
        if (n > 0) {
            tail_.append(chunk, (size_t)n);
            if (tail_.size() > 4096)
                tail_.erase(0, tail_.size() - 4096);
        } else if (n == 0 || errno != EINTR) {
            close(err_);
            err_ = -1;
        }
    }
    out_ = -1;
    int status = 0;
    pid_t r;
    while ((r = waitpid(pid_, &status, 0)) < 0 && errno == EINTR) {
    }
    pid_ = -1;
    /* GDCM's last non-empty stderr line, printable characters only */
    std::string last;
    size_t end = tail_.find_last_not_of("\r\n \t");
    if (end != std::string::npos) {
        size_t begin = tail_.find_last_of('\n', end);
        last = tail_.substr(begin == std::string::npos ? 0 : begin + 1, end + 1 -
                            (begin == std::string::npos ? 0 : begin + 1));
        for (char &c : last)
            if ((unsigned char)c < 32 || (unsigned char)c > 126)
                c = '?';
        if (last.size() > 200)
            last = last.substr(0, 200) + "...";
    }
    char what[320] = "";
    if (r < 0)
        return ""; /* SIGCHLD ignored by the program: the protocol alone tells */
    if (WIFSIGNALED(status))
        snprintf(what, sizeof what, "killed by signal %d%s%s", WTERMSIG(status),
                 last.empty() ? "" : ": ", last.c_str());
    else if (WIFEXITED(status) && WEXITSTATUS(status) != 0)
        snprintf(what, sizeof what, "exit status %d%s%s", WEXITSTATUS(status),
                 last.empty() ? "" : ": ", last.c_str());
    return what;
}

/* The failure of a helper that did not answer "OK"/"D"/"END" where expected. */
cdvr_status helper_failed(Helper &h, const char *path, const std::string &got, cdvr_error *err)
{
    int status = 0;
    if (got.compare(0, 4, "ERR ") == 0 && sscanf(got.c_str() + 4, "%d", &status) == 1 &&
        status > CDVR_OK && status <= CDVR_ERR_CANCELLED) {
        std::string msg = h.rest();
        h.finish();
        return cdvr_plugin_error(err, (cdvr_status)status, "%s", msg.c_str());
    }
    std::string why = h.finish(), said;
    for (char c : got.substr(0, 80))
        said += (unsigned char)c < 32 || (unsigned char)c > 126 ? '?' : c;
    return cdvr_plugin_error(err, CDVR_ERR_FORMAT, "%s: GDCM failed on the DICOM files (the "
                             "helper process %s%s%s%s)", path,
                             why.empty() ? "gave no answer" : why.c_str(),
                             said.empty() ? "" : "; it said '", said.c_str(),
                             said.empty() ? "" : "'");
}

/* The header line "OK X Y Z TYPE s*3 o*3 d*9" into head. */
bool parse_header(const std::string &line, cdvr_volume *head)
{
    if (line.compare(0, 3, "OK ") != 0)
        return false;
    const char *p = line.c_str() + 3;
    char *end;
    double v[19];
    for (int i = 0; i < 19; i++, p = end) {
        v[i] = strtod(p, &end);
        if (end == p)
            return false;
    }
    if (*p)
        return false;
    for (int i = 0; i < 3; i++)
        if (!(v[i] >= 1 && v[i] <= 65535.0 * 65535.0 && v[i] == (double)(size_t)v[i]))
            return false;
    if (!(v[3] >= 0 && v[3] <= 3 && v[3] == (int)v[3]))
        return false;
    for (int i = 0; i < 3; i++)
        head->dims[i] = (size_t)v[i];
    head->timesteps = 1;
    head->type = (cdvr_type)(int)v[3];
    memcpy(head->spacing, v + 4, sizeof head->spacing);
    memcpy(head->origin, v + 7, sizeof head->origin);
    memcpy(head->direction, v + 10, sizeof head->direction);
    memcpy(head->space, "LPS", 4); /* DICOM's patient coordinates (copied by the registry) */
    return true;
}

/* ---- the table ---------------------------------------------------------------------------------- */

int dicom_magic(const uint8_t *head, size_t n)
{
    return n >= 132 && memcmp(head + 128, "DICM", 4) == 0;
}

int dicom_accepts_dir(const char *dir)
{
    try {
        std::vector<std::string> files;
        if (!list_dir(dir, kDirProbeEntries, files))
            return 0;
        for (const std::string &f : files)
            if (has_preamble(f.c_str()))
                return 1;
    } catch (...) {
    }
    return 0;
}

cdvr_status probe_series(const char *path, const cdvr_raw_opts *opts, cdvr_volume *head,
                  cdvr_error *err)
{
    Helper h;
    cdvr_status st = h.start("probe", path, opts, err);
    std::string got;
    if (st == CDVR_OK && (!h.line(got) || !parse_header(got, head)))
        st = helper_failed(h, path, got, err);
    return st;
}

cdvr_status read_series(const char *path, const cdvr_raw_opts *opts, const cdvr_volume *head,
                 void *voxels, cdvr_error *err)
{
    Helper h;
    cdvr_status st = h.start("read", path, opts, err);
    if (st != CDVR_OK)
        return st;
    std::string got;
    cdvr_volume now;
    memset(&now, 0, sizeof now);
    if (!h.line(got) || !parse_header(got, &now))
        return helper_failed(h, path, got, err);
    if (memcmp(now.dims, head->dims, sizeof now.dims) != 0 || now.type != head->type ||
        head->timesteps != 1)
        return cdvr_plugin_error(err, CDVR_ERR_FORMAT, "%s: changed since it was probed", path);
    size_t frame = now.dims[0] * now.dims[1] * type_size(now.type);
    char want[64];
    snprintf(want, sizeof want, "D %zu", frame);
    for (size_t k = 0; k < now.dims[2]; k++) {
        if (!h.line(got) || got != want)
            return helper_failed(h, path, got, err);
        if (!h.exact((char *)voxels + k * frame, frame))
            return helper_failed(h, path, "", err);
    }
    if (!h.line(got) || got != "END")
        return helper_failed(h, path, got, err);
    std::string why = h.rest(); /* nothing after END; waits for the helper's stdout to close */
    if (!why.empty())
        return helper_failed(h, path, why, err);
    why = h.finish();
    if (!why.empty())
        return cdvr_plugin_error(err, CDVR_ERR_FORMAT, "%s: the dicom helper failed after its "
                                 "answer (%s)", path, why.c_str());
    return CDVR_OK;
}

cdvr_status dicom_probe(const char *path, const cdvr_raw_opts *opts, cdvr_volume *head,
                        cdvr_error *err)
{
    try {
        return probe_series(path, opts, head, err);
    } catch (const std::bad_alloc &) {
        return cdvr_plugin_error(err, CDVR_ERR_NOMEM, "%s: out of memory", path);
    } catch (...) {
        return cdvr_plugin_error(err, CDVR_ERR_FORMAT, "%s: the dicom plugin failed", path);
    }
}

cdvr_status dicom_read(const char *path, const cdvr_raw_opts *opts, const cdvr_volume *head,
                       void *voxels, cdvr_error *err)
{
    try {
        return read_series(path, opts, head, voxels, err);
    } catch (const std::bad_alloc &) {
        return cdvr_plugin_error(err, CDVR_ERR_NOMEM, "%s: out of memory", path);
    } catch (...) {
        return cdvr_plugin_error(err, CDVR_ERR_FORMAT, "%s: the dicom plugin failed", path);
    }
}

const char *const dicom_suffixes[] = {".dcm", NULL};

cdvr_format make_format()
{
    cdvr_format f;
    memset(&f, 0, sizeof f);
    f.name = "dicom";
    f.description = "DICOM image series (GDCM plugin): a directory, or a .dcm file's series";
    f.suffixes = dicom_suffixes;
    f.magic = dicom_magic;
    f.probe = dicom_probe;
    f.read = dicom_read; /* no load: the registry allocates from the probe */
    f.accepts_dir = dicom_accepts_dir;
    return f;
}

const cdvr_format dicom_format = make_format();
const cdvr_format *const formats[] = {&dicom_format, NULL};

cdvr_plugin_info make_info()
{
    cdvr_plugin_info info;
    memset(&info, 0, sizeof info);
    info.abi = CDVR_PLUGIN_ABI;
    info.formats = formats;
    return info;
}

const cdvr_plugin_info dicom_plugin = make_info();

} // namespace

extern "C" CDVR_PLUGIN_EXPORT const cdvr_plugin_info *cdvr_plugin_v1(void);
extern "C" CDVR_PLUGIN_EXPORT const cdvr_plugin_info *cdvr_plugin_v1(void)
{
    return &dicom_plugin;
}
