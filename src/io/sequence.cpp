#include "io/sequence.h"

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <filesystem>

#include "core/error.h"

namespace posthaste {
namespace {

struct Placeholder {
    std::size_t begin = std::string::npos;
    std::size_t end = 0;  // one past
    int width = 0;
};

Placeholder find_placeholder(const std::string &p)
{
    // The last placeholder in the name wins (directories may contain '#' in rare cases).
    for (std::size_t i = p.size(); i-- > 0;) {
        if (p[i] == '#' || p[i] == '@') {
            std::size_t b = i;
            while (b > 0 && (p[b - 1] == '#' || p[b - 1] == '@')) {
                --b;
            }
            return {b, i + 1, int(i + 1 - b)};
        }
        if (p[i] == 'd' && i > 0) {
            std::size_t b = i;
            while (b > 0 && std::isdigit(static_cast<unsigned char>(p[b - 1]))) {
                --b;
            }
            if (b > 0 && p[b - 1] == '%') {
                const std::string digits = p.substr(b, i - b);
                // No file name holds more than 255 bytes: %2147483647d took 8 GB to say so,
                // and a width past int's range threw from stoi.
                const auto width = digits.find_first_not_of('0') == std::string::npos
                                       ? 0
                                       : std::stoll(digits.substr(0, 12));
                if (digits.size() > 12 || width > 255) {
                    throw_usage(p,
                                ": the frame number is padded to ",
                                digits.size() > 12 ? digits : std::to_string(width),
                                " digits, more than a file name holds (255 bytes)");
                }
                return {b - 1, i + 1, int(width)};
            }
        }
    }
    return {};
}

std::string format_frame(int frame, int width)
{
    std::string digits = std::to_string(frame < 0 ? -(long long)frame : (long long)frame);
    if (int(digits.size()) < width) {
        digits.insert(0, std::size_t(width) - digits.size(), '0');
    }
    return (frame < 0 ? "-" : "") + digits;
}

}  // namespace

bool has_frame_placeholder(const std::string &pattern)
{
    return find_placeholder(pattern).begin != std::string::npos;
}

std::string expand_frame_pattern(const std::string &pattern, int frame)
{
    const Placeholder ph = find_placeholder(pattern);
    if (ph.begin == std::string::npos) {
        return pattern;
    }
    return pattern.substr(0, ph.begin) + format_frame(frame, ph.width) + pattern.substr(ph.end);
}

std::vector<int> find_frames_on_disk(const std::string &pattern)
{
    const Placeholder ph = find_placeholder(pattern);
    std::vector<int> frames;
    if (ph.begin == std::string::npos) {
        return frames;
    }
    namespace fs = std::filesystem;
    const fs::path full(pattern.substr(0, ph.begin));
    const std::string prefix_dir =
        full.has_parent_path() || pattern.substr(0, ph.begin).ends_with('/')
            ? fs::path(pattern.substr(0, ph.begin)).parent_path().string()
            : std::string();
    const std::string head =
        pattern.substr(0, ph.begin).substr(prefix_dir.empty() ? 0 : prefix_dir.size() + 1);
    const std::string tail = pattern.substr(ph.end);
    if (tail.find('/') != std::string::npos) {
        return frames;  // placeholder in a directory name: not scanned
    }
    std::error_code ec;
    for (const auto &entry : fs::directory_iterator(prefix_dir.empty() ? "." : prefix_dir, ec)) {
        const std::string name = entry.path().filename().string();
        if (name.size() <= head.size() + tail.size() || !name.starts_with(head) ||
            !name.ends_with(tail)) {
            continue;
        }
        const std::string mid = name.substr(head.size(), name.size() - head.size() - tail.size());
        const bool negative = !mid.empty() && mid[0] == '-';
        const std::string digits = negative ? mid.substr(1) : mid;
        if (digits.empty() || digits.size() > 9 ||
            !std::all_of(digits.begin(), digits.end(), [](char c) {
                return std::isdigit(static_cast<unsigned char>(c));
            })) {
            continue;
        }
        if (int(digits.size()) < ph.width) {
            continue;
        }
        const int frame = (negative ? -1 : 1) * std::stoi(digits);
        if (expand_frame_pattern(pattern.substr(prefix_dir.empty() ? 0 : prefix_dir.size() + 1),
                                 frame) == name) {
            frames.push_back(frame);
        }
    }
    std::sort(frames.begin(), frames.end());
    return frames;
}

}  // namespace posthaste
