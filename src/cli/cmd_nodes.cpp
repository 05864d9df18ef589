// posthaste nodes [TYPE]: every node type and its parameters, printed from the declarations.

#include <cstdio>

#include "cli/commands.h"
#include "core/error.h"
#include "graph/graph.h"
#include "nodes/registry.h"

namespace posthaste::cli {
namespace {

/// One parameter's line and help, indented by `indent`; a Records parameter's fields follow,
/// indented further.
void print_param(const ParamSpec &p, int indent)
{
    const std::string range = describe_range(p);
    const std::string condition = describe_condition(p);
    const std::string pad(std::size_t(indent), ' ');
    const int width = 20 - indent;
    std::printf("%s%-*s %-28s default %s%s%s%s%s%s%s\n%s    %s\n",
                pad.c_str(),
                width,
                std::string(p.name).c_str(),
                describe_type(p).c_str(),
                describe_default(p).c_str(),
                range.empty() ? "" : ", range ",
                range.c_str(),
                p.unit.empty() ? "" : ", ",
                std::string(p.unit).c_str(),
                condition.empty() ? "" : "; only when ",
                condition.c_str(),
                pad.c_str(),
                std::string(p.help).c_str());
    for (std::size_t i = 0; i < p.field_count; ++i) {
        print_param(p.fields[i], indent + 4);
    }
}

void print_type(const NodeType &t)
{
    const NodeSpec &s = t.spec;
    std::printf("%s: %s\n", std::string(s.type).c_str(), std::string(s.summary).c_str());
    if (s.inputs.empty()) {
        std::printf("  inputs: none (source)\n");
    }
    for (const PortSpec &p : s.inputs) {
        std::printf("  input %-12s%s reads: %s%s%s\n",
                    std::string(p.name).c_str(),
                    p.optional ? " (optional)" : "",
                    p.passes.empty() ? "-" : std::string(p.passes).c_str(),
                    p.help.empty() ? "" : "  ",
                    std::string(p.help).c_str());
    }
    if (!s.makes.empty()) {
        std::printf("  makes: %s\n", std::string(s.makes).c_str());
    }
    for (const ParamSpec &p : s.params) {
        print_param(p, 2);
    }
}

int nodes(const std::string &type)
{
    if (type.empty()) {
        for (const NodeType *t : all_node_types()) {
            std::printf("%-14s %s\n",
                        std::string(t->spec.type).c_str(),
                        std::string(t->spec.summary).c_str());
        }
        std::printf("\n'posthaste nodes TYPE' lists a node's inputs and parameters.\n");
        return 0;
    }
    if (type == "all") {
        for (const NodeType *t : all_node_types()) {
            print_type(*t);
            std::printf("\n");
        }
        return 0;
    }
    print_type(require_node_type(type));
    return 0;
}

}  // namespace

void add_nodes_command(CLI::App &app, int &exit_code)
{
    auto type = std::make_shared<std::string>();
    CLI::App *cmd = app.add_subcommand("nodes", "List node types, or one type's parameters");
    cmd->add_option("type", *type, "A node type, or 'all'");
    cmd->callback([type, &exit_code] { exit_code = nodes(*type); });
}

}  // namespace posthaste::cli
