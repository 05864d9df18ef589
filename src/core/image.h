#pragma once
// Image: one pass of a frame. float32, width x height x channels, interleaved, row-major, origin
// top-left, pixel centres at (x + 0.5, y + 0.5). Half floats exist only at EXR read and write.

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <glm/vec4.hpp>
#include <memory>
#include <vector>

namespace posthaste {

/// Half-open integer rectangle [x0, x1) x [y0, y1).
struct Rect {
    int x0 = 0, y0 = 0, x1 = 0, y1 = 0;

    int width() const { return x1 - x0; }
    int height() const { return y1 - y0; }
    bool empty() const { return x1 <= x0 || y1 <= y0; }
    bool contains(int x, int y) const { return x >= x0 && x < x1 && y >= y0 && y < y1; }
    Rect intersect(const Rect &o) const
    {
        return {std::max(x0, o.x0), std::max(y0, o.y0), std::min(x1, o.x1), std::min(y1, o.y1)};
    }
    /// Grow by r pixels on every side.
    Rect expand(int r) const { return {x0 - r, y0 - r, x1 + r, y1 + r}; }
    /// Moved by (dx, dy).
    Rect offset(int dx, int dy) const { return {x0 + dx, y0 + dy, x1 + dx, y1 + dy}; }
    /// The smallest rectangle holding both (an empty one is ignored).
    Rect unite(const Rect &o) const
    {
        if (empty()) {
            return o;
        }
        if (o.empty()) {
            return *this;
        }
        return {std::min(x0, o.x0), std::min(y0, o.y0), std::max(x1, o.x1), std::max(y1, o.y1)};
    }
    bool operator==(const Rect &) const = default;
};

/// Largest image accepted anywhere (pixels per side, and channels), so absurd sizes in a header or
/// on the command line fail with a message instead of an allocation failure.
inline constexpr int kMaxImageSide = 65536;
inline constexpr int kMaxChannels = 64;
inline constexpr std::size_t kMaxImageFloats = std::size_t(1) << 32;

/// Frees an image's pixels and gives their bytes back to the memory budget (core/memory.h).
struct ImageRelease {
    std::size_t bytes = 0;
    void operator()(float *p) const;
};

class Image {
   public:
    Image() = default;
    /// A zero-filled image. Throws Error for sizes outside [0, kMaxImageSide] or channel counts
    /// outside [1, kMaxChannels].
    Image(int width, int height, int channels);
    /// An image whose pixels are left uninitialised (every pixel must then be written).
    static Image uninitialized(int width, int height, int channels);
    /// Zero-filled, same size and channel count as `other`.
    static Image like(const Image &other)
    {
        return Image(other.width_, other.height_, other.channels_);
    }

    Image(const Image &other);
    Image &operator=(const Image &other);
    Image(Image &&) noexcept = default;
    Image &operator=(Image &&) noexcept = default;

    int width() const { return width_; }
    int height() const { return height_; }
    int channels() const { return channels_; }
    bool empty() const { return width_ == 0 || height_ == 0; }
    Rect bounds() const { return {0, 0, width_, height_}; }
    std::size_t pixel_count() const { return std::size_t(width_) * std::size_t(height_); }
    std::size_t value_count() const { return pixel_count() * std::size_t(channels_); }

    float *data() { return data_.get(); }
    const float *data() const { return data_.get(); }
    float *pixel(int x, int y) { return data_.get() + index(x, y); }
    const float *pixel(int x, int y) const { return data_.get() + index(x, y); }
    float &at(int x, int y, int c) { return data_[index(x, y) + std::size_t(c)]; }
    float at(int x, int y, int c) const { return data_[index(x, y) + std::size_t(c)]; }

    /// Channel c at (x, y) with coordinates clamped to the image (edge pixels extend outwards).
    float load_clamped(int x, int y, int c) const
    {
        return at(std::clamp(x, 0, width_ - 1), std::clamp(y, 0, height_ - 1), c);
    }
    /// Channel c at (x, y), or 0 outside the image.
    float load_zero(int x, int y, int c) const
    {
        return (x < 0 || y < 0 || x >= width_ || y >= height_) ? 0.0f : at(x, y, c);
    }
    /// Up to four channels at (x, y), clamped; missing channels read as 0.
    glm::vec4 load4_clamped(int x, int y) const;
    /// Bilinear sample at continuous pixel coordinates (pixel centres at +0.5), clamped at edges.
    glm::vec4 sample_bilinear_clamped(float x, float y) const;

    void fill(float value);
    /// True when both images have the same shape and the same bits (NaNs compare by bits).
    bool bit_equal(const Image &other) const;

   private:
    std::size_t index(int x, int y) const
    {
        return (std::size_t(y) * std::size_t(width_) + std::size_t(x)) * std::size_t(channels_);
    }
    void allocate(int width, int height, int channels);

    int width_ = 0, height_ = 0, channels_ = 0;
    std::unique_ptr<float[], ImageRelease> data_;
};

using ImagePtr = std::shared_ptr<const Image>;

/// `image`, which covers the absolute rectangle `from`, placed over the rectangle `to`: pixels of
/// `to` outside `from` take `fill[c]` (0 where `fill` has no entry). The same pixels when the
/// rectangles are equal.
Image place_in_window(const Image &image,
                      const Rect &from,
                      const Rect &to,
                      const std::vector<float> &fill = {});

}  // namespace posthaste
