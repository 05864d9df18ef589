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
    } else if (type == "fog") {
        // Hostile frames carry no camera: each model must refuse them with a clear error or
        // stay finite; frames with a camera are covered in tests/unit/fog_node_test.cpp.
        for (const char *model : {"linear", "exp", "exp2", "atmosphere"}) {
            c.param_sets.push_back({model, {std::string("model=") + model}});
        }
    } else if (type == "grade") {
        c.param_sets.push_back({"full_grade",
                                {"exposure=1.5",
                                 "temperature=3200",
                                 "tint=10",
                                 "slope=[1.2, 1, 0.9]",
                                 "offset=[0.01, 0, -0.01]",
                                 "power=[0.8, 1, 1.25]",
                                 "saturation=1.5",
                                 "lift=[0.02, 0, 0]",
                                 "gamma=[1.2, 1, 0.8]",
                                 "gain=[1.1, 1, 1]"}});
        c.param_sets.push_back({"keep_premultiplied", {"exposure=-3", "unpremultiply=false"}});
    } else if (type == "bloom") {
        c.param_sets.push_back({"fft", {"method=fft", "diffraction_scale=20", "blades=5"}});
        c.param_sets.push_back(
            {"wide_tail", {"intensity=1", "size=0.2", "falloff=1.05", "radius=1"}});
    } else if (type == "exposure") {
        c.param_sets.push_back({"auto", {"mode=auto"}});
        c.param_sets.push_back({"photographic", {"mode=photographic", "fstop=1.4", "iso=3200"}});
    } else if (type == "lens") {
        c.param_sets.push_back(
            {"barrel_aberration",
             {"k1=-0.2", "k2=0.02", "chromatic_aberration=0.02", "vignette=1", "stmap=true"}});
        c.param_sets.push_back({"undistort_pincushion",
                                {"direction=undistort", "k1=0.3", "p1=0.01", "filter=bilinear"}});
    } else if (type == "grain") {
        c.param_sets.push_back(
            {"strong_color", {"intensity=4", "size=16", "mode=color", "response=0"}});
    } else if (type == "reformat") {
        c.param_sets.push_back({"half_lanczos", {"scale=0.5", "filter=lanczos3"}});
        c.param_sets.push_back({"odd_upsize", {"width=37", "height=5", "filter=catmull-rom"}});
        c.param_sets.push_back({"one_pixel", {"width=1", "height=1"}});
    } else if (type == "transform") {
        c.param_sets.push_back(
            {"turn_and_zoom", {"rotate=33", "scale=3", "translate_x=2.5", "filter=lanczos3"}});
        c.param_sets.push_back({"shrink_nearest", {"scale=0.01", "filter=nearest"}});
        c.param_sets.push_back({"far_away", {"translate_x=100000"}});
    } else if (type == "crop") {
        // Inside, across the data window, and wholly outside it (values are matched by file
        // coordinates, so `reformat`, which moves them, is tested in tests/unit/image_ops_test).
        c.param_sets.push_back({"inside", {"box=[2, 3, 9, 11]"}});
        c.param_sets.push_back({"across", {"box=[-4, 8, 12, 30]", "crop_data=false"}});
        c.param_sets.push_back({"outside", {"box=[100, 100, 104, 104]"}});
    } else if (type == "blur") {
        c.param_sets.push_back({"wide", {"sigma=40", "sigma_y=0.3", "passes=color,depth"}});
    } else if (type == "sharpen") {
        c.param_sets.push_back(
            {"strong", {"amount=16", "sigma=8", "clamp_negative=false", "passes=color,normal"}});
    } else if (type == "cryptomatte") {
        c.param_sets.push_back({"names", {R"(matte=["rock", "tre?"])"}});
        c.param_sets.push_back({"keyed", {R"(matte=["*"])", "output=keyed"}});
        c.param_sets.push_back({"alpha_by_id", {R"(matte=["<1e-30>", "rock"])", "output=alpha"}});
    } else if (type == "ao") {
        c.param_sets.push_back(
            {"wide_many", {"radius=50", "slices=8", "steps=32", "apply=multiply"}});
        c.param_sets.push_back({"tiny_radius", {"radius=0.0001", "denoise=false"}});
        c.param_sets.push_back({"trace", {"method=trace", "rays=4", "ray_steps=8"}});
        c.param_sets.push_back({"bitmask", {"method=bitmask", "steps=3", "thickness=0.0001"}});
        c.param_sets.push_back(
            {"bitmask_wide", {"method=bitmask", "radius=50", "thickness=1000000", "slices=3"}});
        c.param_sets.push_back(
            {"trace_extreme", {"method=trace", "rays=1", "radius=50", "thickness=0.0001"}});
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
        {"render", "a source: renders a scene (its passes are checked in tests/unit/raster_test)"},
    };
    return kSkipped;
}

}  // namespace posthaste::stability
