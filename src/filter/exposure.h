#pragma once
// Exposure: the photographic scale from f-number, shutter time and ISO, the metering of a frame
// (a log-luminance histogram with a percentile window) and the adaptation of an auto exposure
// over a sequence (exponential, with separate speeds toward brighter and darker scenes).

#include <utility>
#include <vector>

#include "core/image.h"

namespace posthaste::filter {

/// EV100 = log2(N^2 / t * 100 / S).
double ev100(double fstop, double shutter_seconds, double iso);

/// The scale from scene luminance to the sensor's [0, 1] range for a camera at `ev100`:
/// 1 / (1.2 * 2^EV100) (the saturation-based sensitivity with the usual lens and vignetting
/// factor q = 0.65: L_max = 78 / (q S) * N^2 / t).
double photographic_scale(double ev100);

/// A photographic exposure's lens and film (the shutter time is the caller's: it may come from
/// the header's fraction of the frame interval and the frame rate).
struct PhotographicParams {
    double fstop = 8.0;  ///< f-number
    double iso = 100.0;  ///< sensitivity
};

struct MeterParams {
    double min_ev = -10.0;  ///< histogram range, log2 of Rec.709 luminance
    double max_ev = 20.0;
    double low_percentile = 50.0;  ///< of the samples, darkest first, the window averaged
    double high_percentile = 95.0;
    int step = 4;  ///< every step-th pixel of every step-th row is sampled
};

/// The mean log2 luminance (Rec.709 weights of the first three channels) of the samples whose
/// rank lies in the percentile window, from a 1024-bin histogram over [min_ev, max_ev] that keeps
/// each bin's sum (so a fully counted bin contributes its samples' exact mean). Non-finite
/// samples are skipped; luminance <= 2^min_ev counts as min_ev. Returns min_ev for an image
/// without samples. Deterministic: the same bits whatever the thread count.
double meter_log2_luminance(const Image &image, const MeterParams &p);

/// One frame's metered target: (frame number, target EV).
using MeterSample = std::pair<int, double>;

/// The adapted EV after the samples (ascending frames): starts at the first sample's target, then
/// for each next sample moves toward its target by 1 - exp(-speed dt), dt = frame gap / fps,
/// speed = speed_up toward a brighter target (a higher EV), speed_down toward a darker one.
/// speed <= 0 or infinite: no adaptation (the last target).
double adapt_ev(const std::vector<MeterSample> &samples,
                double fps,
                double speed_up,
                double speed_down);

/// `in` with its first three channels times `scale` (other channels copied); non-finite values
/// stay as they are (a point operation).
Image scale_rgb(const Image &in, float scale);

}  // namespace posthaste::filter
