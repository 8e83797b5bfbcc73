/* tests/plugins/dicom_write.cpp - writes the DICOM series tests/test_dicom.sh loads, with GDCM
 * itself (gdcm::ImageWriter), so the test files are what a DICOM library makes, not hand-written
 * bytes. Usage: dicom_write OUTDIR. Built by plugins/dicom/CMakeLists.txt (only with GDCM).
 *
 * Each case is a folder of OUTDIR. Voxel values are exact functions of the spatial index (x the
 * column, y the row, k the slice in position order along the normal), which the C and Lua sides
 * of the test recompute; files are named in an order unrelated to k (f<(N+1-k) mod N>.dcm, N
 * slices; s... for the sagittal series, d... for the second "dup" one) so the
 * loader must sort by ImagePositionPatient.
 *   oblique/  CT, 5 columns x 7 rows x 9 slices, u16 BitsStored 12, stored (3*(x+5y+35k)) % 4096,
 *             RescaleSlope 2, RescaleIntercept -1024 (so i16: 2*stored - 1024), oblique
 *             orientation r = (cos a, sin a, 0), c = (-sin a cos b, cos a cos b, sin b), a = 0.5,
 *             b = 0.3, PixelSpacing 0.9 (rows) \ 0.7 (columns), slice gap 1.3 along r x c,
 *             first position (-20.5, 10.25, 30). Series "1.2.826.0.1.3680043.9.7777.1",
 *             description "oblique ct".
 *   jpegls/   the same voxels and geometry, JPEG-LS lossless (GDCM's codec), series ...7777.2.
 *   two/      two series in one folder: "1.2.826.0.1.3680043.9.7777.3" 'axial' 5x7x3 u16,
 *             stored 100 + x + 5y + 35k, identity orientation, spacing 1 1 2; and
 *             "1.2.826.0.1.3680043.9.7777.4" 'sagittal' 6x4x4 i16 (signed),
 *             stored -500 + 7x + 11y + 13k, spacing 0.5 0.5 3 with r = (0,1,0), c = (0,0,-1).
 *   float/    5x7x3, u16 stored x + 5y + 35k, RescaleSlope 0.5, RescaleIntercept 0.25 (f32).
 *   uneven/   5x7x4 at positions 0, 1, 2, 3.5 along z (refused: the worst gap is the last).
 *   hostile/  5x7x3 like float/, then f1.dcm (slice 0) rewritten with Rows 7000 (the pixels
 *             stay 5x7): more pixels than the file holds.
 *   same_desc/ two series (...7777.8 like float/, ...7777.9 like axial) both described "dup".
 *   tilt/     like float/, slice k shifted 2k mm along the rows (a gantry tilt).
 *   notag/    like float/, f2.dcm without PixelSpacing.
 *   wobble/   like tilt/ but slice k shifted 2 k^2 mm (not one evenly tilted stack).
 *   mono1/    like float/ but MONOCHROME1, BitsStored 12.
 *   enhanced/ one Enhanced CT multi-frame file (multi.dcm) of oblique/'s 9 slices as frames:
 *             GDCM writes the per-frame PlanePositionSequence and the shared orientation,
 *             pixel measures and rescale.
 *   huge/     like float/ but RescaleSlope 1e36: values beyond f32 (refused).
 *   mfsc/     one Multi-frame Grayscale Word Secondary Capture file of float/'s values, 4 frames,
 *             no geometry at all.
 */
#include <cmath>
#include <cstdio>
#include <string>
#include <sys/stat.h>
#include <vector>

#include <gdcmAttribute.h>
#include <gdcmImage.h>
#include <gdcmImageChangeTransferSyntax.h>
#include <gdcmImageWriter.h>
#include <gdcmReader.h>
#include <gdcmTrace.h>
#include <gdcmUIDGenerator.h>
#include <gdcmWriter.h>

