// The graph engine: validation with located messages, --set overrides, pass planning (sources
// asked only for what is used), node results on hand-computed pixels, the OCIO check value, and
// bit-identical output for 1 and N threads.

#include "graph/graph.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>

#include "core/error.h"
#include "core/parallel.h"
#include "io/color.h"
#include "io/image_file.h"
#include "nodes/registry.h"
#include "test_util.h"

namespace posthaste {
namespace {

using test::make_sample_frame;
using test::scratch_dir;

std::string error_of(const std::string &json, const std::vector<std::string> &sets = {})
{
    try {
        Graph::parse(json, "g.json", nodes::catalog(), sets);
    } catch (const Error &e) {
        EXPECT_EQ(e.code(), ExitCode::Usage) << e.what();
        return e.what();
    }
    return "";
}

#define EXPECT_CONTAINS(haystack, needle) \
    EXPECT_NE(std::string(haystack).find(needle), std::string::npos) << (haystack)

const char *kReadWrite = R"({"nodes": [
    {"id": "src", "type": "read", "params": {"path": "in.####.exr"}},
    {"id": "out", "type": "write", "inputs": {"image": "src"}, "params": {"path": "o.####.exr"}}]})";

TEST(GraphValidation, LocatedMessages)
{
    EXPECT_EQ(error_of(kReadWrite), "");
    EXPECT_CONTAINS(error_of("{\"nodes\": [\n  {\"id\": 1,}\n]}"), "g.json: line 2, column");
    EXPECT_CONTAINS(error_of(R"({"nodes": [{"id": "a", "type": "reed"}]})"),
                    "g.json:/nodes/0/type: node \"a\": unknown node type \"reed\" (did you mean "
                    "\"read\"?)");
    EXPECT_CONTAINS(error_of(R"({"nodes": [{"id": "a", "type": "read", "params": {"pth": "x"}}]})"),
                    "g.json:/nodes/0/params/pth: node \"a\" (read): unknown param \"pth\" (did you "
                    "mean \"path\"?)");
    EXPECT_CONTAINS(error_of(R"({"nodes": [{"id": "a", "type": "read", "params": {"path": 3}}]})"),
                    "param \"path\": expected string, got 3");
    EXPECT_CONTAINS(
        error_of(
            R"({"nodes": [{"id": "a", "type": "read", "params": {"path": "x", "frame_offset": 1.5}}]})"),
        "param \"frame_offset\": expected integer, got 1.5");
    // A whole number past int's range is out of the parameter's range, said with the range
    // (its bound was printed as 2.14748e+09; the message said only "expected integer").
    EXPECT_CONTAINS(
        error_of(R"({"nodes": [{"id": "r", "type": "render", "params": {"seed": 2147483648}}]})"),
        "param \"seed\": expected integer in 0..2147483647, got 2147483648");
    EXPECT_CONTAINS(error_of(R"({"nodes": [{"id": "a", "type": "read"}]})"),
                    "node \"a\" (read): required param \"path\" is missing");
    EXPECT_CONTAINS(
        error_of(R"({"nodes": [
        {"id": "a", "type": "read", "params": {"path": "x"}},
        {"id": "m", "type": "merge", "inputs": {"b": "a", "a": "a"}, "params": {"mix": 2}},
        {"id": "o", "type": "write", "inputs": {"image": "m"}, "params": {"path": "o.exr"}}]})"),
        "g.json:/nodes/1/params/mix: node \"m\" (merge): param \"mix\": expected number "
        "in 0..1, got 2");
    EXPECT_CONTAINS(
        error_of(R"({"nodes": [
        {"id": "a", "type": "read", "params": {"path": "x"}},
        {"id": "m", "type": "merge", "inputs": {"b": "a", "a": "a"}, "params": {"operation": "ovr"}},
        {"id": "o", "type": "write", "inputs": {"image": "m"}, "params": {"path": "o.exr"}}]})"),
        "expected one of over|under|add|subtract|multiply|max|min|mix, got \"ovr\" (did "
        "you mean \"over\"?)");
    EXPECT_CONTAINS(error_of(R"({"nodes": [
        {"id": "a", "type": "read", "params": {"path": "x"}},
        {"id": "m", "type": "merge", "inputs": {"b": "a"}},
        {"id": "o", "type": "write", "inputs": {"image": "m"}, "params": {"path": "o.exr"}}]})"),
                    "node \"m\" (merge): required input \"a\" is not connected");
    EXPECT_CONTAINS(error_of(R"({"nodes": [
        {"id": "a", "type": "read", "params": {"path": "x"}},
        {"id": "o", "type": "write", "inputs": {"img": "a"}, "params": {"path": "o.exr"}}]})"),
                    "unknown input \"img\" (did you mean \"image\"?)");
    EXPECT_CONTAINS(error_of(R"({"nodes": [
        {"id": "a", "type": "read", "params": {"path": "x"}},
        {"id": "o", "type": "write", "inputs": {"image": "b"}, "params": {"path": "o.exr"}}]})"),
                    "input \"image\" names unknown node \"b\" (did you mean \"a\"?)");
    EXPECT_CONTAINS(error_of(R"({"nodes": [
        {"id": "a", "type": "read", "params": {"path": "x"}},
        {"id": "a", "type": "write", "inputs": {"image": "a"}, "params": {"path": "o.exr"}}]})"),
                    "duplicate node id \"a\"");
    EXPECT_CONTAINS(error_of(R"({"nodes": [
        {"id": "a", "type": "ocio", "inputs": {"image": "b"}},
        {"id": "b", "type": "ocio", "inputs": {"image": "a"}},
        {"id": "o", "type": "write", "inputs": {"image": "b"}, "params": {"path": "o.exr"}}]})"),
                    "is in a cycle");
    EXPECT_CONTAINS(
        error_of(R"({"nodes": [{"id": "a", "type": "read", "params": {"path": "x"}}]})"),
        "the graph has no sink (write) node");
    EXPECT_CONTAINS(error_of(R"({"nodes": [
        {"id": "a", "type": "read", "params": {"path": "x"}},
        {"id": "o", "type": "write", "inputs": {"image": "a"}, "params": {"path": "out/o.exr"}},
        {"id": "p", "type": "write", "inputs": {"image": "a"},
         "params": {"path": "out/./o.exr", "compression": "zip"}}]})"),
                    "g.json:/nodes/2/params/path: node \"p\" (write): writes the same files as "
                    "node \"o\" (write)");
    {
        // f.###.exr and f.####.exr are different files until frame 1000: a run that reaches it
        // is refused before any frame is written.
        const Graph g = Graph::parse(std::string(R"({"nodes": [
            {"id": "a", "type": "render", "params": {"width": 8, "height": 8, "scene": ")") +
                                         POSTHASTE_TEST_DIR +
                                         R"(/../samples/scenes/minecrappy.json"}},
            {"id": "o", "type": "write", "inputs": {"image": "a"}, "params": {"path": "f.###.exr"}},
            {"id": "p", "type": "write", "inputs": {"image": "a"},
             "params": {"path": "f.####.exr"}}]})",
                                     "g.json",
                                     nodes::catalog());
        EXPECT_NO_THROW(g.check({1, 999}));
        try {
            g.check({998, 1000});
            ADD_FAILURE() << "frame 1000 written twice";
        } catch (const Error &e) {
            EXPECT_NE(std::string(e.what()).find("writes the same files as node \"o\" (write) "
                                                 "(\"f.####.exr\" at frame 1000)"),
                      std::string::npos)
                << e.what();
        }
    }
    EXPECT_CONTAINS(error_of(R"({"nodes": [
        {"id": "a", "type": "read", "params": {"path": "x", "path": "y"}},
        {"id": "o", "type": "write", "inputs": {"image": "a"}, "params": {"path": "o.exr"}}]})"),
                    "g.json: key \"path\" in \"params\" is given twice (JSON would keep only "
                    "the last)");
    EXPECT_CONTAINS(error_of(R"({"frames": "1", "frames": "2", "nodes": []})"),
                    "key \"frames\" in the top level is given twice");
    EXPECT_CONTAINS(error_of(R"({"nodes": [
        {"id": "a", "type": "read", "params": {"path": "x"}},
        {"id": "f", "type": "fog", "inputs": {"image": "a"},
         "params": {"model": "atmosphere", "sun_illuminance": [1e38, 1, 1]}},
        {"id": "o", "type": "write", "inputs": {"image": "f"}, "params": {"path": "o.exr"}}]})"),
                    "param \"sun_illuminance\": expected array of 3 numbers in 0..1e+06, got "
                    "[1e+38,1,1]");
    EXPECT_CONTAINS(error_of(R"({"nodez": []})"),
                    "unknown key \"nodez\" (did you mean \"nodes\"?)");
    EXPECT_CONTAINS(error_of(R"({"frames": "5-1", "nodes": [{"id": "a", "type": "read"}]})"),
                    "range end 1 is before its start 5");
}

