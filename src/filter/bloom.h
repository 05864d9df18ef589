#pragma once
// Bloom: the light a lens and sensor scatter around bright points, as a convolution of the image
// with a point-spread function (PSF) whose every channel sums to 1, so the image's energy is kept
// (the light is moved, not added). Two methods share one PSF:
//
// - exact: the convolution itself, by FFT (FFTW, single precision), with the frame extended
//   beyond its edges by its edge pixels (a uniform frame stays uniform);
// - pyramid: a downsample/upsample chain (after Jimenez 2014) whose levels are mixed with
//   weights fitted to the PSF's radially symmetric tail by non-negative least squares against
//   each level's own impulse response. It cannot draw the aperture's diffraction spikes; the
//   tail it draws is charted against the exact method (docs/ACCURACY.md).
//
// The built-in PSF: (1 - intensity) of the energy in the aperture's diffraction pattern (the
// squared magnitude of the Fourier transform of a polygon of `blades` blades, per channel at its
// wavelength, sized by the f-number and the pixel pitch, times `diffraction_scale`), and
// `intensity` in a scattering tail k(r) = (1 + (r / r0)^2)^-falloff, truncated at `radius`.

#include <array>
#include <memory>
#include <string>
#include <vector>

#include "core/image.h"

namespace posthaste::filter {

struct BloomPsfParams {
    double intensity = 0.05;         ///< share of the energy in the scattering tail, [0, 1]
    double size = 0.003;             ///< r0 of the tail, as a fraction of the display width
    double falloff = 1.5;            ///< tail exponent (> 1: finite energy)
    double radius = 0.15;            ///< truncation radius, fraction of the display width
    int blades = 6;                  ///< aperture blades (0: a circular aperture)
    double blade_rotation = 0.0;     ///< degrees
    double fstop = 8.0;              ///< f-number
    double pixel_pitch_um = 18.75;   ///< sensor width / display width
    double diffraction_scale = 0.0;  ///< 1: physical size; 0: no diffraction (a point)
};

/// A PSF on the pixel grid: planes R, G, B of (2 radius + 1)^2 values centred on (radius,
/// radius), each summing to 1.
struct Psf {
    int radius = 0;
    std::array<std::vector<float>, 3> planes;
    int size() const { return 2 * radius + 1; }
    float at(int c, int dx, int dy) const
    {
        return planes[std::size_t(c)][std::size_t((dy + radius) * size() + dx + radius)];
    }
};

/// The truncation radius in pixels for a display `width` (at least 1).
int bloom_radius_px(const BloomPsfParams &p, int display_width);

/// The built-in PSF for a display `width` pixels wide.
Psf builtin_psf(const BloomPsfParams &p, int display_width);

/// A PSF from an image (RGB or one channel, odd or even size, centred on its middle pixel):
/// non-finite and negative values read as 0, each channel normalised to sum 1. Throws an Error
/// naming `who` if a channel sums to 0 or the image is larger than `max_radius` allows.
Psf psf_from_image(const Image &image, int max_radius, const std::string &who);

/// A PSF's spectrum prepared for images of one size (FFTW plans and the three channels' kernel
/// transforms), reusable across frames.
class FftKernel {
   public:
    FftKernel(const Psf &psf, int width, int height);
    ~FftKernel();
    FftKernel(const FftKernel &) = delete;
    FftKernel &operator=(const FftKernel &) = delete;
    int width() const;
    int height() const;
    /// `in` (3 or more channels; the first three are convolved, the others copied) convolved
    /// with the PSF, the frame extended by its edge pixels. Non-finite input values read as 0.
    /// Deterministic: the same bits whatever the thread count.
    Image apply(const Image &in) const;

   private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

/// FftKernel(psf, in's size).apply(in).
Image bloom_fft(const Image &in, const Psf &psf);

/// The pyramid's mix: one weight per level (level 0: the image itself), fitted to a PSF's tail.
struct PyramidFit {
    std::vector<float> weights;
    /// Relative RMS of the fitted kernel against the target tail (over its disc).
    double residual = 0.0;
};

/// Fit the pyramid's level weights to the radially symmetric `tail` (one plane of a Psf), with
/// `levels` coarse levels (0: enough that the coarsest pixel is about half the tail's radius).
PyramidFit fit_pyramid(const Psf &tail, int levels = 0);

/// The tail alone of the built-in PSF (intensity 1, no diffraction), the pyramid's target.
Psf tail_psf(const BloomPsfParams &p, int display_width);

/// `in` with its first three channels replaced by (1 - intensity) in + intensity (in * tail),
/// the tail approximated by the pyramid's fitted mix. Expects finite values (the node reads its
/// input through finite_view).
Image bloom_pyramid(const Image &in, const PyramidFit &fit, double intensity);

}  // namespace posthaste::filter
