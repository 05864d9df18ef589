// The non-finite policy (docs/ARCHITECTURE.md, "Non-finite input"): spatial nodes never spread
// a NaN or infinity to a neighbour and never output one, whatever their input holds; point
// nodes pass values through. Every spatial node runs on a frame with NaN, +Inf and -Inf in
// color (one pixel in ten) and in the data passes it reads.

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "core/passes.h"
#include "nodes/registry.h"
#include "stability/stability.h"
#include "test_util.h"

namespace posthaste {
namespace {

/// `f` with one value in ten of every pass replaced by NaN, +Inf or -Inf (depth keeps +inf,
/// the sky, as a legal value and gets NaN and -inf), or with `huge` by +-3.4e38 and 1e38.
Frame poisoned(Frame f, bool huge = false)
{
    const float big = std::numeric_limits<float>::max();
    const float bad[3] = {huge ? big : std::numeric_limits<float>::quiet_NaN(),
                          huge ? -big : std::numeric_limits<float>::infinity(),
                          huge ? 1e38f : -std::numeric_limits<float>::infinity()};
    for (const std::string &name : f.pass_names()) {
        Image img = f.image(name);
        for (std::size_t i = 0; i < img.value_count(); ++i) {
            if (i % 10 == 3) {
                img.data()[i] = bad[(i / 10) % 3];
            }
        }
        f.set(name, std::move(img));
    }
    return f;
}

std::size_t non_finite(const Image &img)
{
    std::size_t n = 0;
    for (std::size_t i = 0; i < img.value_count(); ++i) {
        n += !std::isfinite(img.data()[i]);
    }
    return n;
}

/// Every spatial node with settings that reach its gathers.
const std::vector<std::pair<std::string, std::string>> &spatial_cases()
{
    static const std::vector<std::pair<std::string, std::string>> cases = {
        {"dof", "{}"},
        {"dof", R"({"resolution": "half"})"},
        {"motion_blur", "{}"},
        {"motion_blur", R"({"source": "camera"})"},
        {"fog", R"({"model": "exp", "density": 0.05})"},
        {"fog", R"({"model": "height"})"},
        {"fog", R"({"model": "atmosphere"})"},
        {"relight", R"({"lights": [{"type": "point", "position": [0, 3, 0], "intensity": 20}]})"},
        {"hatching", "{}"},
        {"bloom", "{}"},
        {"lens", R"({"k1": -0.05, "chromatic_aberration": 0.01})"},
        {"bloom", R"({"method": "fft", "diffraction_scale": 10})"},
        {"reformat", R"({"scale": 0.37})"},
        {"transform", R"({"rotate": 20, "scale": 1.3})"},
        {"transform", R"({"rotate": 20, "scale": 1.3, "filter": "lanczos3"})"},
        {"blur", R"({"sigma": 3})"},
        {"sharpen", R"({"amount": 2})"},
        {"ssr", "{}"},
    };
    return cases;
}

TEST(NonFinitePolicy, SpatialNodesNeverOutputNaNOrInf)
{
    const Frame in = poisoned(stability::plain_frame(48, 32));
    ASSERT_GT(non_finite(in.image("color")), 100u);
    for (const auto &[type, params] : spatial_cases()) {
        SCOPED_TRACE(type + " " + params);
        const Frame out = test::run_node(type, in, params);
        EXPECT_EQ(non_finite(out.image("color")), 0u);
    }
}

TEST(NonFinitePolicy, SpatialNodesKeepFloatsLargestValuesFinite)
{
    // Values near float's largest are finite, but a gather's sum of two overflows: bloom's FFT
    // made 10,356 NaN and 15,345 infinities of a 160x90 frame with 17 such pixels, sharpen,
    // lens and a Lanczos transform infinities and NaN. Spatial nodes read at most 1e30.
    const Frame in = poisoned(stability::plain_frame(48, 32), true);
    ASSERT_EQ(non_finite(in.image("color")), 0u);
    // ssgi and ao add to or scale each pixel's colour (a NaN there stays, as in a point node),
    // but their gathers must not overflow either.
    auto cases = spatial_cases();
    cases.emplace_back("ssgi", "{}");
    cases.emplace_back("ao", "{}");
    for (const auto &[type, params] : cases) {
        SCOPED_TRACE(type + " " + params);
        const Frame out = test::run_node(type, in, params);
        EXPECT_EQ(non_finite(out.image("color")), 0u);
    }
}

TEST(NonFinitePolicy, AoPassIsFiniteOnPoisonedDepthAndNormals)
{
    // ao gathers depth and normals: its own pass stays finite. Its `apply: multiply` is a point
    // operation on color, which passes NaN and Inf through like the other point nodes.
    const Frame in = poisoned(stability::plain_frame(48, 32));
    const Frame out = test::run_node("ao", in, R"({"apply": "multiply"})");
    EXPECT_EQ(non_finite(out.image("ao")), 0u);
}

TEST(NonFinitePolicy, PointNodesPassValuesThrough)
{
    const Frame in = poisoned(stability::plain_frame(16, 8));
    const Frame out = test::run_node("channels", in, R"({"keep": "color"})");
    EXPECT_TRUE(out.image("color").bit_equal(in.image("color")));
}

}  // namespace
}  // namespace posthaste
