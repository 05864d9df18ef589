#include "core/camera_solve.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <glm/geometric.hpp>
#include <glm/mat3x3.hpp>
#include <glm/matrix.hpp>
#include <limits>
#include <vector>

#include "core/error.h"

namespace posthaste {
namespace {

/// A surface pixel: world position (double), its NDC centre and its depth.
struct Sample {
    std::array<double, 3> p;
    double u, v, d;
};

/// One affine row: value = coef . P + offset.
struct Row {
    std::array<double, 3> coef{};
    double offset = 0.0;
    double at(const std::array<double, 3> &p) const
    {
        return coef[0] * p[0] + coef[1] * p[1] + coef[2] * p[2] + offset;
    }
};

struct Fit {
    Row w, x, y;  ///< depth, u * depth, v * depth
};

/// Solve the 3x3 symmetric positive system C x = r for three right-hand sides by Cholesky.
/// Returns false when C is (nearly) singular: the positions lie on a plane or a line.
bool cholesky_solve(std::array<std::array<double, 3>, 3> c, std::array<std::array<double, 3>, 3> &r)
{
    const double scale = std::max({c[0][0], c[1][1], c[2][2]});
    if (!(scale > 0.0)) {
        return false;
    }
    std::array<std::array<double, 3>, 3> l{};
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j <= i; ++j) {
            double s = c[i][j];
            for (int k = 0; k < j; ++k) {
                s -= l[i][k] * l[j][k];
            }
            if (i == j) {
                if (!(s > 1e-10 * scale)) {
                    return false;
                }
                l[i][i] = std::sqrt(s);
            } else {
                l[i][j] = s / l[j][j];
            }
        }
    }
    for (auto &rhs : r) {  // each right-hand side: L y = rhs, then L^T x = y
        std::array<double, 3> y{};
        for (int i = 0; i < 3; ++i) {
            double s = rhs[i];
            for (int k = 0; k < i; ++k) {
                s -= l[i][k] * y[k];
            }
            y[i] = s / l[i][i];
        }
        for (int i = 2; i >= 0; --i) {
            double s = y[i];
            for (int k = i + 1; k < 3; ++k) {
                s -= l[k][i] * rhs[k];
            }
            rhs[i] = s / l[i][i];
        }
    }
    return true;
}

/// Weighted least squares of the three rows over the kept samples, weights 1/depth^2 so that
/// each pixel's residual counts in NDC units, whatever its distance. Positions are centred on
/// their weighted mean first (the normal equations of raw world coordinates far from the
/// origin lose the digits the fit needs).
bool fit_rows(const std::vector<Sample> &samples, const std::vector<char> &kept, Fit &fit)
{
    double sw = 0.0;
    std::array<double, 3> mean{};
    std::array<double, 3> tmean{};  // d, u d, v d
    for (std::size_t i = 0; i < samples.size(); ++i) {
        if (!kept[i]) {
            continue;
        }
        const Sample &s = samples[i];
        const double w = 1.0 / (s.d * s.d);
        sw += w;
        for (int k = 0; k < 3; ++k) {
            mean[k] += w * s.p[k];
        }
        tmean[0] += w * s.d;
        tmean[1] += w * s.u * s.d;
        tmean[2] += w * s.v * s.d;
    }
    if (!(sw > 0.0)) {
        return false;
    }
    for (int k = 0; k < 3; ++k) {
        mean[k] /= sw;
        tmean[k] /= sw;
    }
    std::array<std::array<double, 3>, 3> cov{};
    std::array<std::array<double, 3>, 3> rhs{};  // rhs[row][component]
    for (std::size_t i = 0; i < samples.size(); ++i) {
        if (!kept[i]) {
            continue;
        }
        const Sample &s = samples[i];
        const double w = 1.0 / (s.d * s.d);
        const std::array<double, 3> q = {s.p[0] - mean[0], s.p[1] - mean[1], s.p[2] - mean[2]};
        const std::array<double, 3> t = {
            s.d - tmean[0], s.u * s.d - tmean[1], s.v * s.d - tmean[2]};
        for (int a = 0; a < 3; ++a) {
            for (int b = 0; b < 3; ++b) {
                cov[a][b] += w * q[a] * q[b];
            }
            for (int r = 0; r < 3; ++r) {
                rhs[r][a] += w * q[a] * t[r];
            }
        }
    }
    if (!cholesky_solve(cov, rhs)) {
        return false;
    }
    Row *rows[3] = {&fit.w, &fit.x, &fit.y};
    for (int r = 0; r < 3; ++r) {
        rows[r]->coef = rhs[r];
        rows[r]->offset =
            tmean[r] - (rhs[r][0] * mean[0] + rhs[r][1] * mean[1] + rhs[r][2] * mean[2]);
    }
    return true;
}

struct Residual {
    double px;     ///< reprojection error, pixels
    double depth;  ///< |fitted depth - depth| / depth
};

