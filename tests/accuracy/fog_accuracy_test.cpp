// Fog accuracy on the default scene (docs/ACCURACY.md "Fog"): the atmosphere's aerial-perspective
// froxels at several resolutions, and the cheaper analytic models with their best-fitting
// parameters, against the per-pixel ray-marched atmosphere. Error over pixels with geometry
// (sky pixels come from the same sky-view LUT in both atmosphere modes, and are not a fog).
// Writes fog_accuracy.json in the working directory.

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>

#include "graph/graph.h"
#include "metrics/metrics.h"
#include "nodes/registry.h"
#include "raster/render.h"
#include "raster/scene.h"
#include "test_util.h"

namespace posthaste {
namespace {

Frame run_fog(const Frame &in, const std::string &params, double *ms = nullptr)
{
    const test::NodeRunner fog("fog", params);
    const auto input = std::make_shared<const Frame>(in);
    Frame out;
    std::vector<double> times;
    for (int rep = 0; rep < (ms ? 3 : 1); ++rep) {
        const auto t0 = std::chrono::steady_clock::now();
        out = fog.run(input);
        times.push_back(
            std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0)
                .count());
    }
    if (ms) {
        std::sort(times.begin(), times.end());
        *ms = times[1];  // median of 3 (the first run also builds the LUTs; it is dropped)
    }
    return out;
}

struct Err {
    double rmse = 0, max = 0;
};

/// Over the surface pixels (the sky's colour is the sky model's, not the fog's).
Err geometry_error(const Frame &a, const Frame &ref)
{
    const metrics::CompareStats st =
        metrics::compare_surface(a.image("color"), ref.image("color"), ref.image("depth"), 3);
    return {st.all.rms_error, st.all.max_error};
}

TEST(FogAccuracySlow, CheaperModelsAgainstTheRayMarchedAtmosphere)
{
    const raster::Scene scene =
        raster::load_scene(std::string(POSTHASTE_SOURCE_DIR) + "/samples/scenes/minecrappy.json");
    raster::RenderOptions ro;
    ro.width = 320;
    ro.height = 180;
    ro.passes = {"color", "depth"};
    const Frame in = raster::render_frame(scene, 8, ro);
    const std::string common = R"("metres_per_unit": 20, "sun_disc": false)";
    double ref_ms = 0;
    const Frame ref =
        run_fog(in, R"({"model": "atmosphere_raymarch", "steps": 128, )" + common + "}", &ref_ms);
    const Err none = geometry_error(in, ref);

    std::ofstream json("fog_accuracy.json");
    json << "{\"scene\": \"minecrappy\", \"frame\": 8, \"size\": [320, 180], "
            "\"reference\": {\"model\": \"atmosphere_raymarch\", \"steps\": 128, \"ms\": "
         << ref_ms << "}, \"results\": [\n";
    std::printf("%-34s %10s %10s %10s\n", "model", "rmse", "max", "ms");
    std::printf("%-34s %10.5f %10.5f %10s\n", "no fog", none.rmse, none.max, "-");
    json << "  {\"model\": \"none\", \"rmse\": " << none.rmse << ", \"max\": " << none.max << "}";

    std::vector<double> froxel_rmse;
    for (int res : {8, 16, 32, 64}) {
        double ms = 0;
        const Frame f = run_fog(in,
                                R"({"model": "atmosphere", "froxels": )" + std::to_string(res) +
                                    R"(, "slices": )" + std::to_string(res) + ", " + common + "}",
                                &ms);
        const Err e = geometry_error(f, ref);
        froxel_rmse.push_back(e.rmse);
        std::printf("atmosphere froxels %2d^3               %10.5f %10.5f %10.2f\n",
                    res,
                    e.rmse,
                    e.max,
                    ms);
        json << ",\n  {\"model\": \"atmosphere\", \"froxels\": " << res << ", \"rmse\": " << e.rmse
             << ", \"max\": " << e.max << ", \"ms\": " << ms << "}";
    }
    // The analytic models with the best parameters found by a search, and the least-squares fog
    // color for each candidate (closed form).
    for (const std::string model : {"height", "exp", "exp2", "linear"}) {
        Err best{1e30, 0};
        std::string best_params;
        double best_ms = 0;
        const std::vector<double> falloffs = model == "height"
                                                 ? std::vector<double>{0.0, 0.01, 0.03, 0.1}
                                                 : std::vector<double>{0.0};
        for (double falloff : falloffs) {
            for (int i = 0; i < 24; ++i) {
                const double k = 1e-4 * std::pow(1e3, i / 23.0);  // density, or 1/end for linear
                std::string p = R"({"model": ")" + model + R"(", "color": [1, 1, 1], )";
                p += model == "linear" ? R"("start": 0, "end": )" + std::to_string(1.0 / k)
                                       : R"("density": )" + std::to_string(k);
                if (model == "height") {
                    p += R"(, "falloff": )" + std::to_string(falloff) + R"(, "base_height": 0)";
                }
                // Run with input 0 and fog color 1 to get 1 - T per pixel, then fit the color.
                Frame black = in;
                Image zero = in.image("color");
                for (std::size_t j = 0; j < zero.pixel_count(); ++j) {
                    zero.data()[j * 4] = zero.data()[j * 4 + 1] = zero.data()[j * 4 + 2] = 0.0f;
                }
                black.set("color", std::move(zero));
                const Frame w = run_fog(black, p + "}");
                const Image &one_minus_t = w.image("color");
                double fit[3] = {0, 0, 0}, den = 0;
                for (int y = 0; y < 180; ++y) {
                    for (int x = 0; x < 320; ++x) {
                        if (!std::isfinite(in.image("depth").at(x, y, 0))) {
                            continue;
                        }
                        const double a = one_minus_t.at(x, y, 0);
                        den += a * a;
                        for (int c = 0; c < 3; ++c) {
                            fit[c] += a * (ref.image("color").at(x, y, c) -
                                           (1.0 - a) * in.image("color").at(x, y, c));
                        }
                    }
                }
                char color[96];
                std::snprintf(color,
                              sizeof(color),
                              R"("color": [%.6f, %.6f, %.6f])",
                              std::max(0.0, fit[0] / std::max(den, 1e-12)),
                              std::max(0.0, fit[1] / std::max(den, 1e-12)),
                              std::max(0.0, fit[2] / std::max(den, 1e-12)));
                std::string fitted = p;
                fitted.replace(fitted.find(R"("color": [1, 1, 1])"), 18, color);
                const Frame f = run_fog(in, fitted + "}");
                const Err e = geometry_error(f, ref);
                if (e.rmse < best.rmse) {
                    best = e;
                    best_params = fitted + "}";
                }
            }
        }
        run_fog(in, best_params, &best_ms);
        std::printf("%-34s %10.5f %10.5f %10.2f\n",
                    (model + " (best fit)").c_str(),
                    best.rmse,
                    best.max,
                    best_ms);
        json << ",\n  {\"model\": \"" << model << "\", \"params\": " << best_params
             << ", \"rmse\": " << best.rmse << ", \"max\": " << best.max << ", \"ms\": " << best_ms
             << "}";
        EXPECT_LT(best.rmse, none.rmse) << model << " fits no better than no fog";
    }
    json << "\n]}\n";
    std::printf("reference (ray march, 128 steps): %.1f ms\n", ref_ms);
    // The froxel volume converges towards the per-pixel integral as it grows, and the default
    // (32^3) is well under the error of ignoring the atmosphere.
    EXPECT_LT(froxel_rmse[3], froxel_rmse[0]);
    EXPECT_LT(froxel_rmse[2], 0.1 * none.rmse);
}

}  // namespace
}  // namespace posthaste
