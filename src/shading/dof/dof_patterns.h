#pragma once
// The dof gather's sample patterns (shading/dof/dof_gather.cpp): golden-angle spirals per quantised
// radius, disc or polygon by the aperture's blades.

#include <cstddef>
#include <vector>

#include "shading/dof/dof_gather.h"
#include "shading/dof/dof_kernels.h"

namespace posthaste::shading::dof {

// Sample patterns, precomputed per quantised gather radius: kVariants rotated and radially
// jittered golden-angle spirals of n = clamp(density R^2) taps (disc, or polygon by the blade
// shape), each tap an integer pixel offset and the shape-normalised distance of the pixel it
// reads. A group of eight adjacent pixels picks its variant by hash(x / 8, y) (the simple method:
// each pixel by hash(x, y)), so the noise is the same for any thread count.
constexpr int kVariants = 16;

// A tap's rim = 0.5 - the shape-normalised distance d of the pixel read. How much of that pixel
// a CoC of radius r covers is clamp(r - d + 0.5, 0, 1) = clamp(r + rim, 0, 1): a one-pixel ramp
// centred on the rim, so a CoC under half a pixel reaches no neighbour.
class Patterns {
   public:
    /// The spirals for radii up to max_radius at `density` samples per R^2 (capped by
    /// st.samples), shaped by st.blades and st.rotation_deg; offsets for a level `width` wide.
    void build(float max_radius, const DofSettings &st, float density, int width);
    /// The smallest quantised radius >= r (or the largest there is).
    int level(float r) const
    {
        // lut_[i] is the level of i / 4 px, a lower bound; the steps are at least 0.25 px, so
        // one or two more comparisons at most.
        const float q = std::clamp(r * 4.0f, 0.0f, float(lut_.size() - 1));
        int k = lut_[std::size_t(q)];
        const int last = int(radii_.size()) - 1;
        while (k < last && radii_[std::size_t(k)] < r) {
            ++k;
        }
        return k;
    }
    float radius(int k) const { return radii_[std::size_t(k)]; }
    int count(int k) const { return n_[std::size_t(k)]; }
    /// The largest offset (either axis) of any of level k's taps.
    int reach(int k) const { return reach_[std::size_t(k)]; }
    /// Each tap's dy * width + dx (width: the level's, given to build), beside taps(k, variant).
    const std::ptrdiff_t *offsets(int k, int variant) const
    {
        return offsets_.data() + start_[std::size_t(k)] + std::size_t(variant * n_[std::size_t(k)]);
    }
    const Tap *taps(int k, int variant) const
    {
        return taps_.data() + start_[std::size_t(k)] + std::size_t(variant * n_[std::size_t(k)]);
    }

   private:
    std::vector<float> radii_;
    std::vector<int> n_;
    std::vector<std::size_t> start_;
    std::vector<Tap> taps_;
    std::vector<int> lut_;
    std::vector<int> reach_;               ///< Largest |dx| or |dy| of a level's taps.
    std::vector<std::ptrdiff_t> offsets_;  ///< dy * width + dx of each tap.
};

}  // namespace posthaste::shading::dof
