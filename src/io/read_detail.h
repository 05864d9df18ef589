#pragma once
// Internal to the reader (image_read.cpp): how a file's channels map onto views and passes
// (read_views.cpp), and the files OpenImageIO does not hand over as flat native pixels:
// luminance/chroma EXRs and deep parts (read_converted.cpp).

#include <OpenImageIO/imageio.h>

#include <cstddef>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "core/image.h"
#include "io/aliases.h"
#include "io/image_file.h"
#include "io/source_file.h"

namespace posthaste::io_detail {

/// Which part of a file each channel belongs to, and under which view and name it maps.
struct MappedChannel {
    int part, channel;
    std::string view;
    std::string name;  ///< Name used for pass mapping: view removed, part layer added.
};

/// The views of a file and each channel's view and mapping name.
void assign_views(const std::vector<OIIO::ImageSpec> &specs,
                  FileInfo &info,
                  std::vector<MappedChannel> &channels,
                  bool &single_part_views);

/// Map the channels of each view onto passes; the chosen view's keep their names, others become
/// "pass@view". View-less channels of a multi-view file count as the chosen view's.
std::vector<PassSource> map_views(const FileInfo &info,
                                  const std::vector<MappedChannel> &channels,
                                  const std::vector<AliasRule> &rules,
                                  const std::string &convention,
                                  std::vector<RefusedPass> *refused);

/// Throws a one-line error naming the file and part when a window is empty or over the limits.
void check_window(const std::string &path, int part, const char *which, const Rect &w);

/// A part's needed channel span, at native pixel types (converted by the caller, in parallel,
/// rather than by OIIO on one thread), or as floats for converted files.
struct PartPixels {
    int chbegin = 0, chend = 0;
    std::size_t pixel_bytes = 0;
    struct Channel {
        std::size_t offset = 0;  ///< Byte offset within a pixel.
        OIIO::TypeDesc type;
    };
    std::vector<Channel> channels;          ///< By channel - chbegin.
    std::shared_ptr<unsigned char[]> data;  ///< Not zero-filled: every byte is read into.
    std::size_t bytes = 0;
    int row0 = 0;  ///< The part's row (0 = its data window's first) that data starts at.
};

/// An uninitialised byte buffer (a zero fill of a 1080p all-pass frame cost a third of a read),
/// counted against the memory budget like a pass image of `width` x `height` x `channels`.
std::shared_ptr<unsigned char[]> raw_bytes(std::size_t n, int width, int height, int channels);

/// A frame's passes assembled from its file's parts (read_bands.cpp): the pass images (`outs`,
/// set up by the caller) with what no part covers filled, each part's rows converted to float as
/// its bands are read, the file's own bits of the channels a float cannot give back copied into
/// their planes (`raw_planes`), and the first bad value and the kept non-finite count per row.
class FrameRows {
   public:
    struct Out {
        const PassSource *ps;
        Image img;
        bool is_depth, linearize;
        /// First bad value per row (x, channel), for BadPixels::Error; -1 when none.
        std::vector<std::pair<int, int>> bad;
        /// Non-finite values kept, per row (summed in row order: thread-count independent).
        std::vector<std::size_t> kept;
    };
    /// A channel kept as the file's bits: its place in a pixel of the part's buffer, its plane.
    struct RawPlane {
        std::size_t offset, size;
        unsigned char *dst;
    };

    FrameRows(const std::string &path,
              const FileInfo &info,
              const Rect &window,
              const ReadOptions &options,
              bool count_kept);
    /// Channels without a part, and the rows and columns outside a part's window.
    void fill_uncovered();
    /// Part p into the passes: a flat part read band by band from `in` at the native types of
    /// pd's channel span; without `in`, pd's rows as they are (converted floats).
    void read_part(OIIO::ImageInput *in,
                   const OIIO::ImageSpec *spec,
                   std::size_t p,
                   PartPixels &pd);

    std::vector<Out> outs;
    std::vector<std::vector<RawPlane>> raw_planes;  ///< By part.

   private:
    /// Frame rows [y_begin, y_end) of every channel that part p gives, from pd (which holds the
    /// part's rows from pd.row0 on).
    void convert_rows(std::size_t p, const PartPixels &pd, int y_begin, int y_end);
    /// Part rows [r_begin, r_end) (held in pd from its row0) into the raw planes.
    void copy_raw(std::size_t p, const PartPixels &pd, int r_begin, int r_end);

    const std::string &path_;
    const FileInfo &info_;
    Rect window_;
    const ReadOptions &options_;
    bool count_kept_;
};

/// True for an EXR whose RGBA interface reports chroma channels (Y, RY, BY).
bool is_luminance_chroma(const std::string &path);
/// The header of a luminance/chroma file, read through OpenEXR's RGBA interface.
FileInfo luminance_chroma_info(const std::string &path);
/// Every channel of part 0 of a luminance/chroma file, as RGB(A) floats.
PartPixels read_luminance_chroma(const std::string &path, const FilePart &part);

/// A ripmap part's levels other than (0, 0), read through OpenEXR (OpenImageIO 2.4 cannot
/// address them), at native types interleaved in the part's channel order, ly major.
std::vector<posthaste::SourceLevel> read_ripmap_levels(const std::string &path,
                                                       int part,
                                                       const OIIO::ImageSpec &spec);

/// Whether a float pass can give back the file's bits for this channel and mapping.
bool float_reproduces(OIIO::TypeDesc type, const ChannelSource &cs, const PassSource &ps, bool lin);

/// An Error unless a JPEG or PNG at `path` (`format` as OpenImageIO names it) ends with its
/// end marker: libjpeg decodes a cut JPEG with a warning, grey below the cut; libpng prints its
/// own "libpng error" line on stderr for a cut PNG. Other formats pass.
void check_image_ends(const std::string &path, const std::string &format);

/// A deep part flattened: per pixel the samples sorted by Z (stable), composited front to back
/// with `over` on premultiplied values (c += (1 - a_acc) * c_s; alpha likewise), Z the nearest
/// sample's (+inf for an empty pixel), every other channel composited like a colour. Floats.
PartPixels flatten_deep(OIIO::ImageInput &in, int sub, const std::string &path);

}  // namespace posthaste::io_detail
