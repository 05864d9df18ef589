// The graph's evaluation order (graph_order.h): consumers, the cycle check, and the order in
// which ready nodes run.
#include "graph/graph_order.h"

#include <algorithm>
#include <functional>
#include <string>

#include "core/error.h"

namespace posthaste {

std::vector<int> evaluation_order(std::vector<GraphNode> &nodes)
{
    // Consumers, topological order and cycles.
    const int count = int(nodes.size());
    for (int i = 0; i < count; ++i) {
        for (int src : nodes[std::size_t(i)].inputs) {
            if (src >= 0) {
                nodes[std::size_t(src)].consumers.push_back(i);
            }
        }
    }
    std::vector<int> state(std::size_t(count), 0);  // 0 new, 1 on stack, 2 done
    std::vector<int> stack;
    std::function<void(int)> visit = [&](int i) {
        state[std::size_t(i)] = 1;
        stack.push_back(i);
        for (int src : nodes[std::size_t(i)].inputs) {
            if (src < 0) {
                continue;
            }
            if (state[std::size_t(src)] == 1) {
                std::string cycle;
                auto it = std::find(stack.begin(), stack.end(), src);
                for (; it != stack.end(); ++it) {
                    cycle += nodes[std::size_t(*it)].identity.id + " <- ";
                }
                cycle += nodes[std::size_t(src)].identity.id;
                throw_usage(nodes[std::size_t(src)].identity.json_path,
                            "/inputs: node \"",
                            nodes[std::size_t(src)].identity.id,
                            "\" is in a cycle: ",
                            cycle);
            }
            if (state[std::size_t(src)] == 0) {
                visit(src);
            }
        }
        stack.pop_back();
        state[std::size_t(i)] = 2;
    };
    for (int i = 0; i < count; ++i) {
        if (state[std::size_t(i)] == 0) {
            visit(i);
        }
    }
    // Evaluation order: of the nodes whose inputs are ready, the one with the fewest nodes
    // downstream runs first, so short branches (a preview of the render, a hatching pass)
    // finish and free their frames before the long chain holds them (peak memory).
    {
        std::vector<int> downstream(std::size_t(count), 0);
        for (int i = 0; i < count; ++i) {
            std::vector<char> seen(std::size_t(count), 0);
            std::vector<int> todo = nodes[std::size_t(i)].consumers;
            while (!todo.empty()) {
                const int c = todo.back();
                todo.pop_back();
                if (!seen[std::size_t(c)]) {
                    seen[std::size_t(c)] = 1;
                    ++downstream[std::size_t(i)];
                    for (int d : nodes[std::size_t(c)].consumers) {
                        todo.push_back(d);
                    }
                }
            }
        }
        std::vector<char> done(std::size_t(count), 0);
        std::vector<int> order;
        while (int(order.size()) < count) {
            int best = -1;
            for (int i = 0; i < count; ++i) {
                if (done[std::size_t(i)]) {
                    continue;
                }
                bool ready = true;
                for (int src : nodes[std::size_t(i)].inputs) {
                    ready = ready && (src < 0 || done[std::size_t(src)]);
                }
                if (ready &&
                    (best < 0 || downstream[std::size_t(i)] < downstream[std::size_t(best)])) {
                    best = i;
                }
            }
            done[std::size_t(best)] = 1;
            order.push_back(best);
        }
        return order;
    }
}

}  // namespace posthaste
