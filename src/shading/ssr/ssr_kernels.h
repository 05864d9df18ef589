#pragma once
// The screen-space reflection march's depth tests (shading/ssr/ssr.h), written once over Highway's
// lane types (ssr_kernels.cpp): one step of one ray a lane, so that a ray's steps are tested
// together (they are independent: each compares its own sample with the depth there and with the
// previous sample), and what follows a crossing (the bisection, the hit's checks) stays per ray.
// Compiled for each x86 target Highway supports and dispatched at run time; the same bits as the
// scalar march on every target.

#include <cmath>

namespace posthaste::shading {

struct SkyCoordParams;

/// Step buffers hold the ray's steps rounded up to whole vectors: steps + kSsrStepPad.
inline constexpr int kSsrStepPad = 16;

/// The traced grid's 1 / depth (0 on the sky), w x h cells of `stride` pixels, row-major.
struct SsrDepthGrid {
    const float *inv_depth = nullptr;
    int w = 0, h = 0;
    float inv_stride = 1.0f;
    float thickness = 0.5f;  ///< world units a surface extends behind its depth
};

/// A ray's projected segment: pixel coordinates and 1 / camera z at t = 0 (a) and t = 1 (b), all
/// finite, 1 / z positive; the steps cover [t_start, t_end] as t_start + s^2 (t_end - t_start),
/// s = (i + jitter) / steps.
struct SsrSegment {
    float ax = 0, ay = 0, a_inv_z = 0, bx = 0, by = 0, b_inv_z = 0;
    float t_start = 0, t_end = 0, jitter = 0;
    int steps = 1;
};

/// Taylor coefficients of sin x / x - 1 and cos x - 1 in x^2 (highest first), shared by
/// sincos_turns and its lanes (ssr_kernels.cpp) so that they round alike.
inline constexpr float kSinTaylor[5] = {
    -2.5052108385e-8f, 2.7557319224e-6f, -1.9841269841e-4f, 8.3333333333e-3f, -1.6666666667e-1f};
inline constexpr float kCosTaylor[6] = {2.0876756988e-9f,
                                        -2.7557319224e-7f,
                                        2.4801587302e-5f,
                                        -1.3888888889e-3f,
                                        4.1666666667e-2f,
                                        -0.5f};

/// sin and cos of 2 pi u for any finite u: u reduced to [-1/4, 1/4] turns, then Taylor
/// polynomials to x^11 and x^12 (error below 1e-7), multiplies and adds in this order; the
/// scalar twin of the sampling kernel's lanes.
inline void sincos_turns(float u, float &s, float &c)
{
    float q = u - float(int(u));                           // (-1, 1)
    q = q > 0.5f ? q - 1.0f : (q < -0.5f ? q + 1.0f : q);  // [-1/2, 1/2]
    // sin(pi - x) = sin x, cos(pi - x) = -cos x: fold |q| > 1/4 back into [-1/4, 1/4].
    const bool fold = q > 0.25f || q < -0.25f;
    const float r = q > 0.25f ? 0.5f - q : (q < -0.25f ? -0.5f - q : q);
    const float x = r * 6.28318530717958647692f;
    const float x2 = x * x;
    float ps = kSinTaylor[0];
    for (int i = 1; i < 5; ++i) {
        ps = ps * x2 + kSinTaylor[i];
    }
    s = x + x * (x2 * ps);
    float pc = kCosTaylor[0];
    for (int i = 1; i < 6; ++i) {
        pc = pc * x2 + kCosTaylor[i];
    }
    const float cv = 1.0f + x2 * pc;
    c = fold ? -cv : cv;
}

/// shading::sample_ggx_reflection's method with sincos_turns for the azimuth (the truth's
/// sampler uses std::cos and std::sin; the directions agree to about 1e-7): the reflected
/// direction for GGX roughness alpha around unit n seen from v, from (u1, u2) in [0, 1)^2.
/// The scalar reference of ssr_ggx_rays, bit for bit.
inline void ggx_reflection_twin(
    const float n[3], const float v[3], float alpha, float u1, float u2, float l[3])
{
    const float a2 = alpha * alpha;
    const float cos2 = (1.0f - u1) / (1.0f + (a2 - 1.0f) * u1);
    const float cos_t = std::sqrt(cos2 > 0.0f ? (cos2 < 1.0f ? cos2 : 1.0f) : 0.0f);
    const float sin2 = 1.0f - cos_t * cos_t;
    const float sin_t = std::sqrt(sin2 > 0.0f ? sin2 : 0.0f);
    float sp, cp;
    sincos_turns(u2, sp, cp);
    // An orthonormal basis around n (Duff et al. 2017).
    const float sign = std::copysign(1.0f, n[2]);
    const float a = -1.0f / (sign + n[2]), b = n[0] * n[1] * a;
    const float t1[3] = {1.0f + sign * n[0] * n[0] * a, sign * b, -sign * n[0]};
    const float t2[3] = {b, sign + n[1] * n[1] * a, -n[1]};
    const float w1 = sin_t * cp, w2 = sin_t * sp;
    float h[3];
    for (int i = 0; i < 3; ++i) {
        h[i] = (t1[i] * w1 + t2[i] * w2) + n[i] * cos_t;
    }
    const float vh2 = 2.0f * ((v[0] * h[0] + v[1] * h[1]) + v[2] * h[2]);
    float r[3];
    for (int i = 0; i < 3; ++i) {
        r[i] = vh2 * h[i] - v[i];
    }
    const float inv = 1.0f / std::sqrt((r[0] * r[0] + r[1] * r[1]) + r[2] * r[2]);
    for (int i = 0; i < 3; ++i) {
        l[i] = r[i] * inv;
    }
}

/// ggx_reflection_twin for n rays, and n.l: in[0..8] are n x, y, z, v x, y, z, alpha, u1, u2;
/// out[0..3] receive l x, y, z and n.l. Every array holds n + kSsrStepPad values.
void ssr_ggx_rays(const float *const in[9], int n, float *const out[4]);

/// What a ray's segment on screen is computed from (ssr.cpp's Marcher::segment): the camera's
/// matrices as glm holds them (column-major, m[4 c + r]), the image size, the ray's length, the
/// most steps, the near plane the far end is clipped to.
struct SsrSegmentCamera {
    float world_to_camera[16] = {}, world_to_ndc[16] = {};
    int width = 1, height = 1;
    float max_distance = 60.0f;
    int max_steps = 16;
    float near = 1e-3f;
};

/// The segments of n rays (origins ox, oy, oz; unit directions dx, dy, dz) as Marcher::segment
/// computes them, bit for bit: out[0..8] receive a.x, a.y, a.inv_z, b.x, b.y, b.inv_z, t_start,
/// t_end and the steps (0 for a ray with no segment on screen; then the others are
/// meaningless). Every array holds n + kSsrStepPad values.
void ssr_segments(const SsrSegmentCamera &c,
                  const float *ox,
                  const float *oy,
                  const float *oz,
                  const float *dx,
                  const float *dy,
                  const float *dz,
                  int n,
                  float *const out[9]);

/// For each step i < s.steps: its t (t[i]) and whether the ray crossed the depth pass there
/// (crossed[i] 1, else 0): the sample at or behind the grid's surface and the stretch of ray
/// since the previous sample (the origin for i = 0) overlapping [depth, depth + thickness].
/// t and crossed hold s.steps + kSsrStepPad values.
void ssr_march_steps(const SsrDepthGrid &g, const SsrSegment &s, float *t, float *crossed);

/// SkyView::radiance (shading/atmosphere/atmosphere.h) of n unit directions (x[i], y[i], z[i]), bit
/// for bit on every target, into r, g, b; `p` from SkyView::coord_params. All arrays hold n +
/// kSsrStepPad values.
void ssr_sky_view_radiance(const SkyCoordParams &p,
                           const float *x,
                           const float *y,
                           const float *z,
                           int n,
                           float *r,
                           float *g,
                           float *b);

/// One row of the per-pixel inputs of the resolve, one array a channel (n values each, rounded
/// up to whole vectors: n + kSsrStepPad), and the camera: depth_ray(u, v) = origin + u du + v dv
/// (shading/camera_rays.h).
struct SsrWeightRow {
    const float *z = nullptr;
    const float *nx = nullptr, *ny = nullptr, *nz = nullptr;
    const float *ar = nullptr, *ag = nullptr, *ab = nullptr;
    const float *roughness = nullptr, *metallic = nullptr;
    int n = 0;
    int width = 1;   ///< the image's width (u = (x stride + 0.5) / width)
    int stride = 1;  ///< value i is pixel column i stride
    float v = 0.5f;  ///< the row's NDC v
    float origin[3] = {}, du[3] = {}, dv[3] = {};
    float max_roughness = 0.78f;
    /// Optional (the march's start, where non-null): the camera's position, and per value the
    /// unit normal turned to the camera, the view direction and the world point
    /// (position + depth_ray z), glossy_pixel's bits where the weight is not 0.
    float position[3] = {};
    float *n_out[3] = {}, *view_out[3] = {}, *point_out[3] = {};
    /// Where non-null (brdf ggx), the weight is the GGX lobe's directional albedo
    /// (shading::ggx_reflection_weight) looked up in this table (shading::ggx_albedo_table).
    const float *ggx_table = nullptr;
};

/// The reflection weight of each pixel of the row that ssr changes, 0 for the others (sky,
/// rough, no normal, no weight), as ssr_rows.cpp's glossy_pixel computes it, bit for bit: the
/// sky reflection weight (shading::sky_reflection_weight: Fresnel-Schlick at n.v times the
/// gloss), or with a ggx_table the GGX lobe's; into wr, wg, wb (n + kSsrStepPad values each),
/// and glossy_pixel's other terms where asked for.
void ssr_weight_row(const SsrWeightRow &r, float *wr, float *wg, float *wb);

/// The traced cells' estimates near one output row, and that row's pixels, for the resolve's
/// window (ssr_rows.cpp). A cell row holds kSsrCellChannels arrays of `pitch` floats (depth, NaN
/// where the cell holds no estimate; the pass's normal x, y, z; the change r, g, b), indexed by
/// pixel column: the cell of pixel column x is repeated over its `stride` columns, so that column
/// x + stride k holds the k-th cell from x's own; valid from column -kSsrCellMargin to w +
/// kSsrCellMargin. cell_x: the first pixel column of the cell each column holds.
inline constexpr int kSsrCellChannels = 7;
inline constexpr int kSsrCellMargin = 32;
struct SsrResolveRow {
    const float *const *rows = nullptr;  ///< the window's cell rows, top down (column 0 each)
    int row_count = 0;
    int pitch = 0;
    const float *cell_x = nullptr;  ///< column 0
    int stride = 1;
    int radius = 0;  ///< a cell is in x's window when |cell_x - x| <= radius
    /// The row: the pixels' depth and normal as the passes have them, their sky reflection
    /// weights (0: left alone), n + kSsrStepPad values each.
    const float *z = nullptr, *nx = nullptr, *ny = nullptr, *nz = nullptr;
    const float *wr = nullptr, *wg = nullptr, *wb = nullptr;
    int n = 0;
    float intensity = 1.0f;
};

/// The resolve of one row: for each pixel with a weight, the mean change of the cells in its
/// window on its surface (depth within 5 % of the pixel's, n . n_cell >= 0.9) times its weight
/// and the intensity, into dr, dg, db, and apply 1 (else 0: no weight or no such cell); the
/// same bits as ssr_rows.cpp's scalar resolve. Outputs hold n + kSsrStepPad values.
void ssr_resolve_row(const SsrResolveRow &r, float *dr, float *dg, float *db, float *apply);

}  // namespace posthaste::shading
