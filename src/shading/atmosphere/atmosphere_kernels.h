#pragma once
// The per-pixel parts of the atmosphere (shading/atmosphere/atmosphere.h), written once over Highway's lane
// types (atmosphere_kernels.cpp) and dispatched at run time: the sky-view LUT coordinates of
// view directions, and one image row of aerial perspective and sky. The LUT lookups and the sun
// disc stay with their classes; these kernels do the arithmetic around them.

#include <cstdint>

namespace posthaste::shading {

/// The sky-view LUT and what its coordinates need (SkyView's members).
struct SkyCoordParams {
    const float *lut = nullptr;  ///< RGB texels, lut_width x lut_height
    int lut_width = 2, lut_height = 4;
    float up[3] = {0.0f, 1.0f, 0.0f}, sun_tangent[3] = {1.0f, 0.0f, 0.0f},
          sun_side[3] = {0.0f, 0.0f, 1.0f};
    float mu_horizon = 0.0f, theta_horizon = 1.5707963f;
    float inv_theta_above = 1.0f / 1.5707963f, inv_theta_below = 1.0f / 1.5707963f;
};

/// SkyView::radiance for n unit directions (x[i], y[i], z[i]) into rgb (3 n floats): the LUT's
/// coordinates and its bilinear lookup. NaN directions give finite radiance.
void sky_view_radiance(
    const SkyCoordParams &p, const float *x, const float *y, const float *z, int n, float *rgb);

/// One image row for the aerial perspective (finite depths) and the sky (infinite ones).
struct AtmosphereRowParams {
    /// depth_ray(u, v) of this row = origin + u du.
    float origin[3] = {}, du[3] = {};
    float inv_w = 1.0f;
    /// The froxel volume (AerialPerspective's members): 8 floats a froxel (in-scatter RGB0,
    /// transmittance RGB1), slice-major, then rows, then columns.
    const float *froxels = nullptr;
    int ap_width = 2, ap_height = 2, slices = 2;
    float inv_max_distance = 0.0f, inv_slices = 0.0f;
    const float *inv_centre_sum = nullptr;  ///< per slice
    int cy = 0;                             ///< the froxel row below this image row
    float ty = 0.0f;                        ///< and the weight of the one after it
    /// With `sky`, infinite depths get the sky's radiance instead of being left alone.
    bool sky = false;
    SkyCoordParams sky_coords;
    bool sun_disc = false;  ///< flag directions within the sun's disc (cos >= cos_sun)
    float sun[3] = {}, cos_sun = 2.0f;
};

/// The aerial perspective composited over the n pixels of a row (`channels` >= 3 floats each;
/// channel 3 passes through exactly): pixel = pixel * T + in-scatter from the froxels at each
/// finite depth z[i] (AerialPerspective::sample's trilinear fetch). NaN depths are left alone;
/// infinite ones too unless p.sky, which writes the sky's radiance there. Sky pixels within the
/// sun's disc (p.sun_disc) are listed in disc_x (n values at most) with their unit directions
/// in disc_dir (3 n floats), for the caller to add the disc; returns their count.
int atmosphere_row(const AtmosphereRowParams &p,
                   const float *z,
                   float *px,
                   int channels,
                   int n,
                   std::int32_t *disc_x,
                   float *disc_dir);

}  // namespace posthaste::shading