TEST(GraphValidation, SetOverridesUseTheSameChecks)
{
    const Graph g = Graph::parse(
        kReadWrite, "g.json", nodes::catalog(), {"out.compression=zip", "src.frame_offset=3"});
    EXPECT_EQ(g.nodes()[0].params.values().at("frame_offset").number, 3.0);
    EXPECT_EQ(g.nodes()[1].params.values().at("compression").text, "zip");
    EXPECT_CONTAINS(error_of(kReadWrite, {"src.frame_offset=abc"}),
                    "--set src.frame_offset=abc: node \"src\" (read): param \"frame_offset\": "
                    "expected integer, got \"abc\"");
    EXPECT_CONTAINS(error_of(kReadWrite, {"sr.path=x"}),
                    "unknown node \"sr\" (did you mean \"src\"?)");
    EXPECT_CONTAINS(error_of(kReadWrite, {"src.pat=x"}), "unknown param \"pat\"");
    EXPECT_CONTAINS(error_of(kReadWrite, {"srcpath"}), "expected node.param=value");
}

// A parameter that applies only in some modes (ParamSpec::only_when) is refused in the others,
// from the file and from --set, naming the parameter, the mode that rules it out and its value.
TEST(GraphValidation, ParamsOfAnotherModeAreRefused)
{
    const auto fog = [](const std::string &params) {
        return R"({"nodes": [
            {"id": "src", "type": "read", "params": {"path": "in.####.exr"}},
            {"id": "f", "type": "fog", "inputs": {"image": "src"}, "params": )" +
               params + R"(},
            {"id": "out", "type": "write", "inputs": {"image": "f"}, "params": {"path": "o.####.exr"}}]})";
    };
    EXPECT_EQ(error_of(fog(R"({"model": "atmosphere", "froxels": 8})")), "");
    EXPECT_EQ(error_of(fog(R"({"model": "linear", "start": 1, "end": 9})")), "");
    EXPECT_CONTAINS(error_of(fog(R"({"model": "linear", "froxels": 8})")),
                    "g.json:/nodes/1/params/froxels: node \"f\" (fog): param \"froxels\" applies "
                    "only when model is atmosphere, not linear");
    // The default mode counts too (height), and a list of modes is spelled out.
    EXPECT_CONTAINS(error_of(fog(R"({"end": 50})")),
                    "param \"end\" applies only when model is linear, not height");
    EXPECT_CONTAINS(error_of(fog(R"({"model": "atmosphere", "color": [1, 1, 1]})")),
                    "param \"color\" applies only when model is linear, exp, exp2 or height, "
                    "not atmosphere");
    // --set is held to the same rule, in both directions.
    EXPECT_CONTAINS(error_of(fog(R"({"model": "height"})"), {"f.steps=8"}),
                    "param \"steps\" applies only when model is atmosphere_raymarch, not height");
    EXPECT_EQ(error_of(fog(R"({"model": "height"})"), {"f.model=atmosphere_raymarch", "f.steps=8"}),
              "");
    // A boolean mode.
    const std::string relight = R"({"nodes": [
        {"id": "src", "type": "read", "params": {"path": "in.####.exr"}},
        {"id": "r", "type": "relight", "inputs": {"image": "src"}, "params": {"shadow_steps": 4}},
        {"id": "out", "type": "write", "inputs": {"image": "r"}, "params": {"path": "o.####.exr"}}]})";
    EXPECT_CONTAINS(error_of(relight),
                    "param \"shadow_steps\" applies only when shadows is true, not false");
    EXPECT_EQ(error_of(relight, {"r.shadows=true"}), "");
}

