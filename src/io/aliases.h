#pragma once
// Channel aliases: how the channel names other tools write map onto posthaste's canonical passes,
// with sign and direction conventions converted (docs/CONVENTIONS.md has the table and sources).
// A graph adds its own rules; they are tried before the built-in ones.

#include <string>
#include <utility>
#include <vector>

namespace posthaste {

/// One way to make a pass from file channels. Output channel k is
///   scale[k] * file_channel(channels[k]) + offset[k]
/// and values >= infinite_above become +inf (Blender writes 1e10 for the sky's depth).
/// A channel name may start with "*." to match any layer prefix (Blender's view-layer name):
/// "*.Vector.X" matches "ViewLayer.Vector.X". An empty channel name makes a constant (offset).
struct AliasRule {
    std::string pass;
    std::vector<std::string> channels;
    std::vector<float> scale;     ///< Empty: all 1.
    std::vector<float> offset;    ///< Empty: all 0.
    float infinite_above = 0.0f;  ///< 0: off.
    std::string origin;           ///< "canonical", "Blender", "Nuke", "Arnold", "graph".
    int priority = 0;             ///< Lower is tried first.
};

/// A renderer's channels that would make a canonical pass but whose values cannot be converted
/// without knowing a render setting (V-Ray's depth normalised between Black and White, Redshift's
/// encoded motion vectors, Unreal's screen-normalised ones): posthaste does not guess. When the
/// file has the channels and the pass is not made otherwise, `message` says what to set.
struct RefusalRule {
    std::string pass;
    std::vector<std::string> channels;
    std::string origin;   ///< The renderer.
    std::string message;  ///< {W}, {H}, {W/2}, {H/2} become the file's display size.
};
struct RefusedPass {
    std::string pass;
    std::string origin;
    std::string message;
};

/// The built-in refusals (docs/CONVENTIONS.md).
const std::vector<RefusalRule> &builtin_refusal_rules();

/// The built-in rules, canonical names first.
const std::vector<AliasRule> &builtin_alias_rules();

/// Parse graph alias rules from JSON text: an array of objects
///   {"pass": "depth", "channels": ["zdepth.Z"], "scale": [1], "offset": [0],
///    "infinite_above": 1e9}
/// Throws a usage Error prefixed with `where`.
std::vector<AliasRule> parse_alias_rules(const std::string &json_text, const std::string &where);

/// Where each channel of a pass comes from in a file.
struct ChannelSource {
    int part = -1;     ///< Subimage index; -1 for a constant.
    int channel = -1;  ///< Channel index within the part.
    std::string name;  ///< Full file channel name ("" for a constant).
    float scale = 1.0f;
    float offset = 0.0f;
};
struct PassSource {
    std::string pass;
    std::vector<std::string> channel_suffixes;  ///< Names of the pass's channels ("X", "R").
    std::vector<ChannelSource> sources;
    float infinite_above = 0.0f;
    std::string origin;
};

/// The channels of one file part (subimage).
struct PartChannels {
    std::string part_name;
    std::vector<std::string> names;
};

/// Map a file's channels onto passes: canonical and aliased passes first (graph rules, then
/// built-in), then every remaining layer as a pass of its own name (channels grouped by the
/// prefix before the last '.'; a channel without a prefix is a pass of its own name). A color
/// pass without alpha gets A = 1; a file with only Y (and A) gets Y copied into R, G and B.
/// The renderer conventions the built-in rules know (lower-case names for a `convention`
/// setting) and the origin each stands for: "blender" -> "Blender", "unreal" -> "Unreal MRQ".
const std::vector<std::pair<std::string, std::string>> &known_conventions();

/// `convention` "" or "auto": every built-in rule; else only the canonical names and that
/// renderer's (a name from known_conventions, checked by the caller).
std::vector<PassSource> map_channels(const std::vector<PartChannels> &parts,
                                     const std::vector<AliasRule> &graph_rules,
                                     const std::string &convention = "");

/// The refusals that apply to a file whose channels are `parts`, given the passes it makes and
/// its display size.
std::vector<RefusedPass> refused_passes(const std::vector<PartChannels> &parts,
                                        const std::vector<PassSource> &made,
                                        int width,
                                        int height,
                                        const std::string &convention = "");

}  // namespace posthaste
