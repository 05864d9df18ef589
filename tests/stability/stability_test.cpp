// Stability suite: every registered node type (sources and sinks aside) on every hostile frame,
// with its defaults and its own parameter sets (stability_cases.cpp). Results go to
// stability.json in the working directory (build/ under ctest).

#include "stability/stability.h"

#include <gtest/gtest.h>

#include <limits>

#include "core/error.h"
#include "nodes/registry.h"

namespace posthaste::stability {
namespace {

std::vector<std::string> tested_types()
{
    std::vector<std::string> types;
    for (const NodeType *t : all_node_types()) {
        if (!skipped_types().count(std::string(t->spec.type))) {
            types.emplace_back(t->spec.type);
        }
    }
    return types;
}

class Stability : public ::testing::TestWithParam<std::string> {};

TEST_P(Stability, FiniteAndBoundedOnHostileFrames)
{
    const NodeType *type = find_node_type(GetParam());
    ASSERT_NE(type, nullptr);
    const NodeCases cases = node_cases(GetParam());
    std::vector<std::pair<std::string, std::vector<std::string>>> sets = {{"defaults", {}}};
    sets.insert(sets.end(), cases.param_sets.begin(), cases.param_sets.end());
    std::vector<HostileFrame> frames = hostile_frames();
    if (cases.extra_frames) {
        for (HostileFrame &f : cases.extra_frames()) {
            frames.push_back(std::move(f));
        }
    }
    for (const auto &[set_name, overrides] : sets) {
        for (const HostileFrame &f : frames) {
            SCOPED_TRACE(GetParam() + " " + set_name + " on " + f.name + " (" + f.what + ")");
            StabilityResult r = run_case(*type, overrides, f.frame, cases.bound);
            r.params = set_name;
            r.frame = f.name;
            const auto known = cases.known_failures.find(set_name + "/" + f.name);
            if (known != cases.known_failures.end() && r.status != "ok") {
                r.status = "known_failure";
                r.message += " [known: " + known->second + "]";
            }
            record(r);
            EXPECT_TRUE(r.status == "ok" || r.status == "rejected" || r.status == "known_failure")
                << r.status << ": " << r.message;
            if (f.name == "plain") {
                EXPECT_EQ(r.status, "ok") << "the control frame must work: " << r.message;
            }
        }
    }
}

INSTANTIATE_TEST_SUITE_P(AllNodes,
                         Stability,
                         ::testing::ValuesIn(tested_types()),
                         [](const ::testing::TestParamInfo<std::string> &info) {
                             return info.param;
                         });

TEST(StabilityHarness, DetectsSpreadingAndUnboundedOutput)
{
    // A deliberately bad node: turns every value into 1/(x - x) (NaN everywhere) and writes a
    // huge value; the harness must flag it as unstable.
    static constexpr PortSpec kInputs[] = {{"image", "", false, ""}};
    static const NodeType kBad{{"bad", "", kInputs, {}, ""}, [](NodeContext &ctx) {
                                   Image img(
                                       ctx.input("image").width(), ctx.input("image").height(), 1);
                                   img.fill(std::numeric_limits<float>::quiet_NaN());
                                   img.at(0, 0, 0) = 1e30f;
                                   ctx.output().set("junk", std::move(img));
                               }};
    const StabilityResult r = run_case(kBad, {}, plain_frame(4, 4), kDefaultBound);
    EXPECT_EQ(r.status, "unstable");
    EXPECT_EQ(r.spread, 15);
    EXPECT_EQ(r.max_abs, double(1e30f));
    static const NodeType kRefuses{{"refuses", "", kInputs, {}, ""}, [](NodeContext &ctx) {
                                       throw_runtime(ctx.where(), ": no thanks");
                                   }};
    EXPECT_EQ(run_case(kRefuses, {}, plain_frame(2, 2), kDefaultBound).status, "rejected");
    // Hostile frames really are hostile.
    int with_nan = 0;
    for (const HostileFrame &f : hostile_frames()) {
        with_nan += f.name == "nan_everywhere" ? 1 : 0;
        EXPECT_FALSE(f.frame.passes().empty()) << f.name;
    }
    EXPECT_EQ(with_nan, 1);
}

}  // namespace
}  // namespace posthaste::stability