// Every only_when names a choice or boolean parameter of the same node and values it can take,
// so no condition is dead or refers to nothing.
TEST(GraphValidation, ModeConditionsNameRealModes)
{
    int conditions = 0;
    for (const NodeType *t : nodes::catalog().all()) {
        for (const ParamSpec &p : t->spec.params) {
            if (p.when_param.empty()) {
                continue;
            }
            ++conditions;
            const ParamSpec *control = nullptr;
            for (const ParamSpec &c : t->spec.params) {
                if (c.name == p.when_param) {
                    control = &c;
                }
            }
            ASSERT_NE(control, nullptr) << t->spec.type << "." << p.name << ": " << p.when_param;
            ASSERT_TRUE(control->type == ParamType::Choice || control->type == ParamType::Bool)
                << t->spec.type << "." << p.when_param;
            const std::vector<std::string> allowed = control->type == ParamType::Bool
                                                         ? std::vector<std::string>{"true", "false"}
                                                         : split_choices(control->choices);
            for (const std::string &w : split_choices(p.when_values)) {
                EXPECT_NE(std::find(allowed.begin(), allowed.end(), w), allowed.end())
                    << t->spec.type << "." << p.name << ": " << w;
            }
            EXPECT_FALSE(describe_condition(p).empty());
        }
    }
    EXPECT_GE(conditions, 30);  // fog, exposure, bloom, ocio, relight, hatching, dof, tonemap
}

