// Golden-image tests: each tests/golden/<case>/graph.json runs on analytic input frames and its
// output is compared with <case>/expected.exr within OIIO testsuite tolerances (fail 0.004,
// failpercent 0.02, hardfail 0.012). On failure, actual.exr and diff.exr (|a-b| x 16) are kept
// in the scratch directory. POSTHASTE_UPDATE_GOLDEN=1 rewrites the references.

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>

#include "graph/graph.h"
#include "io/image_file.h"
#include "io/sequence.h"
#include "metrics/metrics.h"
#include "test_util.h"

namespace posthaste {
namespace {

namespace fs = std::filesystem;

TEST(Golden, EveryCaseMatchesItsReference)
{
    const bool update = std::getenv("POSTHASTE_UPDATE_GOLDEN") != nullptr;
    int cases = 0;
    for (const auto &entry : fs::directory_iterator(fs::path(POSTHASTE_TEST_DIR) / "golden")) {
        if (!entry.is_directory() || !fs::exists(entry.path() / "graph.json")) {
            continue;
        }
        ++cases;
        const std::string name = entry.path().filename().string();
        SCOPED_TRACE(name);
        const std::string dir = test::scratch_dir("golden_" + name);
        for (int f = 1; f <= 2; ++f) {
            WriteOptions o;
            o.storage["color"] = PixelStorage::Float;
            write_exr(test::make_sample_frame(96, 64, f),
                      expand_frame_pattern(dir + "/in.####.exr", f),
                      o);
        }
        Graph g = Graph::load(
            (entry.path() / "graph.json").string(),
            {"src.path=" + dir + "/in.####.exr", "out.path=" + dir + "/actual.####.exr"});
        g.check({2});
        g.evaluate(2);
        const std::string actual = dir + "/actual.0002.exr";
        const std::string expected = (entry.path() / "expected.exr").string();
        if (!update && !fs::exists(expected)) {
            ADD_FAILURE() << expected << " is missing; POSTHASTE_UPDATE_GOLDEN=1 writes it";
            continue;
        }
        if (update) {
            fs::copy_file(actual, expected, fs::copy_options::overwrite_existing);
            std::printf("golden %s: reference written\n", name.c_str());
            continue;
        }
        const Frame a = read_frame(actual, nullptr, 2);
        const Frame b = read_frame(expected, nullptr, 2);
        ASSERT_EQ(a.pass_names(), b.pass_names());
        metrics::Thresholds t;
        t.fail = 0.004f;
        t.fail_percent = 0.02f;
        t.hard_fail = 0.012f;
        t.warn = 0.004f;
        t.warn_percent = 0.02f;
        for (const std::string &p : a.pass_names()) {
            const metrics::CompareStats s = metrics::compare(a.image(p), b.image(p), t);
            const metrics::Verdict v = metrics::verdict(s, t);
            if (v != metrics::Verdict::Pass) {
                Frame d;
                d.set(p, metrics::difference_image(a.image(p), b.image(p), 16.0f));
                write_exr(d, dir + "/diff.exr", {});
            }
            EXPECT_EQ(v, metrics::Verdict::Pass)
                << "pass " << p << ": max error " << s.all.max_error << " at (" << s.all.max_x
                << ", " << s.all.max_y << ") channel " << s.all.max_channel << "; "
                << s.all.fail_count << " pixels over 0.004; see " << dir;
        }
    }
    EXPECT_GE(cases, 1);
}

}  // namespace
}  // namespace posthaste
