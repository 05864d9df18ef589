// Per-node stability cases: parameter sets to try on every hostile frame, extra frames, and
// known failures (with the reason). A new node adds its entry here.

#include "stability/stability.h"

namespace posthaste::stability {

NodeCases node_cases(const std::string &type)
{
    NodeCases c;
    if (type == "merge") {
        for (const char *op : {"under", "add", "subtract", "multiply", "max", "min", "mix"}) {
            c.param_sets.push_back({op, {std::string("operation=") + op}});
        }
        c.param_sets.push_back({"half_mix", {"mix=0.5"}});
        c.param_sets.push_back({"luminance_mask", {"mask_channel=luminance"}});
    } else if (type == "ocio") {
        c.param_sets.push_back({"display", {"mode=display"}});
        c.param_sets.push_back({"keep_premultiplied", {"unpremultiply=false"}});
        c.param_sets.push_back({"to_linear", {"from=srgb", "to=lin_rec709"}});
        c.known_failures["to_linear/huge_values"] =
            "decoding sRGB-encoded 1e6 gives ~1.5e15 (a power of 2.4); such input is not "
            "display-referred, so the bound does not apply";
        c.known_failures["to_linear/zero_alpha"] =
            "finding: unpremultiplying by alpha 1e-30 gives RGB ~1e29, the sRGB decode overflows "
            "to Inf and the re-premultiply makes Inf/NaN from finite input; io/color.cpp should "
            "leave pixels with alpha below a threshold (or 0) unpremultiplied";
    } else if (type == "channels") {
        c.param_sets.push_back({"copy_rename_remove",
                                {R"(copy={"mix": ["color.R", "depth.Z", 1], "n2": "normal"})",
                                 R"(rename={"motion": "mv"})",
                                 "remove=albedo"}});
        c.param_sets.push_back({"keep_color", {"keep=color"}});
    }
    return c;
}

const std::map<std::string, std::string> &skipped_types()
{
    static const std::map<std::string, std::string> kSkipped = {
        {"read", "a source: reads files (its bad_pixels option is tested with the reader)"},
        {"write", "a sink: writes files"},
    };
    return kSkipped;
}

}  // namespace posthaste::stability