// A list-of-records parameter (relight's lights) is declared field by field and checked by the
// graph like any parameter: types, ranges, choices, mandatory fields, fields of another kind,
// unknown fields; the node reads the records back with their defaults filled in.
TEST(GraphValidation, RecordParamsAreCheckedFieldByField)
{
    const auto relight = [](const std::string &lights) {
        return R"({"nodes": [
            {"id": "src", "type": "read", "params": {"path": "in.####.exr"}},
            {"id": "r", "type": "relight", "inputs": {"image": "src"}, "params": {"lights": )" +
               lights + R"(}},
            {"id": "out", "type": "write", "inputs": {"image": "r"}, "params": {"path": "o.####.exr"}}]})";
    };
    const std::string ok = R"([{"type": "directional", "direction": [0, 1, 0], "intensity": 3},
                               {"type": "spot", "position": [1, 2, 3], "direction": [0, -1, 0]}])";
    EXPECT_EQ(error_of(relight(ok)), "");
    EXPECT_CONTAINS(
        error_of(relight(R"({"type": "point"})")),
        "g.json:/nodes/1/params/lights: node \"r\" (relight): param \"lights\": expected "
        "a list of records, got an object");
    EXPECT_CONTAINS(
        error_of(relight(R"([3])")),
        "/params/lights/0: node \"r\" (relight): param \"lights[0]\": expected a record");
    EXPECT_CONTAINS(
        error_of(relight(R"([{"type": "point", "position": [0, 0, 0], "intesity": 2}])")),
        "/params/lights/0/intesity: node \"r\" (relight): param \"lights[0]\": unknown "
        "field \"intesity\" (did you mean \"intensity\"?)");
    EXPECT_CONTAINS(error_of(relight(R"([{"type": "point"}])")),
                    "/params/lights/0: node \"r\" (relight): param \"lights[0]\": needs "
                    "\"position\" when type is point or spot");
    EXPECT_CONTAINS(error_of(relight(R"([{"direction": [0, 1, 0]}])")),
                    "param \"lights[0]\": needs \"type\"");
    EXPECT_CONTAINS(
        error_of(relight(R"([{"type": "directional", "direction": [0, 1, 0], "radius": 1}])")),
        "/params/lights/0/radius: node \"r\" (relight): param \"lights[0].radius\" applies only "
        "when type is point or spot, not directional");
    EXPECT_CONTAINS(
        error_of(relight(R"([{"type": "point", "position": [0, 0, 0], "intensity": -1}])")),
        "/params/lights/0/intensity: node \"r\" (relight): param \"lights[0].intensity\": "
        "expected number in 0..1e+12, got -1");
    EXPECT_CONTAINS(
        error_of(relight(R"([{"type": "area"}])")),
        "param \"lights[0].type\": expected one of directional|point|spot, got \"area\"");
    // --set takes the whole list as JSON and checks it the same way.
    EXPECT_EQ(error_of(relight("[]"), {"r.lights=" + std::string(ok)}), "");
    EXPECT_CONTAINS(error_of(relight("[]"), {R"(r.lights=[{"type": "spot"}])"}),
                    "param \"lights[0]\": needs \"direction\" when type is directional or spot");

    // Read back: the given values and the declared defaults of the fields left out.
    const Graph g = Graph::parse(relight(ok), "g.json", nodes::catalog());
    const NodeType *type = nodes::catalog().find("relight");
    const ParamSpec *lights = nullptr;
    for (const ParamSpec &p : type->spec.params) {
        if (p.name == "lights") {
            lights = &p;
        }
    }
    ASSERT_NE(lights, nullptr);
    ASSERT_EQ(lights->type, ParamType::Records);
    const auto field = [&](std::string_view name) -> const ParamSpec & {
        for (std::size_t i = 0; i < lights->field_count; ++i) {
            if (lights->fields[i].name == name) {
                return lights->fields[i];
            }
        }
        throw std::runtime_error("no field");
    };
    const std::vector<NodeParams> &records = g.nodes()[1].params.get_records(*lights);
    ASSERT_EQ(records.size(), 2u);
    EXPECT_EQ(records[0].get_choice(field("type")), 0);
    EXPECT_EQ(records[0].get_real(field("intensity")), 3.0);
    EXPECT_EQ(records[1].get_choice(field("type")), 2);
    EXPECT_EQ(records[1].get_real(field("intensity")), 1.0);  // the default
    EXPECT_FALSE(records[1].given(field("intensity")));
    EXPECT_EQ(records[1].get_real(field("outer_deg")), 30.0);
    EXPECT_EQ(records[1].get_vec(field("position")), (std::vector<double>{1, 2, 3}));
}

// "The header's value unless given" is one flag on the declaration, printed as the default.
TEST(GraphValidation, HeaderDefaultsAreDeclared)
{
    const auto spec = [](std::string_view type, std::string_view name) -> const ParamSpec & {
        for (const ParamSpec &p : nodes::catalog().find(type)->spec.params) {
            if (p.name == name) {
                return p;
            }
        }
        throw std::runtime_error("no such param");
    };
    EXPECT_EQ(describe_default(spec("exposure", "fstop")), "the header's aperture, else 8");
    EXPECT_EQ(describe_default(spec("motion_blur", "shutter")), "the header's shutter, else 0.5");
    EXPECT_EQ(describe_default(spec("bloom", "fstop")), "the header's aperture, else 8");
    EXPECT_EQ(describe_default(spec("fog", "sun_direction")),
              "the header's posthaste:sunDirection, else [0.4, 0.75, 0.3]");
    EXPECT_EQ(describe_default(spec("dof", "focus_distance")),
              "the header's focus (required there)");
    EXPECT_EQ(describe_default(spec("fog", "density")), "0.01");
}

