// Bloom by a fitted downsample/upsample pyramid (see bloom.h): the levels, the non-negative
// fit of their weights to a PSF's tail, and the blur itself. bloom.cpp has the PSFs and the
// FFT convolution.

#include <algorithm>
#include <cmath>
#include <functional>
#include <vector>

#include "core/error.h"
#include "core/parallel.h"
#include "filter/bloom.h"

namespace posthaste::filter {
namespace {

// ---- the pyramid ---------------------------------------------------------------------------
//
// Levels hold NC channels interleaved (3 for an image's RGB, 1 for the fit's impulse responses).
// The loops keep the edge clamping out of their interiors so that they vectorise.

template <int NC>
struct Plane {
    int w = 0, h = 0;
    std::vector<float> v;
    Plane() = default;
    Plane(int w_, int h_) : w(w_), h(h_), v(std::size_t(w_) * std::size_t(h_) * NC, 0.0f) {}
    float *row(int y) { return v.data() + std::size_t(y) * std::size_t(w) * NC; }
    const float *row(int y) const { return v.data() + std::size_t(y) * std::size_t(w) * NC; }
};

/// Rows of `w` pixels, `stride` floats apart, of which the first NC are read.
struct View {
    const float *data;
    int w, h, stride;
    const float *row(int y) const
    {
        return data + std::size_t(y) * std::size_t(w) * std::size_t(stride);
    }
};

template <int NC>
View view_of(const Plane<NC> &p)
{
    return {p.v.data(), p.w, p.h, NC};
}

/// Rows [0, n) in parallel, in blocks, each row written by one task.
void for_rows(int n, const std::function<void(int)> &fn)
{
    constexpr int kBlock = 16;
    parallel_for(0, (n + kBlock - 1) / kBlock, [&](int b) {
        for (int y = b * kBlock; y < std::min(n, (b + 1) * kBlock); ++y) {
            fn(y);
        }
    });
}

// Downsample by 2 with the separable [1 3 3 1] / 8 filter (coarse pixel x is centred between
// fine pixels 2x and 2x + 1), edges clamped.
template <int NC>
Plane<NC> downsample(const View &in)
{
    const int w = in.w, h = in.h, w2 = (w + 1) / 2, h2 = (h + 1) / 2, st = in.stride;
    Plane<NC> tmp(w2, h), out(w2, h2);
    // Interior columns: 2x - 1 >= 0 and 2x + 2 <= w - 1.
    const int lo = std::min(1, w2), hi = std::max(lo, std::min(w2, (w - 3) / 2 + 1));
    for_rows(h, [&](int y) {
        const float *s = in.row(y);
        float *d = tmp.row(y);
        auto clamped = [&](int x) {
            for (int c = 0; c < NC; ++c) {
                auto tap = [&](int i) {
                    return s[std::size_t(std::clamp(i, 0, w - 1)) * std::size_t(st) +
                             std::size_t(c)];
                };
                d[x * NC + c] = 0.125f * (tap(2 * x - 1) + tap(2 * x + 2)) +
                                0.375f * (tap(2 * x) + tap(2 * x + 1));
            }
        };
        for (int x = 0; x < lo; ++x) {
            clamped(x);
        }
        for (int x = lo; x < hi; ++x) {
            const float *p = s + std::size_t(2 * x - 1) * std::size_t(st);
            for (int c = 0; c < NC; ++c) {
                d[x * NC + c] =
                    0.125f * (p[c] + p[3 * st + c]) + 0.375f * (p[st + c] + p[2 * st + c]);
            }
        }
        for (int x = hi; x < w2; ++x) {
            clamped(x);
        }
    });
    const int n = w2 * NC;
    for_rows(h2, [&](int y) {
        auto r = [&](int i) { return tmp.row(std::clamp(i, 0, h - 1)); };
        const float *a = r(2 * y - 1), *b = r(2 * y), *c = r(2 * y + 1), *e = r(2 * y + 2);
        float *d = out.row(y);
        for (int i = 0; i < n; ++i) {
            d[i] = 0.125f * (a[i] + e[i]) + 0.375f * (b[i] + c[i]);
        }
    });
    return out;
}

/// One coarse row brought to `wf` pixels: fine pixel 2j + 1/2 -/+ 1/2 takes 3/4 of coarse pixel
/// j and 1/4 of its neighbour on that side (edges clamped).
template <int NC>
void upsample_row(const float *s, int wc, float *d, int wf)
{
    auto coarse = [&](int j, int c) { return s[std::clamp(j, 0, wc - 1) * NC + c]; };
    auto edge = [&](int x) {
        const int j = x >> 1, k = (x & 1) ? j + 1 : j - 1;
        for (int c = 0; c < NC; ++c) {
            d[x * NC + c] = 0.75f * coarse(j, c) + 0.25f * coarse(k, c);
        }
    };
    // Interior coarse pixels j in [1, wc - 2] whose both fine pixels exist.
    const int jhi = std::min(wc - 1, wf / 2);
    for (int x = 0; x < std::min(2, wf); ++x) {
        edge(x);
    }
    for (int j = 1; j < jhi; ++j) {
        for (int c = 0; c < NC; ++c) {
            const float m = 0.75f * s[j * NC + c];
            d[(2 * j) * NC + c] = m + 0.25f * s[(j - 1) * NC + c];
            d[(2 * j + 1) * NC + c] = m + 0.25f * s[(j + 1) * NC + c];
        }
    }
    for (int x = std::max(2, 2 * std::max(jhi, 1)); x < wf; ++x) {
        edge(x);
    }
}

/// fine = scale * fine + up(coarse).
template <int NC>
void upsample_add(const Plane<NC> &coarse, Plane<NC> &fine, float scale)
{
    Plane<NC> tmp(fine.w, coarse.h);
    for_rows(coarse.h,
             [&](int y) { upsample_row<NC>(coarse.row(y), coarse.w, tmp.row(y), fine.w); });
    const int n = fine.w * NC;
    for_rows(fine.h, [&](int y) {
        const int j = y >> 1, k = (y & 1) ? j + 1 : j - 1;
        const float *a = tmp.row(std::clamp(j, 0, coarse.h - 1));
        const float *b = tmp.row(std::clamp(k, 0, coarse.h - 1));
        float *d = fine.row(y);
        for (int i = 0; i < n; ++i) {
            d[i] = scale * d[i] + 0.75f * a[i] + 0.25f * b[i];
        }
    });
}

/// Number of coarse levels for a tail of radius R pixels: the coarsest level's pixels are at
/// most R / 2 wide.
int pyramid_levels(int radius)
{
    int n = 0;
    while ((2 << n) <= std::max(radius, 1)) {
        ++n;
    }
    return std::max(n, 1);
}

/// The coarse levels 1..n-1 of `levels` mixed onto level 1: sum_{i >= 1} weights[i] up(level i).
template <int NC>
Plane<NC> mix_coarse(std::vector<Plane<NC>> &levels, const std::vector<float> &weights)
{
    const int n = int(levels.size());
    Plane<NC> acc = std::move(levels[std::size_t(n - 1)]);
    for (float &v : acc.v) {
        v *= weights[std::size_t(n - 1)];
    }
    for (int i = n - 2; i >= 1; --i) {
        Plane<NC> next = std::move(levels[std::size_t(i)]);
        upsample_add(acc, next, weights[std::size_t(i)]);
        acc = std::move(next);
    }
    return acc;
}

/// Solve the small symmetric system G w = b for w >= 0 (an active set: solve, drop the most
/// negative weight, repeat).
std::vector<double> nonnegative_solve(const std::vector<double> &g, const std::vector<double> &b)
{
    const int n = int(b.size());
    std::vector<bool> active(std::size_t(n), true);
    std::vector<double> w(std::size_t(n), 0.0);
    for (int iter = 0; iter < n; ++iter) {
        std::vector<int> idx;
        for (int i = 0; i < n; ++i) {
            if (active[std::size_t(i)]) {
                idx.push_back(i);
            }
        }
        const int k = int(idx.size());
        // Gaussian elimination with partial pivoting on the active rows and columns.
        std::vector<double> a(std::size_t(k) * std::size_t(k + 1));
        double trace = 0.0;
        for (int r = 0; r < k; ++r) {
            trace += g[std::size_t(idx[std::size_t(r)] * n + idx[std::size_t(r)])];
        }
        for (int r = 0; r < k; ++r) {
            for (int c = 0; c < k; ++c) {
                a[std::size_t(r * (k + 1) + c)] =
                    g[std::size_t(idx[std::size_t(r)] * n + idx[std::size_t(c)])] +
                    (r == c ? 1e-12 * trace : 0.0);
            }
            a[std::size_t(r * (k + 1) + k)] = b[std::size_t(idx[std::size_t(r)])];
        }
        for (int col = 0; col < k; ++col) {
            int piv = col;
            for (int r = col + 1; r < k; ++r) {
                if (std::abs(a[std::size_t(r * (k + 1) + col)]) >
                    std::abs(a[std::size_t(piv * (k + 1) + col)])) {
                    piv = r;
                }
            }
            for (int c = 0; c <= k; ++c) {
                std::swap(a[std::size_t(col * (k + 1) + c)], a[std::size_t(piv * (k + 1) + c)]);
            }
            const double d = a[std::size_t(col * (k + 1) + col)];
            for (int r = col + 1; r < k; ++r) {
                const double f = a[std::size_t(r * (k + 1) + col)] / d;
                for (int c = col; c <= k; ++c) {
                    a[std::size_t(r * (k + 1) + c)] -= f * a[std::size_t(col * (k + 1) + c)];
                }
            }
        }
        std::vector<double> x(std::size_t(k), 0.0);
        for (int r = k - 1; r >= 0; --r) {
            double s = a[std::size_t(r * (k + 1) + k)];
            for (int c = r + 1; c < k; ++c) {
                s -= a[std::size_t(r * (k + 1) + c)] * x[std::size_t(c)];
            }
            x[std::size_t(r)] = s / a[std::size_t(r * (k + 1) + r)];
        }
        int worst = -1;
        for (int r = 0; r < k; ++r) {
            if (x[std::size_t(r)] < 0.0 &&
                (worst < 0 || x[std::size_t(r)] < x[std::size_t(worst)])) {
                worst = r;
            }
        }
        std::fill(w.begin(), w.end(), 0.0);
        if (worst < 0) {
            for (int r = 0; r < k; ++r) {
                w[std::size_t(idx[std::size_t(r)])] = x[std::size_t(r)];
            }
            return w;
        }
        active[std::size_t(idx[std::size_t(worst)])] = false;
    }
    return w;
}

}  // namespace

PyramidFit fit_pyramid(const Psf &tail, int levels)
{
    const int r = tail.radius;
    if (levels <= 0) {
        levels = pyramid_levels(r);
    }
    const int n = levels + 1;
    // Every step of the chain is separable, so a level's response to an impulse is the outer
    // product k(x) k(y) of its response on a one-row image: fit with those.
    int canvas = 16;
    while (canvas < 2 * r + (8 << levels)) {
        canvas *= 2;
    }
    std::vector<double> gram(std::size_t(n) * std::size_t(n), 0.0), rhs(std::size_t(n), 0.0);
    double tail_energy = 0.0;
    // The chain is not shift-invariant: average the fit over impulses at two phases of the
    // coarsest grid.
    const int phases[2] = {0, (1 << levels) / 2 + 1};
    for (int phase : phases) {
        const int c0 = canvas / 2 + phase;
        // levels[0] is the impulse itself; only level i is non-zero when its response is taken.
        std::vector<Plane<1>> chain;
        chain.emplace_back(canvas, 1);
        chain[0].v[std::size_t(c0)] = 1.0f;
        for (int i = 1; i < n; ++i) {
            chain.push_back(downsample<1>(view_of(chain.back())));
        }
        std::vector<std::vector<double>> k(static_cast<std::size_t>(n));
        for (int i = 0; i < n; ++i) {
            Plane<1> up = chain[std::size_t(i)];
            for (int j = i - 1; j >= 0; --j) {
                Plane<1> finer(chain[std::size_t(j)].w, chain[std::size_t(j)].h);
                upsample_add(up, finer, 0.0f);
                up = std::move(finer);
            }
            k[std::size_t(i)].assign(up.v.begin(), up.v.end());
        }
        for (int a = 0; a < n; ++a) {
            for (int b = 0; b < n; ++b) {
                double s = 0.0;
                for (int x = 0; x < canvas; ++x) {
                    s += k[std::size_t(a)][std::size_t(x)] * k[std::size_t(b)][std::size_t(x)];
                }
                gram[std::size_t(a * n + b)] += s * s;
            }
            const std::vector<double> &ka = k[std::size_t(a)];
            double s = 0.0;
            for (int dy = -r; dy <= r; ++dy) {
                double row = 0.0;
                for (int dx = -r; dx <= r; ++dx) {
                    row += ka[std::size_t(c0 + dx)] * tail.at(0, dx, dy);
                }
                s += row * ka[std::size_t(c0 + dy)];
            }
            rhs[std::size_t(a)] += s;
        }
        for (float v : tail.planes[0]) {
            tail_energy += double(v) * v;
        }
    }
    std::vector<double> w = nonnegative_solve(gram, rhs);
    double total = 0.0;
    for (double v : w) {
        total += v;
    }
    PyramidFit fit;
    fit.weights.resize(std::size_t(n));
    for (int i = 0; i < n; ++i) {
        fit.weights[std::size_t(i)] = float(total > 0.0 ? w[std::size_t(i)] / total : i == 0);
    }
    // Residual of the normalised mix: |G w|^2 - 2 b.w + |t|^2 over both phases.
    double quad = 0.0, lin = 0.0;
    for (int a = 0; a < n; ++a) {
        lin += double(fit.weights[std::size_t(a)]) * rhs[std::size_t(a)];
        for (int b = 0; b < n; ++b) {
            quad += double(fit.weights[std::size_t(a)]) * fit.weights[std::size_t(b)] *
                    gram[std::size_t(a * n + b)];
        }
    }
    fit.residual = std::sqrt(std::max(0.0, quad - 2.0 * lin + tail_energy) / tail_energy);
    return fit;
}

Image bloom_pyramid(const Image &in, const PyramidFit &fit, double intensity)
{
    const int nc = in.channels();
    if (nc < 3) {
        throw_runtime("bloom: the image has ", nc, " channels; it needs 3 or more");
    }
    const int w = in.width(), h = in.height();
    const int n = int(fit.weights.size());
    std::vector<float> weights = fit.weights;
    for (float &v : weights) {
        v *= float(intensity);
    }
    const float w0 = weights[0] + float(1.0 - intensity);
    // Level 0 is the image itself, read in place; levels 1.. hold RGB.
    std::vector<Plane<3>> levels(1);
    for (int i = 1; i < n; ++i) {
        levels.push_back(
            downsample<3>(i == 1 ? View{in.data(), w, h, nc} : view_of(levels.back())));
    }
    Image out = Image::uninitialized(w, h, nc);
    if (n == 1) {
        for (std::size_t i = 0; i < in.value_count(); ++i) {
            out.data()[i] = (i % std::size_t(nc)) < 3 ? w0 * in.data()[i] : in.data()[i];
        }
        return out;
    }
    const Plane<3> acc = mix_coarse(levels, weights);
    // The last step writes the image: out = w0 in + up(acc), the other channels copied.
    Plane<3> tmp(w, acc.h);
    for_rows(acc.h, [&](int y) { upsample_row<3>(acc.row(y), acc.w, tmp.row(y), w); });
    for_rows(h, [&](int y) {
        const int j = y >> 1, k = (y & 1) ? j + 1 : j - 1;
        const float *a = tmp.row(std::clamp(j, 0, acc.h - 1));
        const float *b = tmp.row(std::clamp(k, 0, acc.h - 1));
        const float *s = in.pixel(0, y);
        float *d = out.pixel(0, y);
        if (nc == 4) {
            for (int x = 0; x < w; ++x) {
                for (int c = 0; c < 3; ++c) {
                    d[4 * x + c] = w0 * s[4 * x + c] + 0.75f * a[3 * x + c] + 0.25f * b[3 * x + c];
                }
                d[4 * x + 3] = s[4 * x + 3];
            }
            return;
        }
        for (int x = 0; x < w; ++x) {
            for (int c = 0; c < nc; ++c) {
                const std::size_t i = std::size_t(x) * std::size_t(nc) + std::size_t(c);
                d[i] = c < 3 ? w0 * s[i] + 0.75f * a[3 * x + c] + 0.25f * b[3 * x + c] : s[i];
            }
        }
    });
    return out;
}

}  // namespace posthaste::filter
