// scripts/bench/bc1_squish.cpp - libsquish BC1 (DXT1) on the same 4x4 RGB blocks that PVTC
// <1,3,time> codes: timesteps 3g, 3g+1, 3g+2 as R, G, B (the last group repeats its last
// timestep), z-slice by z-slice. Error is squish's own decode against the input, counted only
// over real timesteps, with the uniform colour metric (metric = NULL: MSE, as for cdvr). Blocks where squish
// chose BC1's 3-colour mode (colour0 <= colour1; PVTC has no such mode) are counted.
//
//   bc1_squish RAW X Y Z T     (raw u8, x fastest, then y, z, t)
#include <squish.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <vector>

namespace {

struct Result {
    double sse = 0;
    long blocks = 0, three_colour = 0;
};

Result run(const std::vector<unsigned char> &data, size_t X, size_t Y, size_t Z, size_t T,
           int flags)
{
    Result r;
    const size_t n = X * Y * Z;
    for (size_t t0 = 0; t0 < T; t0 += 3) {
        size_t nf = T - t0 < 3 ? T - t0 : 3;
        for (size_t z = 0; z < Z; z++)
            for (size_t by = 0; by < Y; by += 4)
                for (size_t bx = 0; bx < X; bx += 4) {
                    unsigned char rgba[64], out[64], block[8];
                    for (int i = 0; i < 16; i++) {
                        size_t x = bx + i % 4 < X ? bx + i % 4 : X - 1;
                        size_t y = by + i / 4 < Y ? by + i / 4 : Y - 1;
                        for (size_t c = 0; c < 3; c++) {
                            size_t t = t0 + (c < nf ? c : nf - 1);
                            rgba[4 * i + c] = data[n * t + x + X * (y + Y * z)];
                        }
                        rgba[4 * i + 3] = 255;
                    }
                    squish::Compress(rgba, block, flags);
                    squish::Decompress(out, block, squish::kDxt1);
                    unsigned c0 = block[0] | block[1] << 8, c1 = block[2] | block[3] << 8;
                    r.three_colour += c0 <= c1;
                    r.blocks++;
                    for (int i = 0; i < 16; i++) {
                        if (bx + i % 4 >= X || by + i / 4 >= Y)
                            continue;
                        for (size_t c = 0; c < nf; c++) {
                            double d = double(rgba[4 * i + c]) - out[4 * i + c];
                            r.sse += d * d;
                        }
                    }
                }
    }
    return r;
}

} // namespace

int main(int argc, char **argv)
{
    if (argc != 6) {
        std::fprintf(stderr, "usage: bc1_squish RAW X Y Z T\n");
        return 2;
    }
    size_t X = std::strtoul(argv[2], nullptr, 10), Y = std::strtoul(argv[3], nullptr, 10);
    size_t Z = std::strtoul(argv[4], nullptr, 10), T = std::strtoul(argv[5], nullptr, 10);
    std::vector<unsigned char> data(X * Y * Z * T);
    FILE *f = std::fopen(argv[1], "rb");
    if (!f || std::fread(data.data(), 1, data.size(), f) != data.size()) {
        std::fprintf(stderr, "%s: cannot read %zu bytes\n", argv[1], data.size());
        return 1;
    }
    std::fclose(f);
    const struct { const char *name; int flags; } fits[] = {
        {"squish_cluster", squish::kDxt1 | squish::kColourClusterFit},
        {"squish_iterative",
         squish::kDxt1 | squish::kColourIterativeClusterFit}};
    std::printf("fit,mse,psnr,blocks,three_colour_blocks\n");
    for (const auto &fit : fits) {
        Result r = run(data, X, Y, Z, T, fit.flags);
        double mse = r.sse / (double(X) * Y * Z * T);
        std::printf("%s,%.4f,%.2f,%ld,%ld\n", fit.name, mse, 10 * std::log10(255.0 * 255 / mse),
                    r.blocks, r.three_colour);
    }
    return 0;
}
