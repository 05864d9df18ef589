#pragma once
// Canonical pass names and their channel names (DESIGN.md "Canonical passes and channels").
// Readers map other tools' names onto these (io/aliases.h); nodes ask for passes by these names.

#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace posthaste::pass {

inline constexpr const char *kColor = "color";    // R G B A: scene-linear Rec.709, premultiplied
inline constexpr const char *kDepth = "depth";    // Z: camera-space z, +inf where nothing was hit
inline constexpr const char *kNormal = "normal";  // N.X N.Y N.Z: world-space unit normal
inline constexpr const char *kPosition = "position";  // P.X P.Y P.Z: world-space position
inline constexpr const char *kMotion = "motion";  // motion.X motion.Y: pixels, prev -> this, y down
inline constexpr const char *kMotionNext = "motion_next";  // same convention, this -> next frame
inline constexpr const char *kAlbedo = "albedo";           // albedo.R albedo.G albedo.B
inline constexpr const char *kMaterial = "material";  // material.roughness .metallic .anisotropy
inline constexpr const char *kTangent = "tangent";    // T.X T.Y T.Z: world-space tangent
inline constexpr const char *kId = "id";              // id: integer id stored as float
// specular.R .G .B: the view-dependent share of color (color less the diffuse terms)
inline constexpr const char *kSpecular = "specular";
// specular_motion.X .Y: how the specular share moves on screen, prev -> this (as motion)
inline constexpr const char *kSpecularMotion = "specular_motion";
// diffuse_motion.X .Y: how color less its specular share moves (as motion), where it does not
// follow the surface points (an untextured ball's shading moves with its centre, not its spin)
inline constexpr const char *kDiffuseMotion = "diffuse_motion";
// specular_depth.Z: the camera depth at which the specular share is in focus (the depth of a
// highlight's virtual image), as depth
inline constexpr const char *kSpecularDepth = "specular_depth";
// shadow.Y: the sun's visibility at the surface, 1 lit .. 0 shadowed or facing away (0 on the sky)
inline constexpr const char *kShadow = "shadow";
// Made by nodes, not read by alias: ambient occlusion (ao.Y, 0 occluded .. 1 open).
inline constexpr const char *kAo = "ao";

/// A pass of camera depths whose +inf is the sky (depth, specular_depth), by its name without
/// any "@view".
inline bool is_depth_pass(std::string_view base)
{
    return base == kDepth || base == kSpecularDepth;
}

struct CanonicalPass {
    std::string_view name;
    std::string_view layer;                  ///< EXR layer prefix ("" for R G B A and Z).
    std::vector<std::string_view> channels;  ///< Channel suffixes, in order.
    bool half_by_default;  ///< Written as half unless asked otherwise (color, albedo).
    std::string_view meaning;
    /// Describes the lighting split of the colour it came with (the specular share, how it
    /// moves and where it focuses): worth asking for only through nodes that keep that colour's
    /// split valid (NodeSpec::keeps_specular).
    bool of_color_split = false;
};

/// All canonical passes, in a stable order.
std::span<const CanonicalPass> canonical_passes();
/// The canonical pass called `name`, or nullptr.
const CanonicalPass *find_canonical(std::string_view name);
/// Full EXR channel names of a pass: canonical ones from the table ("N.X"), otherwise
/// "<pass>.<suffix>" for each given suffix (a one-channel pass named after its channel: bare).
std::vector<std::string> exr_channel_names(std::string_view pass,
                                           const std::vector<std::string> &suffixes);

}  // namespace posthaste::pass