TEST(GraphFrames, ListsAndRanges)
{
    EXPECT_EQ(parse_frame_list("1-5x2"), (std::vector<int>{1, 3, 5}));
    EXPECT_EQ(parse_frame_list("1,5,10-12"), (std::vector<int>{1, 5, 10, 11, 12}));
    EXPECT_EQ(parse_frame_list("-2--1"), (std::vector<int>{-2, -1}));
    EXPECT_EQ(parse_frame_list("7"), (std::vector<int>{7}));
    EXPECT_THROW(parse_frame_list("1-x"), Error);
    EXPECT_THROW(parse_frame_list("1-10x0"), Error);
    EXPECT_THROW(parse_frame_list(""), Error);
    EXPECT_THROW(parse_frame_list("1-99999999"), Error);
    // A frame listed twice is run once, in the order it is first listed; the bound counts
    // frames, not how they were listed.
    EXPECT_EQ(parse_frame_list("5,1-6,2,5"), (std::vector<int>{5, 1, 2, 3, 4, 6}));
    EXPECT_EQ(parse_frame_list("1-1000000,1-1000000").size(), 1000000u);
    EXPECT_THROW(parse_frame_list("1-1000001"), Error);
    // An "x" with no step after it is a mistake, not a step of 1.
    try {
        parse_frame_list("1-3x");
        ADD_FAILURE() << "1-3x accepted";
    } catch (const Error &e) {
        EXPECT_NE(std::string(e.what()).find("missing step after \"x\""), std::string::npos)
            << e.what();
    }
}

TEST(GraphPlan, PassNamingParametersAskTheInputForThosePasses)
{
    // `pass` and `passes` parameters declared reads_passes(): the planner asks the first input
    // for the passes they name, beside what downstream reads.
    const Graph g = Graph::parse(R"({"nodes": [
        {"id": "src", "type": "read", "params": {"path": "x.exr"}},
        {"id": "soft", "type": "blur", "inputs": {"image": "src"},
         "params": {"passes": "albedo, depth"}},
        {"id": "tone", "type": "tonemap", "inputs": {"image": "soft"}, "params": {"pass": "spec"}},
        {"id": "out", "type": "write", "inputs": {"image": "tone"},
         "params": {"path": "o.exr", "passes": "color"}}]})",
                                 "g.json",
                                 nodes::catalog());
    EXPECT_EQ(g.nodes()[2].requested.to_string(), "color");  // what the write reads
    EXPECT_EQ(g.nodes()[1].requested.to_string(), "color,spec");
    EXPECT_EQ(g.nodes()[0].requested.to_string(), "albedo,color,depth,spec");
}

TEST(GraphPlan, SourcesAreAskedOnlyForWhatIsUsed)
{
    const Graph g = Graph::parse(R"({"nodes": [
        {"id": "src", "type": "read", "params": {"path": "x.exr"}},
        {"id": "cc", "type": "ocio", "inputs": {"image": "src"}},
        {"id": "sh", "type": "channels", "inputs": {"image": "cc"},
         "params": {"copy": {"zz": ["depth.Z"]}, "rename": {"albedo": "base"}}},
        {"id": "out", "type": "write", "inputs": {"image": "sh"},
         "params": {"path": "o.exr", "passes": "color,zz,base"}},
        {"id": "png", "type": "write", "inputs": {"image": "src"}, "params": {"path": "p.png"}}]})",
                                 "g.json",
                                 nodes::catalog());
    EXPECT_EQ(g.nodes()[0].requested.to_string(), "albedo,color,depth");
    EXPECT_EQ(g.nodes()[1].requested.to_string(), "albedo,color,depth");
    EXPECT_EQ(g.nodes()[2].requested.to_string(), "base,color,zz");

    const Graph m = Graph::parse(R"({"nodes": [
        {"id": "a", "type": "read", "params": {"path": "a.exr"}},
        {"id": "b", "type": "read", "params": {"path": "b.exr"}},
        {"id": "k", "type": "read", "params": {"path": "k.exr"}},
        {"id": "m", "type": "merge", "inputs": {"b": "b", "a": "a", "mask": "k"},
         "params": {"mask_pass": "id", "mask_channel": "r"}},
        {"id": "out", "type": "write", "inputs": {"image": "m"},
         "params": {"path": "o.exr", "passes": "color,depth"}}]})",
                                 "g.json",
                                 nodes::catalog());
    EXPECT_EQ(m.nodes()[0].requested.to_string(), "color");
    EXPECT_EQ(m.nodes()[1].requested.to_string(), "color,depth");
    EXPECT_EQ(m.nodes()[2].requested.to_string(), "id");
}

