// I/O and engine-overhead benchmarks (issue 2), each beside its baseline in the same run:
//  - read + write of a 1920x1080, 16-channel frame (half+piz, float+zip, float+none) through
//    posthaste's read_frame/write_exr, beside OIIO ImageInput -> ImageOutput copying the same
//    file at native pixel types (what `oiiotool in.exr -o out.exr` does);
//  - write_exr of a frame already read, beside OpenEXR's own API writing the same planes;
//  - a read -> write graph over small frames, beside calling read_frame + write_exr directly:
//    the difference is the engine's overhead per frame.
// Run: build/tests/posthaste_benchmarks --benchmark_filter=Io --benchmark_repetitions=5

#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfOutputFile.h>
#include <ImfThreading.h>
#include <OpenImageIO/imageio.h>
#include <benchmark/benchmark.h>

#include <filesystem>
#include <vector>

#include "core/parallel.h"
#include "graph/graph.h"
#include "io/image_file.h"
#include "io/io_detail.h"
#include "io/sequence.h"
#include "nodes/registry.h"

namespace posthaste {
namespace {

namespace fs = std::filesystem;

const std::string &bench_dir()
{
    static const std::string dir = [] {
        const fs::path d = fs::temp_directory_path() / "posthaste_bench";
        fs::create_directories(d);
        return d.string();
    }();
    return dir;
}

/// A 1920x1080 frame with 16 channels: color RGBA, depth, normal, position, motion, albedo.
Frame make_big_frame()
{
    const int w = 1920, h = 1080;
    Frame f;
    Image color(w, h, 4), depth(w, h, 1), normal(w, h, 3), position(w, h, 3), motion(w, h, 2),
        albedo(w, h, 3);
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            const float u = float(x) / w, v = float(y) / h;
            const float n = float((unsigned(x) * 73856093u) ^ (unsigned(y) * 19349663u)) * 1e-10f;
            float *c = color.pixel(x, y);
            c[0] = u + n;
            c[1] = v;
            c[2] = 0.5f * u * v + n;
            c[3] = 1.0f;
            depth.at(x, y, 0) = 1.0f + 50.0f * v + n;
            normal.at(x, y, 0) = u - 0.5f;
            normal.at(x, y, 1) = 0.7f;
            normal.at(x, y, 2) = v - 0.5f;
            position.at(x, y, 0) = 10.0f * u;
            position.at(x, y, 1) = n;
            position.at(x, y, 2) = 50.0f * v;
            motion.at(x, y, 0) = 3.0f * u;
            motion.at(x, y, 1) = -2.0f * v;
            albedo.at(x, y, 0) = 0.3f;
            albedo.at(x, y, 1) = 0.5f + n;
            albedo.at(x, y, 2) = 0.2f;
        }
    }
    f.set("color", std::move(color));
    f.set("depth", std::move(depth));
    f.set("normal", std::move(normal));
    f.set("position", std::move(position));
    f.set("motion", std::move(motion));
    f.set("albedo", std::move(albedo));
    return f;
}

struct Codec {
    const char *name;
    const char *compression;
    PixelStorage storage;
};
const Codec kCodecs[] = {{"half_piz", "piz", PixelStorage::Half},
                         {"float_zip", "zip", PixelStorage::Float},
                         {"float_none", "none", PixelStorage::Float}};

const std::string &source_file(int codec)
{
    static std::string paths[3];
    if (paths[codec].empty()) {
        const Frame f = make_big_frame();
        WriteOptions o;
        o.compression = kCodecs[codec].compression;
        for (const std::string &n : f.pass_names()) {
            o.storage[n] = kCodecs[codec].storage;
        }
        paths[codec] = bench_dir() + "/big_" + kCodecs[codec].name + ".exr";
        write_exr(f, paths[codec], o);
    }
    return paths[codec];
}

