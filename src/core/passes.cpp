#include "core/passes.h"

namespace posthaste::pass {

std::span<const CanonicalPass> canonical_passes()
{
    static const CanonicalPass kTable[] = {
        {kColor, "", {"R", "G", "B", "A"}, true, "scene-linear Rec.709 radiance, premultiplied"},
        {kDepth, "", {"Z"}, false, "camera-space depth (scene units), +inf on the sky"},
        {kNormal, "N", {"X", "Y", "Z"}, false, "world-space unit normal"},
        {kPosition, "P", {"X", "Y", "Z"}, false, "world-space position"},
        {kMotion,
         "motion",
         {"X", "Y"},
         false,
         "pixels from the previous frame to this one, y down"},
        {kMotionNext,
         "motion_next",
         {"X", "Y"},
         false,
         "pixels from this frame to the next, y down"},
        {kAlbedo, "albedo", {"R", "G", "B"}, true, "base color"},
        {kMaterial,
         "material",
         {"roughness", "metallic", "anisotropy"},
         false,
         "GGX perceptual roughness, metallic, anisotropy in [-1,1]"},
        {kTangent, "T", {"X", "Y", "Z"}, false, "world-space tangent"},
        {kId, "", {"id"}, false, "material/object id (integer stored as float)"},
        {kShadow,
         "shadow",
         {"Y"},
         true,
         "the sun's visibility at the surface: 1 lit, 0 shadowed or facing away (0 on the sky)"},
        {kSpecular,
         "specular",
         {"R", "G", "B"},
         true,
         "the view-dependent share of color (reflections, highlights); color less it moves "
         "with the surface",
         true},
        {kSpecularMotion,
         "specular_motion",
         {"X", "Y"},
         false,
         "how the specular share moves, pixels from the previous frame, y down",
         true},
        {kDiffuseMotion,
         "diffuse_motion",
         {"X", "Y"},
         false,
         "how color less the specular share moves, pixels from the previous frame, y down",
         true},
        {kSpecularDepth,
         "specular_depth",
         {"Z"},
         false,
         "the camera depth of the specular share's image (a highlight's virtual image), +inf on "
         "the sky",
         true},
    };
    return kTable;
}

const CanonicalPass *find_canonical(std::string_view name)
{
    for (const CanonicalPass &p : canonical_passes()) {
        if (p.name == name) {
            return &p;
        }
    }
    return nullptr;
}

std::vector<std::string> exr_channel_names(std::string_view pass,
                                           const std::vector<std::string> &suffixes)
{
    std::vector<std::string> names;
    const CanonicalPass *canonical = find_canonical(pass);
    std::string layer = canonical ? std::string(canonical->layer) : std::string(pass);
    for (const std::string &s : suffixes) {
        // A one-channel pass named after its channel (a bare "Y" or "mask") keeps the bare name.
        const bool bare = layer.empty() || (!canonical && suffixes.size() == 1 && s == layer);
        names.push_back(bare ? s : layer + "." + s);
    }
    return names;
}

}  // namespace posthaste::pass
