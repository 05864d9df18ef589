// The farm job directory's own checks (farm_job.h): job.json's shape as the commands read it
// (a damaged file gave a crash or a raw nlohmann message), the graph written for the tasks with
// the --set values typed as `run` types them, and what `submit --force` may replace.

#include <algorithm>
#include <climits>
#include <fstream>
#include <set>

#include "cli/farm_job.h"
#include "core/error.h"
#include "graph/param.h"

namespace posthaste::cli::farm {

namespace {

/// job.json's shape: each check throws one line naming the file and the key's JSON path.
class JobShape {
   public:
    explicit JobShape(std::string file) : file_(std::move(file)) {}

    [[noreturn]] void fail(const std::string &key, const std::string &want) const
    {
        throw_runtime(file_, ": ", key, ": expected ", want, " (a damaged job directory?)");
    }
    /// obj[key], which must be there unless `optional`; null when absent.
    const json *at(const json &obj, const std::string &path, const char *key, bool optional) const
    {
        const auto it = obj.find(key);
        if (it == obj.end()) {
            if (!optional) {
                throw_runtime(file_, ": ", path, "/", key, ": missing (a damaged job directory?)");
            }
            return nullptr;
        }
        return &*it;
    }
    void string(const json &obj, const std::string &path, const char *key, bool optional) const
    {
        if (const json *v = at(obj, path, key, optional); v && !v->is_string()) {
            fail(path + "/" + key, "a string");
        }
    }
    void whole(const json &obj, const std::string &path, const char *key, int least) const
    {
        const json *v = at(obj, path, key, least == 0);
        if (v && (!is_int(*v) || v->get<long long>() < least)) {
            fail(path + "/" + key, str_cat("a whole number of at least ", least));
        }
    }
    void flag(const json &obj, const std::string &path, const char *key) const
    {
        if (const json *v = at(obj, path, key, true); v && !v->is_boolean()) {
            fail(path + "/" + key, "true or false");
        }
    }
    /// A job id: digits only, since it goes into squeue's command line.
    void job_id(const json &obj, const std::string &path, const char *key) const
    {
        const json *v = at(obj, path, key, true);
        if (v && (!v->is_string() || v->get<std::string>().empty() ||
                  v->get<std::string>().find_first_not_of("0123456789") != std::string::npos)) {
            fail(path + "/" + key, "a Slurm job id (digits)");
        }
    }
    std::vector<int> frames(const json &v, const std::string &path) const
    {
        if (!v.is_array() || !std::all_of(v.begin(), v.end(), is_int)) {
            fail(path, "an array of frame numbers");
        }
        return v.get<std::vector<int>>();
    }

