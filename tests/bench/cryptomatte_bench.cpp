// The cryptomatte node keying a matte from 6 ranks (3 rank layers) at 1920x1080, as a graph runs
// it, beside a copy of one rank layer in the same run. The ranks: 200 names spread over the
// frame in blocks, each pixel's coverages summing to 1; two names keyed, and a pattern over the
// manifest that keys 20.
//   build/tests/posthaste_benchmarks --benchmark_filter=Cryptomatte --benchmark_repetitions=5
//       --benchmark_report_aggregates_only=true   (one command line)
#include <benchmark/benchmark.h>

#include <nlohmann/json.hpp>

#include "bench_util.h"
#include "core/hash.h"
#include "core/parallel.h"
#include "io/cryptomatte.h"
#include "test_util.h"

namespace posthaste {
namespace {

const Frame &crypto_frame()
{
    static const Frame f = [] {
        const int w = 1920, h = 1080;
        Frame out;
        out.set_size(w, h);
        std::vector<float> ids;
        nlohmann::json manifest = nlohmann::json::object();
        for (int i = 0; i < 200; ++i) {
            const std::string name = "object_" + std::to_string(i);
            ids.push_back(cryptomatte::id_of(name));
            manifest[name] = cryptomatte::hex_of(ids.back());
        }
        for (int k = 0; k < 3; ++k) {
            Image ranks(w, h, 4);
            for (int y = 0; y < h; ++y) {
                for (int x = 0; x < w; ++x) {
                    // Six names a pixel, from its 64x64 block and hashed neighbours; coverage
                    // falls off with the rank (0.4, 0.25, 0.15, 0.1, 0.06, 0.04).
                    static const float cov[6] = {0.4f, 0.25f, 0.15f, 0.1f, 0.06f, 0.04f};
                    float *p = ranks.pixel(x, y);
                    for (int j = 0; j < 2; ++j) {
                        const int rank = 2 * k + j;
                        const int name = int((x / 64 + 30 * (y / 64) +
                                              int(hash_unit(x / 8, y / 8, rank, 3) * 7.0f) * rank) %
                                             200);
                        p[2 * j] = ids[std::size_t(name)];
                        p[2 * j + 1] = cov[rank];
                    }
                }
            }
            out.set("CryptoObject0" + std::to_string(k), std::move(ranks), {"R", "G", "B", "A"});
        }
        for (const auto &[field, value] :
             std::vector<std::pair<std::string, std::string>>{{"name", "CryptoObject"},
                                                              {"hash", "MurmurHash3_32"},
                                                              {"conversion", "uint32_to_float32"},
                                                              {"manifest", manifest.dump()}}) {
            out.attributes.push_back(OIIO::ParamValue("cryptomatte/a1b2c3d/" + field, value));
        }
        return out;
    }();
    return f;
}

void run(benchmark::State &state, const std::string &params)
{
    set_thread_count(2);
    const test::NodeRunner node("cryptomatte", params);
    const auto input = std::make_shared<const Frame>(crypto_frame());
    for (auto _ : state) {
        const Frame out = node.run(input, 1);
        benchmark::DoNotOptimize(out.image("matte").data());
    }
    set_thread_count(0);
}

void BM_CryptomatteCopyBaseline(benchmark::State &state)
{
    bench::copy_baseline(state, crypto_frame().image("CryptoObject00"));
}
BENCHMARK(BM_CryptomatteCopyBaseline)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_CryptomatteTwoNames(benchmark::State &state)
{
    run(state, R"({"matte": ["object_3", "object_77"]})");
}
BENCHMARK(BM_CryptomatteTwoNames)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_CryptomattePattern(benchmark::State &state)
{
    run(state, R"({"matte": ["object_1?"]})");
}
BENCHMARK(BM_CryptomattePattern)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace posthaste