namespace {

struct Case {
    std::string dir, uid, description;
    unsigned cols, rows, slices;
    bool is_signed;
    unsigned bits_stored;
    double slope, intercept;
    double origin[3], r[3], c[3], spacing[3]; /* spacing: columns (x), rows (y), slice gap */
    std::vector<double> positions;           /* along the normal; empty: k * spacing[2] */
    bool jpegls;
    int (*value)(unsigned x, unsigned y, unsigned k);
    double tilt = 0;          /* slice k shifted k * tilt mm along r (in its plane) */
    std::string prefix = "f"; /* of the file names */
    bool wobble = false;      /* the shift grows as k * k * tilt (not one tilted stack) */
    bool mono1 = false;       /* PhotometricInterpretation MONOCHROME1 */
};

int v_oblique(unsigned x, unsigned y, unsigned k) { return (int)((3 * (x + 5 * y + 35 * k)) % 4096); }
int v_axial(unsigned x, unsigned y, unsigned k) { return (int)(100 + x + 5 * y + 35 * k); }
int v_sagittal(unsigned x, unsigned y, unsigned k) { return -500 + (int)(7 * x + 11 * y + 13 * k); }
int v_plain(unsigned x, unsigned y, unsigned k) { return (int)(x + 5 * y + 35 * k); }

bool write_slice(const Case &cs, unsigned k, const std::string &file)
{
    gdcm::ImageWriter w;
    gdcm::Image &im = w.GetImage();
    im.SetNumberOfDimensions(2);
    im.SetDimension(0, cs.cols);
    im.SetDimension(1, cs.rows);
    gdcm::PixelFormat pf(cs.is_signed ? gdcm::PixelFormat::INT16 : gdcm::PixelFormat::UINT16);
    pf.SetBitsStored((unsigned short)cs.bits_stored);
    pf.SetHighBit((unsigned short)(cs.bits_stored - 1));
    im.SetPixelFormat(pf);
    im.SetPhotometricInterpretation(cs.mono1 ? gdcm::PhotometricInterpretation::MONOCHROME1
                                             : gdcm::PhotometricInterpretation::MONOCHROME2);
    im.SetTransferSyntax(gdcm::TransferSyntax::ExplicitVRLittleEndian);
    double n[3] = {cs.r[1] * cs.c[2] - cs.r[2] * cs.c[1], cs.r[2] * cs.c[0] - cs.r[0] * cs.c[2],
                   cs.r[0] * cs.c[1] - cs.r[1] * cs.c[0]};
    double d = cs.positions.empty() ? k * cs.spacing[2] : cs.positions[k];
    double origin[3], dircos[6] = {cs.r[0], cs.r[1], cs.r[2], cs.c[0], cs.c[1], cs.c[2]};
    for (int i = 0; i < 3; i++)
        origin[i] = cs.origin[i] + d * n[i] + (cs.wobble ? k * k : k) * cs.tilt * cs.r[i];
    for (unsigned i = 0; i < 3; i++) /* SetOrigin(double[3]) keeps only 2 values of a 2D image */
        im.SetOrigin(i, origin[i]);
    im.SetDirectionCosines(dircos);
    im.SetSpacing(0, cs.spacing[0]);
    im.SetSpacing(1, cs.spacing[1]);
    im.SetSpacing(2, cs.spacing[2]);
    im.SetSlope(cs.slope);
    im.SetIntercept(cs.intercept);
    std::vector<short> px(cs.cols * cs.rows);
    for (unsigned y = 0; y < cs.rows; y++)
        for (unsigned x = 0; x < cs.cols; x++)
            px[x + cs.cols * y] = (short)cs.value(x, y, k);
    gdcm::DataElement pixels(gdcm::Tag(0x7fe0, 0x0010));
    pixels.SetByteValue((const char *)px.data(), (uint32_t)(px.size() * sizeof(short)));
    im.SetDataElement(pixels);

    gdcm::DataSet &ds = w.GetFile().GetDataSet();
    gdcm::UIDGenerator uids;
    gdcm::Attribute<0x0008, 0x0016> sop_class = {gdcm::MediaStorage::GetMSString(
        gdcm::MediaStorage::CTImageStorage)};
    gdcm::Attribute<0x0008, 0x0018> sop_instance = {uids.Generate()};
    gdcm::Attribute<0x0020, 0x000e> series = {cs.uid.c_str()};
    gdcm::Attribute<0x0020, 0x000d> study = {"1.2.826.0.1.3680043.9.7777.100"};
    gdcm::Attribute<0x0008, 0x103e> description = {cs.description.c_str()};
    gdcm::Attribute<0x0008, 0x0060> modality = {"CT"};
    gdcm::Attribute<0x0020, 0x0013> instance = {(int)(k + 1)};
    ds.Replace(sop_class.GetAsDataElement());
    ds.Replace(sop_instance.GetAsDataElement());
    ds.Replace(series.GetAsDataElement());
    ds.Replace(study.GetAsDataElement());
    ds.Replace(description.GetAsDataElement());
    ds.Replace(modality.GetAsDataElement());
    ds.Replace(instance.GetAsDataElement());
    if (cs.jpegls) {
        gdcm::ImageChangeTransferSyntax change;
        change.SetTransferSyntax(gdcm::TransferSyntax::JPEGLSLossless);
        change.SetInput(im);
        if (!change.Change()) {
            fprintf(stderr, "dicom_write: JPEG-LS encoding failed\n");
            return false;
        }
        w.SetImage(change.GetOutput());
    }
    w.SetFileName(file.c_str());
    if (!w.Write()) {
        fprintf(stderr, "dicom_write: cannot write %s\n", file.c_str());
        return false;
    }
    return true;
}

/* One multi-frame file of cs's slices as frames: an Enhanced CT image (GDCM writes the
 * functional groups: per-frame PlanePositionSequence, shared PlaneOrientationSequence,
 * PixelMeasuresSequence and PixelValueTransformationSequence), or (sc) a Multi-frame Grayscale
 * Word Secondary Capture image without any geometry. */
bool write_multiframe(const std::string &out, const Case &cs, bool sc)
{
    std::string dir = out + "/" + cs.dir;
    mkdir(dir.c_str(), 0777);
    gdcm::ImageWriter w;
    gdcm::Image &im = w.GetImage();
    im.SetNumberOfDimensions(3);
    im.SetDimension(0, cs.cols);
    im.SetDimension(1, cs.rows);
    im.SetDimension(2, cs.slices);
    gdcm::PixelFormat pf(gdcm::PixelFormat::UINT16);
    pf.SetBitsStored((unsigned short)cs.bits_stored);
    pf.SetHighBit((unsigned short)(cs.bits_stored - 1));
    im.SetPixelFormat(pf);
    im.SetPhotometricInterpretation(gdcm::PhotometricInterpretation::MONOCHROME2);
    im.SetTransferSyntax(gdcm::TransferSyntax::ExplicitVRLittleEndian);
    double dircos[6] = {cs.r[0], cs.r[1], cs.r[2], cs.c[0], cs.c[1], cs.c[2]};
    if (!sc) {
        for (unsigned i = 0; i < 3; i++)
            im.SetOrigin(i, cs.origin[i]);
        im.SetDirectionCosines(dircos);
        for (unsigned i = 0; i < 3; i++)
            im.SetSpacing(i, cs.spacing[i]);
        im.SetSlope(cs.slope);
        im.SetIntercept(cs.intercept);
    }
    std::vector<unsigned short> px(cs.cols * cs.rows * cs.slices);
    for (unsigned k = 0; k < cs.slices; k++)
        for (unsigned y = 0; y < cs.rows; y++)
            for (unsigned x = 0; x < cs.cols; x++)
                px[x + cs.cols * (y + cs.rows * k)] = (unsigned short)cs.value(x, y, k);
    gdcm::DataElement pixels(gdcm::Tag(0x7fe0, 0x0010));
    pixels.SetByteValue((const char *)px.data(), (uint32_t)(px.size() * sizeof(short)));
    im.SetDataElement(pixels);
    gdcm::DataSet &ds = w.GetFile().GetDataSet();
    gdcm::UIDGenerator uids;
    gdcm::MediaStorage::MSType ms = sc ? gdcm::MediaStorage::MultiframeGrayscaleWordSecondaryCaptureImageStorage
                                       : gdcm::MediaStorage::EnhancedCTImageStorage;
    gdcm::Attribute<0x0008, 0x0016> sop_class = {gdcm::MediaStorage::GetMSString(ms)};
    gdcm::Attribute<0x0008, 0x0018> sop_instance = {uids.Generate()};
    gdcm::Attribute<0x0020, 0x000e> series = {cs.uid.c_str()};
    gdcm::Attribute<0x0020, 0x000d> study = {"1.2.826.0.1.3680043.9.7777.100"};
    gdcm::Attribute<0x0008, 0x103e> description = {cs.description.c_str()};
    ds.Replace(sop_class.GetAsDataElement());
    ds.Replace(sop_instance.GetAsDataElement());
    ds.Replace(series.GetAsDataElement());
    ds.Replace(study.GetAsDataElement());
    ds.Replace(description.GetAsDataElement());
    std::string file = dir + "/multi.dcm";
    w.SetFileName(file.c_str());
    if (!w.Write()) {
        fprintf(stderr, "dicom_write: cannot write %s\n", file.c_str());
        return false;
    }
    return true;
}

bool write_case(const std::string &out, const Case &cs)
{
    std::string dir = out + "/" + cs.dir;
    mkdir(dir.c_str(), 0777);
    for (unsigned k = 0; k < cs.slices; k++) {
        char name[64];
        snprintf(name, sizeof name, "/%s%u.dcm", cs.prefix.c_str(), (cs.slices + 1 - k) % cs.slices);
        if (!write_slice(cs, k, dir + name))
            return false;
    }
    return true;
}

/* hostile/f1.dcm (the file of slice 0, (3+1-0) % 3): Rows 7000. */
bool make_hostile(const std::string &out)
{
    std::string file = out + "/hostile/f1.dcm";
    gdcm::Reader r;
    r.SetFileName(file.c_str());
    if (!r.Read())
        return false;
    gdcm::Attribute<0x0028, 0x0010> rows = {7000};
    r.GetFile().GetDataSet().Replace(rows.GetAsDataElement());
    gdcm::Writer w;
    w.SetFile(r.GetFile());
    w.SetFileName(file.c_str());
    return w.Write();
}

/* notag/f2.dcm without PixelSpacing. */
bool drop_spacing(const std::string &out)
{
    std::string file = out + "/notag/f2.dcm";
    gdcm::Reader r;
    r.SetFileName(file.c_str());
    if (!r.Read())
        return false;
    r.GetFile().GetDataSet().Remove(gdcm::Tag(0x0028, 0x0030));
    gdcm::Writer w;
    w.SetFile(r.GetFile());
    w.SetFileName(file.c_str());
    return w.Write();
}

} // namespace