   private:
    static bool is_int(const json &v)
    {
        return v.is_number_integer() &&
               (v.is_number_unsigned()
                    ? v.get<unsigned long long>() <= INT_MAX
                    : v.get<long long>() >= INT_MIN && v.get<long long>() <= INT_MAX);
    }
    std::string file_;
};

}  // namespace

json read_job(const fs::path &dir)
{
    const fs::path file = dir / "job.json";
    const json job = read_json(file);
    const JobShape shape(file.string());
    if (!job.is_object()) {
        shape.fail("/", "an object");
    }
    shape.string(job, "", "cwd", false);
    const std::vector<int> frames = shape.frames(*shape.at(job, "", "frames", false), "/frames");
    const std::set<int> known(frames.begin(), frames.end());
    const json &subs = *shape.at(job, "", "submissions", false);
    if (!subs.is_array()) {
        shape.fail("/submissions", "an array");
    }
    for (std::size_t s = 0; s < subs.size(); ++s) {
        const std::string path = "/submissions/" + std::to_string(s);
        if (!subs[s].is_object()) {
            shape.fail(path, "an object");
        }
        const json *chunks = shape.at(subs[s], path, "chunks", false);
        if (!chunks->is_array()) {
            shape.fail(path + "/chunks", "an array of frame lists");
        }
        for (std::size_t k = 0; k < chunks->size(); ++k) {
            const std::string chunk = path + "/chunks/" + std::to_string(k);
            for (int f : shape.frames((*chunks)[k], chunk)) {
                if (!known.count(f)) {
                    shape.fail(chunk, str_cat("frames of /frames (", f, " is not one)"));
                }
            }
        }
        shape.job_id(subs[s], path, "array_job");
        shape.job_id(subs[s], path, "check_job");
    }
    shape.string(job, "", "binary", false);
    shape.whole(job, "", "chunk", 1);
    shape.flag(job, "", "chunk_auto");
    shape.flag(job, "", "interleaved");
    const json &slurm = *shape.at(job, "", "slurm", false);
    if (!slurm.is_object()) {
        shape.fail("/slurm", "an object");
    }
    shape.whole(slurm, "/slurm", "max_running", 0);
    shape.whole(slurm, "/slurm", "cpus_per_task", 0);
    for (const char *key : {"partition", "mem", "time"}) {
        shape.string(slurm, "/slurm", key, true);
    }
    return job;
}

/// The values are typed as `run` types them (graph_parse.cpp): for a string or choice parameter
/// the text as it is (a JSON string when quoted), else JSON when it parses, else the text; a
/// 6 for a string parameter written as the number 6 failed every task. The copy lives in the
/// job folder, so it says where its relative paths point: "base_dir" is the original graph's
/// folder, and relative --set file paths (relative to the current folder, as on the command
/// line) become absolute.
std::string apply_sets(const std::string &graph_path,
                       const Graph &graph,
                       const std::vector<std::string> &sets)
{
    std::ifstream in(graph_path);
    json g = json::parse(in, nullptr, false);
    if (g.is_discarded() || !g.contains("nodes")) {
        throw_usage(graph_path, ": not a graph file");
    }
    for (const std::string &s : sets) {
        const auto eq = s.find('='), dot = s.find('.');
        const std::string id = s.substr(0, dot), name = s.substr(dot + 1, eq - dot - 1);
        const std::string text = s.substr(eq + 1);
        const ParamSpec *spec = nullptr;
        if (const int n = graph.find(id); n >= 0) {
            for (const ParamSpec &ps : graph.nodes()[std::size_t(n)].type->spec.params) {
                spec = ps.name == name ? &ps : spec;
            }
        }
        json value = text;
        if (spec && (spec->type == ParamType::String || spec->type == ParamType::Choice)) {
            if (text.size() >= 2 && text.front() == '"' && text.back() == '"') {
                if (const json q = json::parse(text, nullptr, false); q.is_string()) {
                    value = q;
                }
            }
        } else if (const json v = json::parse(text, nullptr, false); !v.is_discarded()) {
            value = v;
        }
        if (spec && spec->file && value.is_string() && !value.get<std::string>().empty() &&
            fs::path(value.get<std::string>()).is_relative()) {
            value = fs::absolute(value.get<std::string>()).lexically_normal().string();
        }
        for (json &node : g["nodes"]) {
            if (node.is_object() && node.value("id", json()) == id) {
                node["params"][name] = value;
            }
        }
    }
    g["base_dir"] =
        fs::absolute(graph.base_dir().empty() ? "." : graph.base_dir()).lexically_normal().string();
    return g.dump(2) + "\n";
}

/// Chunks of `chunk` frames: contiguous, or `interleaved` (chunk k of n takes frames k, k + n,
/// ...), so that a cost drifting along the sequence is shared evenly by the tasks; only for
/// graphs that do not look back (Graph::looks_back), where a frame costs the same in any chunk.
std::vector<std::vector<int>> make_chunks(const std::vector<int> &frames,
                                          int chunk,
                                          bool interleaved)
{
    std::vector<std::vector<int>> chunks;
    if (interleaved) {
        const std::size_t n = (frames.size() + std::size_t(chunk) - 1) / std::size_t(chunk);
        chunks.resize(n);
        for (std::size_t i = 0; i < frames.size(); ++i) {
            chunks[i % n].push_back(frames[i]);
        }
        return chunks;
    }
    for (std::size_t i = 0; i < frames.size(); i += std::size_t(chunk)) {
        chunks.emplace_back(
            frames.begin() + std::ptrdiff_t(i),
            frames.begin() + std::ptrdiff_t(std::min(frames.size(), i + std::size_t(chunk))));
    }
    return chunks;
}

void require_replaceable(const fs::path &dir,
                         const std::string &graph_path,
                         const std::vector<std::string> &outputs)
{
    std::error_code ec;
    const fs::file_status st = fs::symlink_status(dir, ec);
    if (!fs::exists(st)) {
        return;
    }
    const auto refuse = [&](const std::string &why) {
        throw_usage("farm submit: --force: ", dir.string(), " ", why, ": not replaced");
    };
    if (!fs::is_directory(st)) {
        refuse("is not a job directory");
    }
    const fs::path real = fs::canonical(dir, ec);
    // Whether `p` is `dir` or lies under it (a path that does not exist yet, as an output).
    const auto holds = [&](const fs::path &p) {
        std::error_code e;
        const fs::path c = fs::weakly_canonical(fs::absolute(p), e).lexically_normal();
        return !ec && !e &&
               std::mismatch(real.begin(), real.end(), c.begin(), c.end()).first == real.end();
    };
    if (ec) {
        refuse("cannot be resolved (" + ec.message() + ")");
    }
    if (holds(fs::current_path())) {
        refuse("is the current folder or holds it");
    }
    if (holds(graph_path)) {
        refuse("holds the graph " + graph_path);
    }
    for (const std::string &o : outputs) {
        if (holds(o)) {
            refuse("holds the output " + o);
        }
    }
    const bool job = fs::is_regular_file(dir / "job.json", ec);
    if (!job && !fs::is_empty(dir, ec)) {
        refuse("is not a posthaste job directory (no job.json) and not empty");
    }
}

}  // namespace posthaste::cli::farm
