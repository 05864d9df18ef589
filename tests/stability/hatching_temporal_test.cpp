// Temporal coherence of hatching over the default camera path: frame t-1's output warped by the
// motion pass (the pixel at x in frame t came from x - motion in frame t-1), compared with frame t
// over pixels valid in both (surface in both; disocclusions dropped where the warped world
// position disagrees). Surface-anchored strokes must leave at least 3x less residual than the
// naive screen-space TAM.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <glm/geometric.hpp>

#include "raster/render.h"
#include "shading/hatching/hatch.h"
#include "shading/hatching/tam.h"

namespace posthaste::shading {
namespace {

struct Residual {
    double sum_sq = 0.0;
    std::size_t values = 0;
    double rmse() const { return values ? std::sqrt(sum_sq / double(values)) : 0.0; }
};

/// Adds the residual of `cur` against `prev_out` warped by cur's motion, over valid pixels.
void accumulate_residual(const Frame &prev,
                         const Image &prev_out,
                         const Frame &cur,
                         const Image &cur_out,
                         Residual &r,
                         std::size_t &valid)
{
    const Image &motion = cur.image("motion");
    const Image &pos = cur.image("position"), &ppos = prev.image("position");
    const Image &depth = cur.image("depth"), &pdepth = prev.image("depth");
    const int w = cur_out.width(), h = cur_out.height();
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            const float z = depth.at(x, y, 0);
            if (!std::isfinite(z)) {
                continue;  // sky
            }
            const float sx = float(x) + 0.5f - motion.at(x, y, 0);
            const float sy = float(y) + 0.5f - motion.at(x, y, 1);
            if (sx < 1.0f || sy < 1.0f || sx > float(w) - 1.0f || sy > float(h) - 1.0f) {
                continue;  // came from outside the previous frame
            }
            // Disocclusion: any of the four source pixels is sky or elsewhere in the world.
            bool ok = true;
            const int x0 = int(std::floor(sx - 0.5f)), y0 = int(std::floor(sy - 0.5f));
            const glm::vec3 p{pos.at(x, y, 0), pos.at(x, y, 1), pos.at(x, y, 2)};
            for (int k = 0; k < 4 && ok; ++k) {
                const int xx = x0 + (k & 1), yy = y0 + (k >> 1);
                const glm::vec3 q{ppos.at(xx, yy, 0), ppos.at(xx, yy, 1), ppos.at(xx, yy, 2)};
                ok = std::isfinite(pdepth.at(xx, yy, 0)) && glm::length(q - p) < 0.02f * z + 0.05f;
            }
            if (!ok) {
                continue;
            }
            const glm::vec4 warped = prev_out.sample_bilinear_clamped(sx, sy);
            for (int c = 0; c < 3; ++c) {
                const double d = double(warped[c]) - double(cur_out.at(x, y, c));
                r.sum_sq += d * d;
                ++r.values;
            }
            ++valid;
        }
    }
}

TEST(HatchingTemporal, SurfaceAnchoredBeatsScreenSpace3x)
{
    const raster::Scene scene =
        raster::load_scene(std::string(POSTHASTE_SOURCE_DIR) + "/samples/scenes/minecrappy.json");
    raster::RenderOptions o;
    o.width = 480;
    o.height = 270;
    o.passes = {"color", "depth", "normal", "position", "motion"};
    const Tam tam = build_tam(TamParams{});
    HatchSettings surface, screen;
    screen.screen_space = true;

    // Frames 2-12: the fast translation at the start of the default path.
    Residual rs, rn;
    std::size_t valid = 0, pixels = 0;
    Frame prev = raster::render_frame(scene, 2, o);
    Image prev_s = hatch({&prev.image("color"),
                          &prev.image("depth"),
                          &prev.image("normal"),
                          &prev.image("position")},
                         surface,
                         tam);
    Image prev_n = hatch({&prev.image("color"),
                          &prev.image("depth"),
                          &prev.image("normal"),
                          &prev.image("position")},
                         screen,
                         tam);
    for (int t = 3; t <= 12; ++t) {
        Frame cur = raster::render_frame(scene, t, o);
        const HatchInputs in{
            &cur.image("color"), &cur.image("depth"), &cur.image("normal"), &cur.image("position")};
        Image cur_s = hatch(in, surface, tam), cur_n = hatch(in, screen, tam);
        std::size_t v = 0, unused = 0;
        accumulate_residual(prev, prev_s, cur, cur_s, rs, v);
        accumulate_residual(prev, prev_n, cur, cur_n, rn, unused);
        valid += v;
        pixels += cur_s.pixel_count();
        prev = std::move(cur);
        prev_s = std::move(cur_s);
        prev_n = std::move(cur_n);
    }
    const double ratio = rn.rmse() / std::max(rs.rmse(), 1e-12);
    std::printf(
        "warped residual RMSE over frames 3-12 at %dx%d (%.1f%% of pixels valid): "
        "surface %.4f, screen %.4f, ratio %.2f\n",
        o.width,
        o.height,
        100.0 * double(valid) / double(pixels),
        rs.rmse(),
        rn.rmse(),
        ratio);
    EXPECT_GT(double(valid) / double(pixels), 0.5);
    EXPECT_GE(ratio, 3.0);
}

}  // namespace
}  // namespace posthaste::shading