Residual residual(const Fit &f, const Sample &s, double width, double height)
{
    const double d = f.w.at(s.p);
    if (!(d > 0.0)) {
        return {std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity()};
    }
    const double du = (f.x.at(s.p) / d - s.u) * width;
    const double dv = (f.y.at(s.p) / d - s.v) * height;
    return {std::sqrt(du * du + dv * dv), std::abs(d - s.d) / s.d};
}

/// The median of `values` (reordered).
double median(std::vector<double> &values)
{
    if (values.empty()) {
        return 0.0;
    }
    const auto mid = values.begin() + std::ptrdiff_t(values.size() / 2);
    std::nth_element(values.begin(), mid, values.end());
    return *mid;
}

double dot(const std::array<double, 3> &a, const std::array<double, 3> &b)
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

std::string format_g(double v)
{
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.2g", v);
    return buf;
}

}  // namespace

std::string CameraSolve::describe() const
{
    char pct[32];
    std::snprintf(pct,
                  sizeof pct,
                  "%.1f",
                  pixels_valid ? 100.0 * double(pixels_kept) / double(pixels_valid) : 0.0);
    return str_cat("solved from position + depth, residual ",
                   format_g(residual_px),
                   " px over ",
                   pct,
                   " % of ",
                   pixels_valid,
                   " surface pixels",
                   right_handed_world ? ", right-handed world" : "");
}