TEST(GraphPlan, OnlyANodeThatReadsTheCameraAsksASourceForIt)
{
    // A read solves a camera from position + depth only where something downstream reads the
    // camera (PassSet::camera); a pass-through node carries the request, a write keeps it for
    // what reads its frame, and `all` (a write of every pass) asks for everything.
    const auto plan = [](const std::string &middle, const std::string &out_params) {
        const std::string json = R"({"nodes": [
            {"id": "src", "type": "read", "params": {"path": "x.exr"}},
            {"id": "mid", "type": )" +
                                 middle + R"(, "inputs": {"image": "src"}},
            {"id": "cc", "type": "grade", "inputs": {"image": "mid"}},
            {"id": "out", "type": "write", "inputs": {"image": "cc"}, "params": )" +
                                 out_params + "}]}";
        return Graph::parse(json, "g.json", nodes::catalog());
    };
    const std::string color = R"({"path": "o.exr", "passes": "color"})";
    EXPECT_FALSE(plan(R"("grade")", color).nodes()[0].requested.camera);
    EXPECT_FALSE(plan(R"("motion_blur")", color).nodes()[0].requested.camera);
    EXPECT_FALSE(plan(R"("lens", "params": {"k1": 0.1})", color).nodes()[0].requested.camera);
    for (const char *reads : {R"("ao")",
                              R"("ssr")",
                              R"("ssgi")",
                              R"("dof")",
                              R"("fog")",
                              R"("bloom")",
                              R"("relight")",
                              R"("motion_blur", "params": {"source": "camera"})",
                              R"("lens", "params": {"natural_vignetting": 1})"}) {
        const Graph g = plan(reads, color);
        EXPECT_TRUE(g.nodes()[0].requested.camera) << reads;
        EXPECT_FALSE(g.nodes()[2].requested.camera) << reads;  // the grade after it does not
    }
    EXPECT_FALSE(plan(R"("dof", "params": {"focal_length_mm": 50, "sensor_width_mm": 36})", color)
                     .nodes()[0]
                     .requested.camera);
    EXPECT_TRUE(plan(R"("grade")", R"({"path": "o.exr"})").nodes()[0].requested.all);
}

/// Write two analytic frames and a graph reading them; returns the directory.
std::string prepare_inputs(const std::string &name, int width, int height)
{
    const std::string dir = scratch_dir(name);
    for (int f = 1; f <= 2; ++f) {
        WriteOptions o;
        o.storage["color"] = PixelStorage::Float;
        o.storage["albedo"] = PixelStorage::Float;
        write_exr(
            make_sample_frame(width, height, f), dir + "/in." + std::to_string(f) + ".exr", o);
    }
    return dir;
}

TEST(GraphNodes, MergeOperationsOnHandComputedPixels)
{
    const std::string dir = prepare_inputs("merge", 8, 4);
    // Foreground: color scaled to alpha 0.5 (premultiplied) via a second read and channels.
    const std::string graph = R"({"nodes": [
        {"id": "b", "type": "read", "params": {"path": ")" +
                              dir + R"(/in.#.exr"}},
        {"id": "a", "type": "channels", "inputs": {"image": "b"},
         "params": {"copy": {"color": ["albedo.R", "albedo.G", "albedo.B", 0.5]}}},
        {"id": "m", "type": "merge", "inputs": {"b": "b", "a": "a"}, "params": {"operation": "over"}},
        {"id": "o", "type": "write", "inputs": {"image": "m"}, "params": {"path": ")" +
                              dir + R"(/o.exr", "passes": "color"}}]})";
    Graph g = Graph::parse(graph, "g.json", nodes::catalog());
    g.set_capture("m");
    const Frame out = g.evaluate(1);
    const Image &c = out.image("color");
    // B at (x, y): (2u, v, 0.26, 1); A = (0.5, 0.4, 0.3, 0.5); over: A + B (1 - 0.5).
    for (int y = 0; y < 4; ++y) {
        for (int x = 0; x < 8; ++x) {
            const float u = (x + 0.5f) / 8.0f, v = (y + 0.5f) / 4.0f;
            EXPECT_FLOAT_EQ(c.at(x, y, 0), 0.5f + 2.0f * u * 0.5f);
            EXPECT_FLOAT_EQ(c.at(x, y, 1), 0.4f + v * 0.5f);
            EXPECT_FLOAT_EQ(c.at(x, y, 2), 0.3f + 0.26f * 0.5f);
            EXPECT_FLOAT_EQ(c.at(x, y, 3), 0.5f + 1.0f * 0.5f);
        }
    }
    EXPECT_TRUE(out.has("depth"));  // B's other passes pass through

    for (const auto &[op, r] :
         std::vector<std::pair<std::string, float>>{{"add", 0.5f + 2.0f * (0.5f / 8.0f)},
                                                    {"multiply", 0.5f * 2.0f * (0.5f / 8.0f)},
                                                    {"subtract", 0.5f - 2.0f * (0.5f / 8.0f)},
                                                    {"under", 2.0f * (0.5f / 8.0f) + 0.5f * 0.0f},
                                                    {"max", 0.5f},
                                                    {"mix", 0.5f}}) {
        Graph h = Graph::parse(graph, "g.json", nodes::catalog(), {"m.operation=" + op});
        h.set_capture("m");
        EXPECT_FLOAT_EQ(h.evaluate(1).image("color").at(0, 0, 0), r) << op;
    }
    Graph half = Graph::parse(graph, "g.json", nodes::catalog(), {"m.operation=mix", "m.mix=0.25"});
    half.set_capture("m");
    EXPECT_FLOAT_EQ(half.evaluate(1).image("color").at(0, 0, 0), 0.125f + (0.5f - 0.125f) * 0.25f);
}