void BM_IoPosthasteCopy(benchmark::State &state)
{
    const int codec = int(state.range(0));
    const std::string &src = source_file(codec);
    const std::string dst = bench_dir() + "/out_posthaste.exr";
    WriteOptions o;
    o.compression = kCodecs[codec].compression;
    for (auto _ : state) {
        const Frame f = read_frame(src, nullptr, 1);
        for (const std::string &n : f.pass_names()) {
            o.storage[n] = kCodecs[codec].storage;
        }
        write_exr(f, dst, o);
    }
    state.SetLabel(kCodecs[codec].name);
}

void BM_IoOiioCopy(benchmark::State &state)
{
    const int codec = int(state.range(0));
    const std::string &src = source_file(codec);
    const std::string dst = bench_dir() + "/out_oiio.exr";
    for (auto _ : state) {
        auto in = OIIO::ImageInput::open(src);
        const OIIO::ImageSpec spec = in->spec();
        std::vector<char> pixels(spec.image_bytes(/*native=*/true));
        in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeUnknown, pixels.data());
        in->close();
        auto out = OIIO::ImageOutput::create(dst);
        out->open(dst, spec);
        out->write_image(OIIO::TypeUnknown, pixels.data());
        out->close();
    }
    state.SetLabel(kCodecs[codec].name);
}

void BM_IoPosthasteRead(benchmark::State &state)
{
    const std::string &src = source_file(int(state.range(0)));
    for (auto _ : state) {
        benchmark::DoNotOptimize(read_frame(src, nullptr, 1));
    }
    state.SetLabel(kCodecs[state.range(0)].name);
}

void BM_IoOiioRead(benchmark::State &state)
{
    const std::string &src = source_file(int(state.range(0)));
    for (auto _ : state) {
        auto in = OIIO::ImageInput::open(src);
        const OIIO::ImageSpec spec = in->spec();
        std::vector<float> pixels(spec.image_pixels() * std::size_t(spec.nchannels));
        in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeFloat, pixels.data());
        benchmark::DoNotOptimize(pixels.data());
    }
    state.SetLabel(kCodecs[state.range(0)].name);
}

// The write alone: posthaste's write_exr of a frame already read, beside OpenEXR's own API
// writing the same planes (one Imf::Slice per channel over the pass images; a half channel's
// plane converted first, as OpenEXR's OutputFile takes only slices of the channel's own type),
// OpenEXR's thread pool at the process's thread count. The second is the floor a writer through
// OpenEXR could reach: what is left above it is posthaste's (and OpenImageIO's) interleaving.
void BM_IoPosthasteWrite(benchmark::State &state)
{
    const int codec = int(state.range(0));
    const Frame f = read_frame(source_file(codec), nullptr, 1);
    const std::string dst = bench_dir() + "/write_posthaste.exr";
    WriteOptions o;
    o.compression = kCodecs[codec].compression;
    for (const std::string &n : f.pass_names()) {
        o.storage[n] = kCodecs[codec].storage;
    }
    for (auto _ : state) {
        write_exr(f, dst, o);
    }
    state.SetLabel(kCodecs[codec].name);
}

