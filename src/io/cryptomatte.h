#pragma once
// Cryptomatte (Psyop's specification 1.1/1.2): ID mattes as the production renderers write them.
// A file declares each cryptomatte in its header, under a metadata key:
//   cryptomatte/<key>/name        the type name as the layers carry it ("CryptoObject", or
//                                 Blender's "ViewLayer.CryptoObject")
//   cryptomatte/<key>/hash        "MurmurHash3_32"
//   cryptomatte/<key>/conversion  "uint32_to_float32"
//   cryptomatte/<key>/manifest    JSON {"name": "8 hex digits of the ID's float bits"}, or
//   cryptomatte/<key>/manif_file  the same JSON in a file beside the image
// and its ranks in layers <name>00, <name>01, ...: R and B are IDs (float32), G and A their
// coverages. An ID is the name's MurmurHash3_x86_32 (seed 0) with its float exponent kept in
// 1..254 (no zero, denormal, infinity or NaN).

#include <OpenImageIO/paramlist.h>

#include <cstdint>
#include <cstring>
#include <set>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "core/cryptomatte_id.h"

namespace posthaste {
class Frame;
}

namespace posthaste::cryptomatte {

/// One cryptomatte a header declares.
struct Layer {
    std::string key;   ///< The metadata key ("d593dd7").
    std::string name;  ///< The layers' prefix: ranks are <name>00, <name>01, ...
    /// Names and IDs, sorted by name; empty without a manifest.
    std::vector<std::pair<std::string, float>> manifest;
    bool has_manifest = false;
    std::string manifest_from;  ///< "header", the sidecar's path, or "" (none).
    /// What breaks the specification in its declaration (one line naming the image and the
    /// cryptomatte), or "": an error where this cryptomatte is used.
    std::string problem;

    /// Whether `type` names this cryptomatte: its name, or its name after a view layer's
    /// prefix ("CryptoObject" names "ViewLayer.CryptoObject").
    bool is(std::string_view type) const;
};

/// Every cryptomatte in `attributes` (a frame's header), sorted by name. `image_path` locates a
/// sidecar manifest. A declaration that breaks the specification (no name, a hash other than
/// MurmurHash3_32, a conversion other than uint32_to_float32, a manifest that is not a JSON
/// object of 8-hex-digit IDs, a sidecar that cannot be read) comes with its `problem`, naming
/// `image_path`, the cryptomatte and what is wrong.
std::vector<Layer> find_layers(const OIIO::ParamValueList &attributes,
                               const std::string &image_path);

/// `own` (the header of a frame's part) with the cryptomatte declarations of `others` (the
/// file's other parts' headers) that it lacks: a multi-part file may declare a cryptomatte only
/// in the header of the part that holds its rank layers. Each key comes whole from the first
/// header that declares it, `own` first.
OIIO::ParamValueList with_declarations_of(const OIIO::ParamValueList &own,
                                          const std::vector<const OIIO::ParamValueList *> &others);

/// The cryptomatte declarations a frame can use: its attributes' and its source file's other
/// parts'.
OIIO::ParamValueList declarations(const Frame &frame);

/// The rank passes of `layer` among `pass_names`: <name>00, <name>01, ... in order. A gap (a rank
/// layer missing below one that exists) is an Error naming `where` and the missing layer.
std::vector<std::string> rank_passes(const Layer &layer,
                                     const std::vector<std::string> &pass_names,
                                     const std::string &where);

/// Whether `name` matches `pattern`: `*` any run of characters, `?` one character, `\` makes
/// the next character literal (manifests hold names with `*`, `?`, `[` and `]`).
bool name_matches(std::string_view pattern, std::string_view name);
/// Whether `pattern` has a wildcard that is not escaped.
bool has_wildcard(std::string_view pattern);
/// The pattern with its escapes removed (the name it matches when it has no wildcard).
std::string unescape(std::string_view pattern);

/// The optional pass request (graph/node.h's PassSet) that asks a read for the rank passes of
/// the cryptomatte `type` ("" for every cryptomatte in the file): "cryptomatte:<type>".
std::string request_for(std::string_view type);
/// The type a request names, or false when `request` is not one.
bool parse_request(std::string_view request, std::string &type);

/// The rank passes among `pass_names` that the cryptomatte requests in `optional` ask for, by
/// the cryptomattes `attributes` declares (no sidecar manifest is read). Malformed declarations
/// ask for nothing here; the reader and the cryptomatte node report them.
std::set<std::string> requested_ranks(const std::set<std::string> &optional,
                                      const OIIO::ParamValueList &attributes,
                                      const std::vector<std::string> &pass_names);

}  // namespace posthaste::cryptomatte
