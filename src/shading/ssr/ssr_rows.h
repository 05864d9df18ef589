#pragma once
// What the ssr node's trace (ssr.cpp) and its resolve (ssr_rows.cpp) share: a traced pixel's
// set-up (glossy_pixel, and the rows of channels its vector twin reads), the traced cells'
// estimates laid out for the resolve kernel, and the resolve itself. Internal to the ssr node.

#include <algorithm>
#include <array>
#include <cstddef>
#include <glm/vec3.hpp>
#include <limits>
#include <optional>
#include <vector>

#include "core/image.h"
#include "shading/camera_rays.h"
#include "shading/ssr/ssr.h"
#include "shading/ssr/ssr_kernels.h"

namespace posthaste::shading::ssr_detail {

/// A pixel the node changes: a finite surface, roughness at most the cut-off, a normal, a
/// non-zero sky reflection weight.
struct GlossyPixel {
    float z, roughness;
    glm::vec3 point{0.0f}, n, view, weight;  // point: with_point only
};

/// Pixel (x, y)'s set-up, or nothing where the node leaves it alone (the scalar reference of
/// ssr_weight_row).
std::optional<GlossyPixel> glossy_pixel(const SsrInputs &in,
                                        const CameraRays &rays,
                                        const SsrParams &p,
                                        int x,
                                        int y,
                                        bool with_point = true);

/// Room in `buf` for `arrays` arrays of n values side by side, each followed by kSsrStepPad
/// values that the vector kernels read past the end: the pitch. The buffer grows but is not
/// cleared (the arrays are written before they are read); the pads of the first `inputs`
/// arrays are zeroed.
std::size_t soa_arrays(std::vector<float> &buf, std::size_t n, int arrays, int inputs);

/// The channels ssr_weight_row reads (depth; normal x, y, z; albedo r, g, b; roughness;
/// metallic), of every `step`-th pixel of row y from column 0, side by side: `count` values into
/// each of ch[0..8], whose kSsrStepPad values after those are zeroed. The weight kernel's
/// parameters for the row.
SsrWeightRow weight_row_inputs(const SsrInputs &in,
                               const CameraRays &rays,
                               const SsrParams &p,
                               int y,
                               int step,
                               int count,
                               float *const ch[9]);

/// The traced cells' estimates in the layout of ssr_kernels.h's SsrResolveRow: per cell row,
/// kSsrCellChannels arrays indexed by pixel column, each cell repeated over its `stride` columns,
/// depth NaN where no cell or no estimate is.
class CellRows {
   public:
    CellRows(int width, int rows, int stride)
        : pitch_(width + 2 * kSsrCellMargin),
          stride_(stride),
          data_(std::size_t(rows) * kSsrCellChannels * std::size_t(pitch_), 0.0f),
          cell_x_(std::size_t(pitch_))
    {
        for (int r = 0; r < rows; ++r) {
            float *z = data_.data() + std::size_t(r) * kSsrCellChannels * std::size_t(pitch_);
            std::fill(z, z + pitch_, std::numeric_limits<float>::quiet_NaN());
        }
        for (int e = -kSsrCellMargin; e < pitch_ - kSsrCellMargin; ++e) {
            const int cell = e >= 0 ? e / stride : -((-e + stride - 1) / stride);
            cell_x_[std::size_t(e + kSsrCellMargin)] = float(cell * stride);
        }
    }
    /// Cell (tx, ty)'s depth, normal and change.
    void set(int tx, int ty, const std::array<float, kSsrCellChannels> &v)
    {
        float *r = row(ty);
        for (int c = 0; c < kSsrCellChannels; ++c) {
            for (int i = 0; i < stride_; ++i) {
                r[std::size_t(c) * std::size_t(pitch_) + std::size_t(tx * stride_ + i)] = v[c];
            }
        }
    }
    float at(int tx, int ty, int channel) const
    {
        return row(ty)[std::size_t(channel) * std::size_t(pitch_) + std::size_t(tx * stride_)];
    }
    /// Cell row ty at pixel column 0.
    float *row(int ty) { return data_.data() + offset(ty); }
    const float *row(int ty) const { return data_.data() + offset(ty); }
    const float *cell_x() const { return cell_x_.data() + kSsrCellMargin; }
    int pitch() const { return pitch_; }

   private:
    std::size_t offset(int ty) const
    {
        return std::size_t(ty) * kSsrCellChannels * std::size_t(pitch_) + kSsrCellMargin;
    }
    int pitch_, stride_;
    std::vector<float> data_;
    std::vector<float> cell_x_;
};

/// The resolve: the colour with each glossy pixel's change added, the mean of the traced cells
/// (every `stride`-th pixel) within the denoise radius on the same surface.
Image resolve(const SsrInputs &in,
              const SsrParams &p,
              const CameraRays &rays,
              const CellRows &cells,
              int stride,
              bool vector_kernels);

}  // namespace posthaste::shading::ssr_detail