void BM_IoOpenExrWrite(benchmark::State &state)
{
    const int codec = int(state.range(0));
    const Frame f = read_frame(source_file(codec), nullptr, 1);
    const std::string dst = bench_dir() + "/write_openexr.exr";
    const bool half = kCodecs[codec].storage == PixelStorage::Half;
    const Imf::Compression compression[] = {
        Imf::PIZ_COMPRESSION, Imf::ZIP_COMPRESSION, Imf::NO_COMPRESSION};
    Imf::setGlobalThreadCount(thread_count());
    const int w = f.width(), h = f.height();
    std::vector<std::vector<unsigned char>> halves;
    for (auto _ : state) {
        Imf::Header header(w, h);
        header.compression() = compression[codec];
        Imf::FrameBuffer fb;
        halves.clear();
        for (const std::string &name : f.pass_names()) {
            const Image &img = f.image(name);
            const int nc = img.channels();
            const char *base = reinterpret_cast<const char *>(img.data());
            std::size_t xstride = std::size_t(nc) * sizeof(float);
            if (half) {
                halves.emplace_back(img.pixel_count() * std::size_t(nc) * 2);
                unsigned char *dst_half = halves.back().data();
                parallel_for(0, h, [&](int y) {
                    const std::size_t row = std::size_t(y) * std::size_t(w);
                    io_detail::floats_to_halves(img.data() + row * std::size_t(nc),
                                                nc,
                                                w,
                                                dst_half + row * std::size_t(nc) * 2,
                                                std::size_t(nc) * 2);
                });
                base = reinterpret_cast<const char *>(dst_half);
                xstride = std::size_t(nc) * 2;
            }
            for (int k = 0; k < nc; ++k) {
                const std::string ch = name + "." + std::to_string(k);
                const Imf::PixelType type = half ? Imf::HALF : Imf::FLOAT;
                header.channels().insert(ch, Imf::Channel(type));
                fb.insert(ch,
                          Imf::Slice(type,
                                     const_cast<char *>(base) + std::size_t(k) * (half ? 2 : 4),
                                     xstride,
                                     xstride * std::size_t(w)));
            }
        }
        Imf::OutputFile out(dst.c_str(), header);
        out.setFrameBuffer(fb);
        out.writePixels(h);
    }
    state.SetLabel(kCodecs[codec].name);
}

BENCHMARK(BM_IoOiioCopy)->DenseRange(0, 2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_IoPosthasteCopy)->DenseRange(0, 2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_IoPosthasteWrite)->DenseRange(0, 2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_IoOpenExrWrite)->DenseRange(0, 2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_IoOiioRead)->DenseRange(0, 2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_IoPosthasteRead)->DenseRange(0, 2)->Unit(benchmark::kMillisecond)->UseRealTime();

// Engine overhead: 100 small frames through read -> write, against direct calls.
const std::string &small_sequence()
{
    static const std::string pattern = [] {
        const std::string p = bench_dir() + "/small.####.exr";
        for (int f = 1; f <= 100; ++f) {
            Frame fr;
            Image c(64, 64, 4);
            c.fill(0.5f);
            fr.set("color", std::move(c));
            Image z(64, 64, 1);
            z.fill(3.0f);
            fr.set("depth", std::move(z));
            write_exr(fr, expand_frame_pattern(p, f), {});
        }
        return p;
    }();
    return pattern;
}

void BM_IoEngineGraph100(benchmark::State &state)
{
    const std::string &in = small_sequence();
    const std::string json = R"({"nodes": [
        {"id": "src", "type": "read", "params": {"path": ")" +
                             in + R"("}},
        {"id": "out", "type": "write", "inputs": {"image": "src"},
         "params": {"path": ")" +
                             bench_dir() + R"(/small_out.####.exr"}}]})";
    const Graph g = Graph::parse(json, "bench", nodes::catalog());
    for (auto _ : state) {
        for (int f = 1; f <= 100; ++f) {
            g.evaluate(f);
        }
    }
    state.counters["ms_per_frame"] =
        benchmark::Counter(100.0 * 1e-3 * double(state.iterations()),
                           benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}

void BM_IoDirectCalls100(benchmark::State &state)
{
    const std::string &in = small_sequence();
    const std::string out = bench_dir() + "/small_direct.####.exr";
    for (auto _ : state) {
        for (int f = 1; f <= 100; ++f) {
            const Frame fr = read_frame(expand_frame_pattern(in, f), nullptr, f);
            write_exr(fr, expand_frame_pattern(out, f), {});
        }
    }
    state.counters["ms_per_frame"] =
        benchmark::Counter(100.0 * 1e-3 * double(state.iterations()),
                           benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}

BENCHMARK(BM_IoDirectCalls100)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_IoEngineGraph100)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace posthaste