TEST(GraphNodes, ChannelsCopyRenameRemoveKeep)
{
    const std::string dir = prepare_inputs("channels", 4, 4);
    Graph g = Graph::parse(R"({"nodes": [
        {"id": "src", "type": "read", "params": {"path": ")" +
                               dir + R"(/in.#.exr"}},
        {"id": "sh", "type": "channels", "inputs": {"image": "src"},
         "params": {"copy": {"mv": ["motion.Y", "motion.X", 1], "n2": "normal"},
                    "rename": {"albedo": "base"}, "remove": "normal",
                    "keep": "mv,n2,base,color"}},
        {"id": "o", "type": "write", "inputs": {"image": "sh"}, "params": {"path": ")" +
                               dir + R"(/x.exr"}}]})",
                           "g.json",
                           nodes::catalog());
    g.set_capture("sh");
    const Frame f = g.evaluate(2);
    EXPECT_EQ(f.pass_names(), (std::vector<std::string>{"base", "color", "mv", "n2"}));
    EXPECT_EQ(f.pass("mv").channels, (std::vector<std::string>{"Y", "X", "2"}));
    EXPECT_EQ(f.image("mv").at(1, 1, 0), -1.0f);
    EXPECT_EQ(f.image("mv").at(1, 1, 1), 2.0f);
    EXPECT_EQ(f.image("mv").at(1, 1, 2), 1.0f);
    EXPECT_EQ(f.image("base").at(0, 0, 0), 0.5f);
    EXPECT_EQ(f.pass("base").channels, (std::vector<std::string>{"R", "G", "B"}));
}

// A rename onto a pass the frame has replaces it and says so once; a pass renamed to a canonical
// name of another channel count keeps its own channel names (a 3-channel normal renamed "ao",
// whose canonical pass has one channel, would otherwise be written as bare channels 0, 1, 2).
TEST(GraphNodes, ChannelsRenameOntoAPassSaysSoAndKeepsChannelNames)
{
    const std::string dir = prepare_inputs("channels_rename", 4, 4);
    Graph g = Graph::parse(R"({"nodes": [
        {"id": "src", "type": "read", "params": {"path": ")" +
                               dir + R"(/in.#.exr"}},
        {"id": "sh", "type": "channels", "inputs": {"image": "src"},
         "params": {"rename": {"albedo": "color", "normal": "ao"}}},
        {"id": "o", "type": "write", "inputs": {"image": "sh"}, "params": {"path": ")" +
                               dir + R"(/x.exr"}}]})",
                           "g.json",
                           nodes::catalog());
    g.set_capture("sh");
    testing::internal::CaptureStderr();
    const Frame f = g.evaluate(2);
    const std::string err = testing::internal::GetCapturedStderr();
    EXPECT_NE(err.find(R"(rename "albedo" -> "color" replaces the pass "color" the frame had)"),
              std::string::npos)
        << err;
    EXPECT_EQ(err.find(R"(replaces the pass "ao")"), std::string::npos) << err;
    EXPECT_FALSE(f.has("albedo"));
    EXPECT_EQ(f.image("color").at(0, 0, 0), 0.5f);  // albedo's value
    EXPECT_EQ(f.pass("color").channels, (std::vector<std::string>{"R", "G", "B"}));
    EXPECT_EQ(f.pass("ao").channels, (std::vector<std::string>{"X", "Y", "Z"}));
}

// Renames happen at once: {"albedo": "color", "color": "albedo"} swaps the two passes (one
// after the other, the second rename found the first's result and colour was lost), asks its
// input for both when only one is wanted downstream, and says nothing of replacing a pass.
// Two passes renamed to one name is a usage error naming both.
TEST(GraphNodes, ChannelsRenamesSwapAtOnce)
{
    const std::string dir = prepare_inputs("channels_swap", 4, 4);
    const Frame in = read_frame(dir + "/in.2.exr", nullptr, 2);
    const auto graph = [&](const std::string &rename, const std::string &passes) {
        return R"({"nodes": [
        {"id": "src", "type": "read", "params": {"path": ")" +
               dir + R"(/in.#.exr"}},
        {"id": "sh", "type": "channels", "inputs": {"image": "src"},
         "params": {"rename": )" +
               rename + R"(}},
        {"id": "o", "type": "write", "inputs": {"image": "sh"}, "params": {"path": ")" +
               dir + R"(/x.#.exr", "passes": ")" + passes + R"("}}]})";
    };
    Graph g = Graph::parse(
        graph(R"({"albedo": "color", "color": "albedo"})", "color"), "g.json", nodes::catalog());
    g.set_capture("sh");
    testing::internal::CaptureStderr();
    const Frame f = g.evaluate(2);
    const std::string err = testing::internal::GetCapturedStderr();
    EXPECT_EQ(err.find("replaces the pass"), std::string::npos) << err;
    ASSERT_FALSE(in.image("albedo").bit_equal(in.image("color")));
    EXPECT_TRUE(f.image("color").bit_equal(in.image("albedo")));
    EXPECT_TRUE(f.image("albedo").bit_equal(in.image("color")));
    // The write asked for colour alone: the read still gave albedo for it.
    const Frame out = read_frame(dir + "/x.2.exr", nullptr, 2);
    for (int c = 0; c < 3; ++c) {  // (the reader gives colour an alpha of 1)
        EXPECT_EQ(out.image("color").at(1, 2, c), in.image("albedo").at(1, 2, c)) << c;
    }
    EXPECT_NE(out.image("color").at(1, 2, 0), in.image("color").at(1, 2, 0));
    try {
        Graph::parse(graph(R"({"albedo": "x", "normal": "x"})", "x"), "g.json", nodes::catalog());
        ADD_FAILURE() << "two renames to one name were accepted";
    } catch (const Error &e) {
        EXPECT_NE(std::string(e.what()).find(R"(rename/normal: node "sh" (channels): "albedo" is)"
                                             R"( renamed "x" too)"),
                  std::string::npos)
            << e.what();
    }
}