int main(int argc, char **argv)
{
    gdcm::Trace::SetWarning(false); /* "No PhotometricInterpretation found" from the JPEG-LS path */
    if (argc != 2) {
        fprintf(stderr, "usage: dicom_write OUTDIR\n");
        return 2;
    }
    const std::string out = argv[1];
    const double a = 0.5, b = 0.3;
    Case oblique = {"oblique", "1.2.826.0.1.3680043.9.7777.1", "oblique ct", 5, 7, 9, false, 12,
                    2, -1024, {-20.5, 10.25, 30}, {std::cos(a), std::sin(a), 0},
                    {-std::sin(a) * std::cos(b), std::cos(a) * std::cos(b), std::sin(b)},
                    {0.7, 0.9, 1.3}, {}, false, v_oblique};
    Case jpegls = oblique;
    jpegls.dir = "jpegls";
    jpegls.uid = "1.2.826.0.1.3680043.9.7777.2";
    jpegls.jpegls = true;
    Case axial = {"two", "1.2.826.0.1.3680043.9.7777.3", "axial", 5, 7, 3, false, 16, 1, 0,
                  {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 2}, {}, false, v_axial};
    Case sagittal = {"two", "1.2.826.0.1.3680043.9.7777.4", "sagittal", 6, 4, 4, true, 16, 1, 0,
                     {5, -3, 8}, {0, 1, 0}, {0, 0, -1}, {0.5, 0.5, 3}, {}, false, v_sagittal};
    sagittal.prefix = "s";
    Case flt = {"float", "1.2.826.0.1.3680043.9.7777.5", "float", 5, 7, 3, false, 16, 0.5, 0.25,
                {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 1}, {}, false, v_plain};
    Case uneven = flt;
    uneven.dir = "uneven";
    uneven.uid = "1.2.826.0.1.3680043.9.7777.6";
    uneven.slices = 4;
    uneven.positions = {0, 1, 2, 3.5};
    Case hostile = flt;
    hostile.dir = "hostile";
    hostile.uid = "1.2.826.0.1.3680043.9.7777.7";
    Case dup1 = flt, dup2 = axial, tilt = flt, notag = flt;
    dup1.dir = dup2.dir = "same_desc";
    dup1.description = dup2.description = "dup";
    dup1.uid = "1.2.826.0.1.3680043.9.7777.8";
    dup2.uid = "1.2.826.0.1.3680043.9.7777.9";
    dup2.prefix = "d";
    tilt.dir = "tilt";
    tilt.uid = "1.2.826.0.1.3680043.9.7777.10";
    tilt.tilt = 2;
    notag.dir = "notag";
    notag.uid = "1.2.826.0.1.3680043.9.7777.11";
    Case wobble = tilt, mono1 = flt, enhanced = oblique, mfsc = flt;
    wobble.dir = "wobble";
    wobble.uid = "1.2.826.0.1.3680043.9.7777.12";
    wobble.wobble = true;
    mono1.dir = "mono1";
    mono1.uid = "1.2.826.0.1.3680043.9.7777.13";
    mono1.mono1 = true;
    mono1.bits_stored = 12;
    enhanced.dir = "enhanced";
    enhanced.uid = "1.2.826.0.1.3680043.9.7777.14";
    mfsc.dir = "mfsc";
    mfsc.uid = "1.2.826.0.1.3680043.9.7777.15";
    mfsc.slices = 4;
    Case huge = flt;
    huge.dir = "huge";
    huge.uid = "1.2.826.0.1.3680043.9.7777.16";
    huge.slope = 1e36;
    for (const Case *cs : {&oblique, &jpegls, &axial, &sagittal, &flt, &uneven, &hostile, &dup1,
                           &dup2, &tilt, &notag, &wobble, &mono1, &huge})
        if (!write_case(out, *cs))
            return 1;
    if (!write_multiframe(out, enhanced, false) || !write_multiframe(out, mfsc, true))
        return 1;
    if (!make_hostile(out) || !drop_spacing(out)) {
        fprintf(stderr, "dicom_write: cannot make hostile/f1.dcm or notag/f2.dcm\n");
        return 1;
    }
    return 0;
}
