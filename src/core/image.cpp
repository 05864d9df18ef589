#include "core/image.h"

#include <cmath>
#include <cstring>

#include "core/error.h"
#include "core/memory.h"
#include "core/parallel.h"

namespace posthaste {

void Image::allocate(int width, int height, int channels)
{
    if (width < 0 || height < 0 || width > kMaxImageSide || height > kMaxImageSide) {
        throw_runtime("image size ", width, "x", height, " is outside 0..", kMaxImageSide);
    }
    if (channels < 1 || channels > kMaxChannels) {
        throw_runtime("image channel count ", channels, " is outside 1..", kMaxChannels);
    }
    const std::size_t n = std::size_t(width) * std::size_t(height) * std::size_t(channels);
    if (n > kMaxImageFloats) {
        throw_runtime("image of ", width, "x", height, "x", channels, " floats is too large");
    }
    reserve_image_memory(n * sizeof(float), width, height, channels);
    float *p = nullptr;
    try {
        p = new float[n];
    } catch (...) {
        release_image_memory(n * sizeof(float));
        throw;
    }
    width_ = width;
    height_ = height;
    channels_ = channels;
    data_ = std::unique_ptr<float[], ImageRelease>(p, ImageRelease{n * sizeof(float)});
    advise_huge_pages(data_.get(), n * sizeof(float));
}

void ImageRelease::operator()(float *p) const
{
    delete[] p;
    release_image_memory(bytes);
}

Image::Image(int width, int height, int channels)
{
    allocate(width, height, channels);
    std::fill_n(data_.get(), value_count(), 0.0f);
}

Image Image::uninitialized(int width, int height, int channels)
{
    Image image;
    image.allocate(width, height, channels);
    return image;
}

Image::Image(const Image &other)
{
    if (other.channels_ == 0) {
        return;
    }
    allocate(other.width_, other.height_, other.channels_);
    std::memcpy(data_.get(), other.data_.get(), value_count() * sizeof(float));
}

Image &Image::operator=(const Image &other)
{
    if (this != &other) {
        Image copy(other);
        *this = std::move(copy);
    }
    return *this;
}

glm::vec4 Image::load4_clamped(int x, int y) const
{
    const float *p = pixel(std::clamp(x, 0, width_ - 1), std::clamp(y, 0, height_ - 1));
    glm::vec4 v(0.0f);
    for (int c = 0; c < std::min(channels_, 4); ++c) {
        v[c] = p[c];
    }
    return v;
}

glm::vec4 Image::sample_bilinear_clamped(float x, float y) const
{
    const float fx = x - 0.5f, fy = y - 0.5f;
    const float x0f = std::floor(fx), y0f = std::floor(fy);
    const float tx = fx - x0f, ty = fy - y0f;
    const int x0 = int(x0f), y0 = int(y0f);
    const glm::vec4 a = load4_clamped(x0, y0), b = load4_clamped(x0 + 1, y0);
    const glm::vec4 c = load4_clamped(x0, y0 + 1), d = load4_clamped(x0 + 1, y0 + 1);
    return (a * (1.0f - tx) + b * tx) * (1.0f - ty) + (c * (1.0f - tx) + d * tx) * ty;
}

void Image::fill(float value)
{
    std::fill_n(data_.get(), value_count(), value);
}

bool Image::bit_equal(const Image &other) const
{
    if (width_ != other.width_ || height_ != other.height_ || channels_ != other.channels_) {
        return false;
    }
    return value_count() == 0 ||
           std::memcmp(data_.get(), other.data_.get(), value_count() * sizeof(float)) == 0;
}

Image place_in_window(const Image &image,
                      const Rect &from,
                      const Rect &to,
                      const std::vector<float> &fill)
{
    const int nch = image.channels();
    Image out = Image::uninitialized(to.width(), to.height(), nch);
    const Rect both = from.intersect(to);
    std::vector<float> pixel(std::size_t(nch), 0.0f);
    for (int c = 0; c < nch && std::size_t(c) < fill.size(); ++c) {
        pixel[std::size_t(c)] = fill[std::size_t(c)];
    }
    const std::size_t n = std::size_t(nch);
    auto fill_span = [&](float *dst, int count) {
        for (int x = 0; x < count; ++x, dst += n) {
            std::copy(pixel.begin(), pixel.end(), dst);
        }
    };
    // Rows in parallel: each is the fill, or the fill either side of one copied span.
    parallel_for(0, out.height(), [&](int y) {
        float *row = out.pixel(0, y);
        const int ay = y + to.y0;
        if (both.empty() || ay < both.y0 || ay >= both.y1) {
            fill_span(row, out.width());
            return;
        }
        const int left = both.x0 - to.x0, span = both.width();
        fill_span(row, left);
        const float *src = image.pixel(both.x0 - from.x0, ay - from.y0);
        std::copy(src, src + std::size_t(span) * n, row + std::size_t(left) * n);
        fill_span(row + std::size_t(left + span) * n, out.width() - left - span);
    });
    return out;
}

}  // namespace posthaste