// A write whose half storage turns finite values into infinity says so once a run, naming
// itself and the channels (20 stops on the inputs' colours of 0.25 and more is 262144 and more,
// beyond half's 65504).
TEST(GraphNodes, WriteSaysOnceWhenHalfStorageOverflows)
{
    const std::string dir = prepare_inputs("write_overflow", 4, 4);
    Graph g = Graph::parse(R"({"nodes": [
        {"id": "src", "type": "read", "params": {"path": ")" +
                               dir + R"(/in.#.exr"}},
        {"id": "up", "type": "grade", "inputs": {"image": "src"}, "params": {"exposure": 20}},
        {"id": "w", "type": "write", "inputs": {"image": "up"}, "params": {"path": ")" +
                               dir + R"(/x.#.exr", "passes": "color", "storage": "half"}}]})",
                           "g.json",
                           nodes::catalog());
    testing::internal::CaptureStderr();
    g.evaluate(1);
    g.evaluate(2);
    const std::string err = testing::internal::GetCapturedStderr();
    const std::string line =
        R"(node "w" (write): values beyond half's range (65504) were written as infinity)";
    const auto at = err.find(line);
    EXPECT_NE(at, std::string::npos) << err;
    EXPECT_EQ(err.find(line, at + 1), std::string::npos) << err;
    const Frame out = read_frame(dir + "/x.2.exr", nullptr, 2);
    EXPECT_EQ(out.image("color").at(0, 0, 0), std::numeric_limits<float>::infinity());
}

TEST(GraphNodes, OcioCheckValue)
{
    const ColorProcessor to_srgb = ColorProcessor::between("lin_rec709", "srgb", "test");
    float rgb[3] = {0.18f, 0.0f, 1.0f};
    to_srgb.apply_rgb(rgb);
    EXPECT_NEAR(rgb[0], 0.461356f, 1e-5f);
    EXPECT_NEAR(rgb[1], 0.0f, 1e-6f);
    EXPECT_NEAR(rgb[2], 1.0f, 1e-5f);
    const ColorProcessor display =
        ColorProcessor::display_view("lin_rec709", "sRGB", "Standard", "test");
    float g[3] = {0.18f, 0.18f, 0.18f};
    display.apply_rgb(g);
    EXPECT_NEAR(g[1], 0.461356f, 1e-5f);
    // Premultiplied pixels are unpremultiplied around the transform.
    Image img(1, 1, 4);
    img.at(0, 0, 0) = 0.09f;
    img.at(0, 0, 3) = 0.5f;
    to_srgb.apply(img, true);
    EXPECT_NEAR(img.at(0, 0, 0), 0.461356f * 0.5f, 1e-5f);
    EXPECT_THROW(ColorProcessor::between("lin_rec709", "srgbb", "test"), Error);
    EXPECT_THROW(ColorProcessor::display_view("lin_rec709", "sRGB", "Filmic", "test"), Error);
}

TEST(GraphDeterminism, SameBitsForOneAndManyThreads)
{
    const std::string dir = prepare_inputs("threads", 301, 173);
    const std::string graph = R"({"nodes": [
        {"id": "b", "type": "read", "params": {"path": ")" +
                              dir + R"(/in.#.exr"}},
        {"id": "cc", "type": "ocio", "inputs": {"image": "b"}, "params": {"to": "srgb"}},
        {"id": "a", "type": "channels", "inputs": {"image": "b"},
         "params": {"copy": {"color": ["albedo.R", "position.X", "albedo.B", 0.25]}}},
        {"id": "m", "type": "merge", "inputs": {"b": "cc", "a": "a", "mask": "b"},
         "params": {"operation": "over", "mask_pass": "color", "mask_channel": "luminance"}},
        {"id": "o", "type": "write", "inputs": {"image": "m"}, "params": {"path": ")" +
                              dir + R"(/x.exr"}}]})";
    Graph g = Graph::parse(graph, "g.json", nodes::catalog());
    g.set_capture("m");
    set_thread_count(1);
    const Frame one = g.evaluate(2);
    set_thread_count(4);
    const Frame many = g.evaluate(2);
    set_thread_count(0);
    ASSERT_EQ(one.pass_names(), many.pass_names());
    for (const std::string &n : one.pass_names()) {
        EXPECT_TRUE(one.image(n).bit_equal(many.image(n))) << n;
    }
}

}  // namespace
}  // namespace posthaste