CameraSolve solve_camera(const Image &position,
                         const Image &depth,
                         const Rect &display,
                         const Rect &data,
                         const std::string &who,
                         const CameraSolveOptions &options)
{
    const char *supply =
        "; give the camera instead: worldToCamera and worldToNDC in the header, or read's "
        "\"camera\" parameter";
    if (position.channels() < 3 || depth.channels() < 1 || position.width() != depth.width() ||
        position.height() != depth.height() || position.width() != data.width() ||
        position.height() != data.height() || display.empty()) {
        throw_runtime(who, ": cannot solve the camera: position and depth passes do not match");
    }
    const int w = position.width(), h = position.height();
    int stride = options.stride;
    if (stride <= 0) {
        stride = std::max(1, int(std::ceil(std::sqrt(double(w) * double(h) / 100000.0))));
    }
    const double dw = double(display.width()), dh = double(display.height());
    std::vector<Sample> samples;
    samples.reserve(std::size_t(w / stride + 1) * std::size_t(h / stride + 1));
    for (int y = 0; y < h; y += stride) {
        for (int x = 0; x < w; x += stride) {
            const float d = depth.pixel(x, y)[0];
            const float *p = position.pixel(x, y);
            if (!(d > 0.0f) || !(d < 1e9f) || !std::isfinite(p[0]) || !std::isfinite(p[1]) ||
                !std::isfinite(p[2])) {
                continue;
            }
            samples.push_back({{double(p[0]), double(p[1]), double(p[2])},
                               (double(data.x0 + x) + 0.5 - double(display.x0)) / dw,
                               (double(data.y0 + y) + 0.5 - double(display.y0)) / dh,
                               double(d)});
        }
    }
    CameraSolve out;
    out.pixels_valid = samples.size();
    if (samples.size() < 16) {
        throw_runtime(who,
                      ": cannot solve the camera: ",
                      samples.size(),
                      " surface pixels with a finite depth and position (at least 16 needed)",
                      supply);
    }
    std::vector<char> kept(samples.size(), 1);
    Fit fit;
    std::vector<double> err_px(samples.size()), err_d(samples.size());
    for (int round = 0; round < 6; ++round) {
        if (!fit_rows(samples, kept, fit)) {
            throw_runtime(who,
                          ": cannot solve the camera: the surface positions lie on one plane or "
                          "line, which fits many cameras",
                          supply);
        }
        std::vector<double> px, dd;
        px.reserve(samples.size());
        dd.reserve(samples.size());
        for (std::size_t i = 0; i < samples.size(); ++i) {
            const Residual r = residual(fit, samples[i], dw, dh);
            err_px[i] = r.px;
            err_d[i] = r.depth;
            if (kept[i]) {
                px.push_back(r.px);
                dd.push_back(r.depth);
            }
        }
        // Keep what lies within four medians (at least 1e-4 px and 1e-5 relative depth, the
        // float32 passes' own rounding): a filtered edge pixel, a mix of two surfaces, leaves.
        const double thr_px = std::max(1e-4, 4.0 * median(px));
        const double thr_d = std::max(1e-5, 4.0 * median(dd));
        bool changed = false;
        for (std::size_t i = 0; i < samples.size(); ++i) {
            const char k = err_px[i] <= thr_px && err_d[i] <= thr_d;
            changed = changed || k != kept[i];
            kept[i] = k;
        }
        if (!changed) {
            break;
        }
    }
    // The final fit's residual over the pixels it keeps.
    double sum2 = 0.0;
    std::size_t n = 0;
    float nearest = std::numeric_limits<float>::infinity();
    for (std::size_t i = 0; i < samples.size(); ++i) {
        if (kept[i]) {
            const Residual r = residual(fit, samples[i], dw, dh);
            sum2 += r.px * r.px;
            ++n;
            nearest = std::min(nearest, float(samples[i].d));
        }
    }
    out.pixels_kept = n;
    out.residual_px = n ? std::sqrt(sum2 / double(n)) : std::numeric_limits<double>::infinity();
    const double kept_fraction = double(n) / double(samples.size());
    if (kept_fraction < 0.5 || !(out.residual_px <= options.max_residual_px)) {
        throw_runtime(who,
                      ": cannot solve the camera: residual ",
                      format_g(out.residual_px),
                      " px (at most ",
                      format_g(options.max_residual_px),
                      ") over ",
                      int(std::round(100.0 * kept_fraction)),
                      " % of the surface pixels: no pinhole camera fits the position and depth "
                      "passes (orthographic, distorted or inconsistent)",
                      supply);
    }
    // Depth must be the camera z in the position's units: |d depth / d P| = 1.
    const double scale = std::sqrt(dot(fit.w.coef, fit.w.coef));
    if (std::abs(scale - 1.0) > 1e-2) {
        throw_runtime(who,
                      ": cannot solve the camera: depth changes ",
                      format_g(scale),
                      " per unit of position, not 1: depth is not the distance along the view "
                      "axis in the position pass's units (a normalised or scaled depth needs an "
                      "alias rule)",
                      supply);
    }
    // worldToCamera: z is the depth row; x and y the projection rows less their principal
    // point's share of z, normalised (their lengths are focal / sensor size).
    std::array<double, 3> z = fit.w.coef;
    double z0 = fit.w.offset;
    for (int k = 0; k < 3; ++k) {
        z[k] /= scale;
    }
    z0 /= scale;
    const double cx = dot(fit.x.coef, z), cy = dot(fit.y.coef, z);
    std::array<double, 3> xr, yr;
    for (int k = 0; k < 3; ++k) {
        xr[k] = fit.x.coef[k] - cx * z[k];
        yr[k] = fit.y.coef[k] - cy * z[k];
    }
    const double sx = std::sqrt(dot(xr, xr)), sy = std::sqrt(dot(yr, yr));
    double x0 = (fit.x.offset - cx * z0) / sx;
    double y0 = -(fit.y.offset - cy * z0) / sy;
    for (int k = 0; k < 3; ++k) {
        xr[k] /= sx;
        yr[k] = -yr[k] / sy;  // NDC v grows downwards, camera y upwards
    }
    const double xy = dot(xr, yr);  // square pixels: 0 up to the fit's noise; keep it orthonormal
    for (int k = 0; k < 3; ++k) {
        yr[k] -= xy * xr[k];
    }
    const double yl = std::sqrt(dot(yr, yr));
    for (int k = 0; k < 3; ++k) {
        yr[k] /= yl;
    }
    out.near_clip = options.near_clip ? *options.near_clip : nearest;
    glm::mat4 w2c(0.0f), w2n(0.0f);  // glm: m[column][row]
    const std::array<double, 3> *rows[3] = {&xr, &yr, &z};
    const double offsets[3] = {x0, y0, z0};
    for (int r = 0; r < 3; ++r) {
        for (int k = 0; k < 3; ++k) {
            w2c[k][r] = float((*rows[r])[k]);
        }
        w2c[3][r] = float(offsets[r]);
    }
    w2c[3][3] = 1.0f;
    const Row *ndc[4] = {&fit.x, &fit.y, &fit.w, &fit.w};
    for (int r = 0; r < 4; ++r) {
        for (int k = 0; k < 3; ++k) {
            w2n[k][r] = float(ndc[r]->coef[k]);
        }
        w2n[3][r] = float(ndc[r]->offset - (r == 2 ? double(out.near_clip) : 0.0));
    }
    out.world_to_camera = w2c;
    out.world_to_ndc = w2n;
    out.focal_over_sensor_width = float(sx);
    out.focal_over_sensor_height = float(sy);
    out.right_handed_world = glm::determinant(glm::mat3(w2c)) < 0.0f;
    return out;
}

void apply_camera_solve(const CameraSolve &solve,
                        std::optional<float> focal_length_mm,
                        Camera &camera)
{
    camera.world_to_camera = solve.world_to_camera;
    camera.world_to_ndc = solve.world_to_ndc;
    if (!camera.near_clip) {
        camera.near_clip = solve.near_clip;
    }
    float focal = 0.0f;
    if (focal_length_mm) {
        focal = *focal_length_mm;
    } else if (camera.focal_length_mm) {
        focal = *camera.focal_length_mm;
    } else {
        focal = solve.focal_over_sensor_width * camera.sensor_width_mm.value_or(36.0f);
    }
    if (!camera.focal_length_mm) {
        camera.focal_length_mm = focal;
    }
    if (!camera.sensor_width_mm) {
        camera.sensor_width_mm = focal / solve.focal_over_sensor_width;
    }
    if (!camera.sensor_height_mm) {
        camera.sensor_height_mm = focal / solve.focal_over_sensor_height;
    }
    camera.origin = solve.describe();
}

}  // namespace posthaste
