#pragma once
// Internal to the EXR writer (image_write.cpp): the output's parts and channels, either in the
// layout of the file the frame was read from or rebuilt with canonical names, with their specs
// (write_layout.cpp), their OpenEXR headers (exr_header.cpp) and the writing (exr_write.cpp).

#include <OpenEXR/ImfHeader.h>
#include <OpenImageIO/imageio.h>

#include <string>
#include <vector>

#include "core/frame.h"
#include "io/image_file.h"
#include "io/source_file.h"

namespace posthaste::io_detail {

/// One channel of an output part and where its values come from.
struct OutChannel {
    std::string name;
    OIIO::TypeDesc type;
    std::string pass;  ///< For messages.
    bool data_pass = false;
    bool untouched = false;  ///< From a pass no node replaced.
    /// Float source: channel `k` of `image` (covering the frame's data window), written as
    /// (v - offset) / scale.
    const Image *image = nullptr;
    int k = 0;
    float scale = 1.0f, offset = 0.0f;
    /// Or the file's own samples over the part's data window.
    const std::vector<unsigned char> *raw = nullptr;
    /// raw's storage when the part's window was cut (a slice of the file's samples).
    std::shared_ptr<const std::vector<unsigned char>> raw_slice;
};

struct OutPart {
    OIIO::ImageSpec spec;  ///< Attributes, name, view, tiles; channels and windows set last.
    Rect data_window;
    std::vector<OutChannel> channels;
    const SourcePart *source = nullptr;
    /// A rebuilt part's view ("" without views): another view's part keeps its own camera.
    std::string view;
    /// A rebuilt part's first pass's source part: its compression is what "auto" keeps.
    const SourcePart *compression_source = nullptr;
    /// The part whose OpenEXR attributes this one's header puts back as the file had them:
    /// `source`, or for a rebuilt layout the part the frame's passes came from.
    const SourcePart *header_source = nullptr;
    /// The source part's window was cut to the frame's data window (a crop): its levels are
    /// made again, not copied.
    bool cut = false;
    bool copy_levels = false;  ///< Write the source's lower levels as read.
    bool make_levels = false;  ///< Make the lower levels again (a touched MIP-mapped part).

    int find(const std::string &name) const
    {
        for (std::size_t i = 0; i < channels.size(); ++i) {
            if (channels[i].name == name) {
                return int(i);
            }
        }
        return -1;
    }
};

/// Passes in write order: canonical ones first, in table order, then the rest alphabetically.
std::vector<std::string> passes_to_write(const Frame &frame, const WriteOptions &options);

/// Rebuilt layout: canonical channel names, one part or one part per pass.
std::vector<OutPart> rebuilt_layout(const Frame &frame,
                                    const std::vector<std::string> &names,
                                    bool multipart,
                                    const WriteOptions &options,
                                    const std::string &path);

/// The source file's layout: its parts in order with their channels; passes no file gave (and
/// touched passes that cannot be mapped back) join part 0 of a single-part file or get a part
/// of their own.
std::vector<OutPart> source_layout(const Frame &frame,
                                   const std::vector<std::string> &names,
                                   const WriteOptions &options,
                                   const std::string &path);

/// Fill in each part's spec: channels, formats, windows, compression, camera, attributes.
void finish_specs(std::vector<OutPart> &parts,
                  const Frame &frame,
                  const WriteOptions &options,
                  const std::string &path);

/// The OpenEXR header of part `index` of `parts` (exr_header.cpp): windows, channels,
/// compression, tiles and levels from the spec, and its attributes under OpenEXR's names.
Imf::Header exr_header(const OutPart &part, int index, int parts, const std::string &path);

/// Finite values a write turned into infinite halves (beyond half's 65504), and the channels
/// (part channel names) they were in.
struct HalfOverflow {
    std::uint64_t values = 0;
    std::vector<std::string> channels;
};

/// Write the parts into `file` through OpenEXR (exr_write.cpp): level 0 of each part, then its
/// MIP levels copied or made again; errors are one line naming `path`. Returns what half storage
/// could not hold.
HalfOverflow write_exr_parts(const std::vector<OutPart> &parts,
                             const Frame &frame,
                             const std::string &file,
                             const std::string &path);

}  // namespace posthaste::io_detail
