// Parameters bound to settings fields (graph/param_bind.h): the catalog's bindings agree with
// their specs, and fill() converts, skips and falls back on the header as declared.

#include "graph/param_bind.h"

#include <gtest/gtest.h>

#include <map>

#include "core/error.h"
#include "graph/graph.h"
#include "graph/mask.h"
#include "graph/param_json.h"
#include "nodes/registry.h"

namespace posthaste {
namespace {

// Every node's bindings: each bound parameter declared, each field able to hold its values, and
// each settings struct's own default the parameter's default.
TEST(ParamBind, EveryBindingInTheCatalogAgreesWithItsSpec)
{
    std::vector<std::string> problems;
    int audited = 0;
    for (const NodeType *t : nodes::catalog().all()) {
        if (t->audit) {
            t->audit(problems);
            ++audited;
        }
        if (t->spec.maskable) {
            audit(*t, kMaskFields, problems);  // the mask's parameters, declared once for all
        }
    }
    std::string all;
    for (const std::string &p : problems) {
        all += p + "\n";
    }
    EXPECT_TRUE(problems.empty()) << all;
    EXPECT_GE(audited, 1);
}

enum class Shape { Disc, Polygon, Star };

struct Settings {
    float radius = 1.0f;
    int samples = 16;
    std::uint32_t seed = 1;
    bool fast = false;
    bool half = false;
    Shape shape = Shape::Disc;
    int size = 256;
    glm::vec3 tint{1.0f, 1.0f, 1.0f};
    std::string name = "a";
    std::vector<std::string> list;
    double fstop = 8.0;
    float shutter = 0.5f;
    float focus = 0.0f;
};

constexpr ParamSpec kRadius = ParamSpec::real("radius", 1.0).range(0.0, 10.0);
constexpr ParamSpec kSamples = ParamSpec::integer("samples", 16).range(1, 64);
constexpr ParamSpec kSeed = ParamSpec::integer("seed", 1).at_least(0);
constexpr ParamSpec kFast = ParamSpec::boolean("fast", false);
constexpr ParamSpec kResolution = ParamSpec::choice("resolution", "full|half", "full");
constexpr ParamSpec kShape =
    ParamSpec::choice("shape", "disc|polygon|star", "disc").only_when("fast", "false");
constexpr ParamSpec kSize = ParamSpec::choice("size", "64|128|256", "256");
constexpr ParamSpec kTint = ParamSpec::vec3("tint", 1.0, 1.0, 1.0);
constexpr ParamSpec kName = ParamSpec::string("name", "a");
constexpr ParamSpec kList = ParamSpec::string("list", "");
constexpr ParamSpec kFstop =
    ParamSpec::real("fstop", 8.0).range(0.5, 128.0).from_header("aperture");
constexpr ParamSpec kShutter =
    ParamSpec::real("shutter", 0.5).range(0.0, 1.0).from_header("shutter");
constexpr ParamSpec kFocus = ParamSpec::real("focus", 0.0).at_least(0.0).from_header_only("focus");
constexpr ParamSpec kParams[] = {kRadius,
                                 kSamples,
                                 kSeed,
                                 kFast,
                                 kResolution,
                                 kShape,
                                 kSize,
                                 kTint,
                                 kName,
                                 kList,
                                 kFstop,
                                 kShutter,
                                 kFocus};

constexpr Binding<Settings> kFields[] = {
    bind<&Settings::radius>(kRadius),
    bind<&Settings::samples>(kSamples),
    bind<&Settings::seed>(kSeed),
    bind<&Settings::fast>(kFast),
    bind<&Settings::half>(kResolution, "half"),
    bind<&Settings::shape>(kShape),
    bind<&Settings::size>(kSize),
    bind<&Settings::tint>(kTint),
    bind<&Settings::name>(kName),
    bind<&Settings::list>(kList),
    bind<&Settings::fstop>(kFstop),
    bind<&Settings::shutter>(kShutter),
    bind<&Settings::focus>(kFocus),
};

void no_op(NodeContext &) {}
const NodeType kToy{{"toy", "", {}, kParams, ""}, &no_op};

NodeParams params(std::map<std::string, nlohmann::json> given)
{
    std::map<std::string, ParamValue> values;
    for (const ParamSpec &s : kParams) {
        const auto it = given.find(std::string(s.name));
        values[std::string(s.name)] =
            it == given.end() ? default_param(s) : convert_param(s, it->second, "t", "toy");
    }
    return NodeParams(&kToy, std::move(values));
}

TEST(ParamBind, FillConvertsEachFieldType)
{
    const Settings s = fill(params({{"radius", 2.5},
                                    {"samples", 32},
                                    {"seed", 7},
                                    {"resolution", "half"},
                                    {"shape", "star"},
                                    {"size", "64"},
                                    {"tint", {0.5, 0.25, 2.0}},
                                    {"name", "b"},
                                    {"list", "x, y,,z"}}),
                            kFields);
    EXPECT_EQ(s.radius, 2.5f);
    EXPECT_EQ(s.samples, 32);
    EXPECT_EQ(s.seed, 7u);
    EXPECT_TRUE(s.half);
    EXPECT_EQ(s.shape, Shape::Star);
    EXPECT_EQ(s.size, 64);
    EXPECT_EQ(s.tint, glm::vec3(0.5f, 0.25f, 2.0f));
    EXPECT_EQ(s.name, "b");
    EXPECT_EQ(s.list, (std::vector<std::string>{"x", "y", "z"}));
}

// A parameter whose only_when does not hold leaves the field as it was.
TEST(ParamBind, FillLeavesAFieldWhoseConditionDoesNotHold)
{
    Settings s;
    s.shape = Shape::Polygon;
    fill_into(s, params({{"fast", true}}), std::span<const Binding<Settings>>(kFields));
    EXPECT_TRUE(s.fast);
    EXPECT_EQ(s.shape, Shape::Polygon);
    fill_into(s, params({}), std::span<const Binding<Settings>>(kFields));
    EXPECT_EQ(s.shape, Shape::Disc);
}

struct Toy {
    NodeIdentity id{"t", "toy", "g.json:/nodes/0"};
    NodeParams p;
    PassSet requested;
    NodeState state;
    Camera camera;
    OIIO::ParamValueList attributes;
    Settings run()
    {
        NodeContext ctx(id, p, {}, {}, requested, 1, state);
        return fill(ctx, kFields, HeaderSource{&camera, &attributes});
    }
};

TEST(ParamBind, HeaderFallbackTakesAValidHeaderValueUnlessGiven)
{
    Toy t;
    t.p = params({});
    t.camera.fstop = 2.8f;
    t.camera.shutter = 0.25f;
    t.camera.focus_distance = 4.0f;
    Settings s = t.run();
    EXPECT_EQ(s.fstop, double(2.8f));
    EXPECT_EQ(s.shutter, 0.25f);
    EXPECT_EQ(s.focus, 4.0f);
    t.p = params({{"fstop", 11.0}, {"focus", 2.0}});
    s = t.run();
    EXPECT_EQ(s.fstop, 11.0);
    EXPECT_EQ(s.focus, 2.0f);
    EXPECT_EQ(s.shutter, 0.25f);
}

// No header value leaves the default (with a note); a header value out of the parameter's range
// is an error naming the parameter, the attribute and the value; a from_header_only parameter
// without a header value is an error naming it and the attribute.
TEST(ParamBind, HeaderFallbackRefusesWhatTheSpecWouldNot)
{
    Toy t;
    t.p = params({});
    t.camera.focus_distance = 3.0f;
    const Settings s = t.run();
    EXPECT_EQ(s.fstop, 8.0);
    EXPECT_EQ(s.shutter, 0.5f);
    const auto message = [&] {
        try {
            t.run();
        } catch (const Error &e) {
            EXPECT_EQ(e.code(), ExitCode::Runtime);
            return std::string(e.what());
        }
        return std::string("no error");
    };
    t.camera.fstop = 0.0f;
    EXPECT_EQ(message(),
              "node \"t\" (toy), frame 1: param \"fstop\": not given, and the frame's header "
              "\"aperture\" is 0, outside 0.5..128 (give fstop)");
    t.camera.fstop.reset();
    t.camera.shutter = std::numeric_limits<float>::quiet_NaN();
    EXPECT_EQ(message(),
              "node \"t\" (toy), frame 1: param \"shutter\": not given, and the frame's header "
              "\"shutter\" is nan, outside 0..1 (give shutter)");
    t.camera.shutter.reset();
    t.camera.focus_distance.reset();
    EXPECT_EQ(message(),
              "node \"t\" (toy), frame 1: param \"focus\": not given, and the frame's header "
              "has no \"focus\"");
    t.p = params({{"focus", 1.0}});
    EXPECT_EQ(t.run().focus, 1.0f);
    t.camera.fstop = 0.0f;
    t.p = params({{"focus", 1.0}, {"fstop", 2.0}});
    EXPECT_EQ(t.run().fstop, 2.0);  // a given value never reads the header
}

TEST(ParamBind, ErrorsHaveOneShape)
{
    try {
        throw_param_expected("g.json:/nodes/2/params: node \"d\" (dof)", "blades", "0 or 3..16", 2);
        FAIL();
    } catch (const Error &e) {
        EXPECT_EQ(e.code(), ExitCode::Usage);
        EXPECT_EQ(std::string(e.what()),
                  "g.json:/nodes/2/params: node \"d\" (dof): param \"blades\": expected 0 or "
                  "3..16, got 2");
    }
}

// The audit names each disagreement: a drifted default, a field that cannot hold the values, a
// parameter the node does not declare.
struct Drifted {
    float radius = 2.0f;
    int shape = 0;
    float other = 0.0f;
};
constexpr ParamSpec kUndeclared = ParamSpec::real("undeclared", 0.0);
constexpr Binding<Drifted> kDrifted[] = {bind<&Drifted::radius>(kRadius),
                                         bind<&Drifted::shape>(kShape),
                                         bind<&Drifted::other>(kUndeclared)};

TEST(ParamBind, AuditNamesEachDisagreement)
{
    std::vector<std::string> problems;
    audit(kToy, kFields, problems);
    EXPECT_TRUE(problems.empty());
    audit(kToy, kDrifted, problems);
    ASSERT_EQ(problems.size(), 3u);
    EXPECT_EQ(problems[0], "toy: param \"radius\": default 1, but its settings field starts at 2");
    EXPECT_EQ(problems[1],
              "toy: param \"shape\": an integer field takes a choice only among whole numbers");
    EXPECT_EQ(problems[2], "toy: param \"undeclared\": bound but not declared by the node");
}

// A parameter the chosen method ignores is refused, naming both (here ao's, render's and
// motion_blur's method-specific parameters).
TEST(ParamBind, AParameterTheMethodIgnoresIsRefused)
{
    const auto error_of = [](const std::string &node, const std::string &params) {
        const std::string g =
            R"({"nodes": [{"id": "r", "type": "render", "params": {"scene": "s.json"}},)"
            R"( {"id": "n", )" +
            std::string(node == "render" ? "" : R"("inputs": {"image": "r"}, )") + R"("type": ")" +
            node + R"(", "params": )" + params + "}]}";
        try {
            Graph::parse(g, "g.json", nodes::catalog());
        } catch (const Error &e) {
            return std::string(e.what());
        }
        return std::string("accepted");
    };
    EXPECT_NE(error_of("ao", R"({"method": "trace", "slices": 4})")
                  .find("param \"slices\" applies only when method is gtao or bitmask, not trace"),
              std::string::npos);
    EXPECT_NE(error_of("ao", R"({"method": "gtao", "rays": 16})")
                  .find("param \"rays\" applies only when method is trace, not gtao"),
              std::string::npos);
    EXPECT_NE(error_of("ao", R"({"thickness": 2})")
                  .find("param \"thickness\" applies only when method is bitmask or trace"),
              std::string::npos);
    EXPECT_NE(error_of("render", R"({"scene": "s.json", "ao_radius": 2})")
                  .find("param \"ao_radius\" applies only when truth is ao, not none"),
              std::string::npos);
    EXPECT_NE(error_of("motion_blur", R"({"method": "uniform", "coherence": 0.2})")
                  .find("param \"coherence\" applies only when method is reconstruct"),
              std::string::npos);
}

}  // namespace
}  // namespace posthaste
