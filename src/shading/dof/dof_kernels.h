#pragma once
// The depth-of-field gather's group kernels (shading/dof/dof_gather.cpp), written once over
// Highway's lane types (dof_kernels.cpp) and dispatched at run time. A group is eight
// horizontally adjacent pixels that share their tap offsets, so every tap is one contiguous load
// per plane (a gather of edge-clamped columns across the image border); a target narrower than
// eight lanes runs the group in pieces, each lane summing its taps in the same order.

#include <cstddef>
#include <cstdint>

namespace posthaste::shading::dof {

inline constexpr int kLanes = 8;

/// One resolution level of the gather's input as planes: colour channels, signed CoC radius
/// (pixels), 1 / CoC^2 (+inf at 0) and size.
struct PlanesView {
    const float *ch[4] = {nullptr, nullptr, nullptr, nullptr};
    const float *coc = nullptr;
    const float *inv2 = nullptr;
    int width = 0, height = 0;
};

/// A sample of a spiral: integer pixel offset and rim = 0.5 - the shape-normalised distance of
/// the pixel read (a CoC of radius r covers clamp(r + rim, 0, 1) of it).
struct Tap {
    std::int16_t dx, dy;
    float rim;
};

/// Per-lane state of one group: the pixel's own CoC, |CoC| and background self weight, and the
/// running sums of the near (front) and background (back) layers.
struct Group {
    float cp[kLanes], acp[kLanes], w_self[kLanes];
    float front[4][kLanes], front_w[kLanes], near_w[kLanes];
    float back[4][kLanes], back_w[kLanes];
};

/// The group's starting sums for pixels x0 .. x0 + 7 of row y: each pixel itself, in the near
/// layer when its CoC is in the near field (< -0.5), else in the background, weighed
/// min(1 / c^2, 1). Lanes from `count` on repeat the row's last pixel.
void setup_group(const PlanesView &lv, int x0, int y, int count, Group &g);

/// The near field's taps: samples q with c_q < -0.5 and c_q <= c_p + 1 spread with their own
/// CoC, weight clamp(rim - c_q, 0, 1) / c_q^2, into front, front_w and near_w.
void near_pass(const PlanesView &lv, int x0, int y, const Tap *taps, int n, Group &g);

/// The background's taps (every sample the near pass does not take) for the lanes set in
/// `lanes`. Behind p (c_q > c_p) a sample counts with p's own radius when p is in the near
/// field (the background within p's disc shows through it), else with min(|c_q|, |c_p|): a far
/// field never bleeds over a sharper foreground; not behind p and not in the near field with its
/// own. Both cases are r = min(max(|c_q|, lo), |c_p|) with lo = |c_p| in the near field and 0
/// elsewhere, weight clamp(r + rim, 0, 1) * max(min(1 / c_q^2, hi), ws) with ws = the lane's
/// self weight, hi = 0 in the near field and 1 elsewhere; a lane outside the pass has hi = ws =
/// 0. offsets[i] is tap i's element offset, used when the whole reach lies inside the image.
void back_pass(const PlanesView &lv,
               int x0,
               int y,
               const Tap *taps,
               const std::ptrdiff_t *offsets,
               int n,
               int reach,
               unsigned lanes,
               Group &g);

/// back (1 - alpha) + front alpha per lane from the sums: weighted means, alpha = min(near_w
/// sample_area, 1); with no background weight the near layer stands alone.
void composite_group(const Group &g, float sample_area, float (*out)[kLanes]);

/// Pixels x0 .. x1 - 1 of an interleaved row of nc channels into four planes (channels past nc
/// are 0), non-finite values as 0.
void split_row(const float *src, int nc, int x0, int x1, float *const *plane);

/// The first `count` lanes of four channel rows into nc-channel interleaved pixels (nc <= 4).
void merge_row(const float (*v)[kLanes], int count, int nc, float *dst);

}  // namespace posthaste::shading::dof
