// Fuzz target: the graph reader and checker's front half (JSON, node types, parameters, inputs,
// cycles, planning), --set strings and frame lists. The first line of the input is a --set
// override and a frame list; the rest is the graph.

#include "fuzz_common.h"
#include "graph/graph.h"
#include "nodes/registry.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t *data, std::size_t size)
{
    using namespace posthaste;
    const std::string text = fuzz::text_of(data, size);
    const auto newline = text.find('\n');
    const std::string first = text.substr(0, newline);
    const std::string graph = newline == std::string::npos ? text : text.substr(newline + 1);
    fuzz::expect_clean([&] { parse_frame_list(first, "--frames"); });
    fuzz::expect_clean([&] { Graph::parse(graph, "fuzz.json", nodes::catalog()); });
    fuzz::expect_clean([&] { Graph::parse(graph, "fuzz.json", nodes::catalog(), {first}); });
    return 0;
}
