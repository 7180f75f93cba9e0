#include <algorithm>
#include <array>
#include <chrono>
#include <exception>
#include <functional>
#include <future>
#include <mutex>
#include <climits>
#include <clearfit/error.hpp>
#include <clearfit/format.hpp>
#include <clearfit/fit/assessment.hpp>
#include <clearfit/fit/assessment_stages.hpp>

#include "baseline_photometry.hpp"
#include <cmath>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <sstream>

namespace clearfit {
namespace {

using Clock = std::chrono::steady_clock;
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

std::string fmt(double v, int digits = 1) { return fixed_digits(v, digits); }

/// Bounding box of the pixels that see the skin (and of those the baseline's own rays leave from), padded for motion.
cv::Rect seen_roi(const RefractionMap& map, const BaselineRays* baseline, int pad) {
  int x0 = map.width, y0 = map.height, x1 = -1, y1 = -1;
  auto add = [&](int x, int y) {
    x0 = std::min(x0, x), x1 = std::max(x1, x);
    y0 = std::min(y0, y), y1 = std::max(y1, y);
  };
  for (int y = 0; y < map.height; ++y)
    for (int x = 0; x < map.width; ++x)
      if (map.status[map.index(x, y)] == PixelStatus::valid) add(x, y);
  if (baseline)
    for (std::uint32_t p : baseline->pixels()) add(static_cast<int>(p % map.width), static_cast<int>(p / map.width));
  if (x1 < 0) return {};
  cv::Rect r(x0 - pad, y0 - pad, x1 - x0 + 1 + 2 * pad, y1 - y0 + 1 + 2 * pad);
  return r & cv::Rect(0, 0, map.width, map.height);
}

PhaseReport phase_report(const CaptureSums& sums, const PhaseAverage& avg, bool compensated) {
  PhaseReport r;
  r.source = sums.info.source.string();
  r.frames_total = sums.info.frames;
  r.window = avg.window;
  r.fps = sums.info.fps;
  r.motion_px_max = avg.motion_px_max;
  r.jitter_px_rms = avg.jitter_px_rms;
  r.rotation_deg_max = avg.rotation_deg_max;
  r.rotation_scale_px_max = avg.rotation_scale_px_max;
  r.motion_compensated = compensated;
  r.saturated_fraction = avg.saturated_fraction;
  r.mean_code = avg.mean_code;
  r.gain_min = avg.gain_min, r.gain_max = avg.gain_max, r.gain_sigma = avg.gain_sigma;
  r.codec = sums.info.codec, r.pixel_format = sums.info.pixel_format, r.colour_matrix = sums.info.colour_matrix;
  r.lossy = sums.info.lossy, r.limited_range = sums.info.limited_range;
  r.rotation_deg = sums.info.rotation_deg, r.bit_depth = sums.info.bit_depth;
  return r;
}

/// The pixels of `roi` that see the skin (CV_8U, 255).
cv::Mat seen_pixels(const RefractionMap& map, const cv::Rect& roi) {
  cv::Mat seen(roi.size(), CV_8U, cv::Scalar(0));
  for (int y = 0; y < roi.height; ++y)
    for (int x = 0; x < roi.width; ++x)
      if (map.status[map.index(roi.x + x, roi.y + y)] == PixelStatus::valid) seen.at<std::uint8_t>(y, x) = 255;
  return seen;
}

/// The pixels of `roi` the baseline's own rays leave from (CV_8U, 255): where its capture can see the skin.
cv::Mat baseline_seen_pixels(const BaselineRays& rays, const cv::Rect& roi) {
  cv::Mat seen(roi.size(), CV_8U, cv::Scalar(0));
  for (std::uint32_t p : rays.pixels()) {
    const int x = static_cast<int>(p % rays.width()) - roi.x, y = static_cast<int>(p / rays.width()) - roi.y;
    if (x >= 0 && y >= 0 && x < roi.width && y < roi.height) seen.at<std::uint8_t>(y, x) = 255;
  }
  return seen;
}

/// The share of each pixel of `roi` that sees the skin (CV_32F; RefractionMap::seen_share).
cv::Mat seen_shares(const RefractionMap& map, const cv::Rect& roi) {
  cv::Mat1f seen(roi.size(), 0.f);
  for (int y = 0; y < roi.height; ++y)
    for (int x = 0; x < roi.width; ++x) seen(y, x) = map.seen_share(map.index(roi.x + x, roi.y + y));
  return seen;
}

/// The fall-off between phases seen at different pixels: a refused estimate is worth a warning.
void warn_vignetting(const VignettingEstimate& v, std::vector<std::string>& warnings) {
  if (!v.estimated && v.problem.find("not vignetting") != std::string::npos)
    warnings.push_back("the image's fall-off between the phases was not divided out: " + v.problem +
                       " (the exposure or the light changed across the view between the phases?)");
}

/// Lossy captures: which codec, and what the spatial noise term (blanching.hpp) did to the noise.
void warn_lossy(Assessment& a) {
  std::string codecs = a.baseline.codec + " (" + a.baseline.pixel_format + ")";
  if (a.worn.source != a.baseline.source) codecs = "baseline " + codecs + ", worn " + a.worn.codec + " (" + a.worn.pixel_format + ")";
  a.warnings.push_back("the capture is lossy: " + codecs + "; compression noise does not average away over frames, so the "
                       "noise includes a spatial term of " + fmt(a.signal.spatial_noise_sigma, 4) +
                       " (the unpressed skin's spread between the phases), raising it from " + fmt(a.signal.temporal_noise_sigma, 4) +
                       " to " + fmt(a.signal.noise_sigma, 4) + "; film losslessly (or at the highest quality) to see weaker pressure");
}

/// A BGR8 image resampled onto the chart (black where unseen).
cv::Mat chart_picture(const cv::Mat& bgr, const InverseMap& inv, const Vec2& shift) {
  cv::Mat mx(inv.height, inv.width, CV_32F), my(inv.height, inv.width, CV_32F);
  for (int j = 0; j < inv.height; ++j)
    for (int i = 0; i < inv.width; ++i) {
      const auto k = inv.index(i, j);
      mx.at<float>(j, i) = inv.valid[k] ? inv.map_x[k] + static_cast<float>(shift.x()) : -1e6f;
      my.at<float>(j, i) = inv.valid[k] ? inv.map_y[k] + static_cast<float>(shift.y()) : -1e6f;
    }
  cv::Mat out;
  cv::remap(bgr, out, mx, my, cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(0, 0, 0));
  return out;
}

/// The glare mask and, with a baseline read through its own view, the fall-off estimated on the way.
struct GlareFound {
  GlareMask glare;
  VignettingEstimate vignetting;
};

/// The glare, with the phases compared where they see the same skin: with its own view (its own
/// geometry, or the phase registration's field) the baseline is read where it sees the worn capture's
/// skin, through its own transmittance and share of the fall-off (estimated here); only the skin both
/// phases see is compared.
GlareFound find_glare(const RefractionMap& map, const PhaseAverage& base_avg, const PhaseAverage& worn_avg, const RefractionMap* base_map,
                      const InverseMap* view, const AssessmentOptions& o) {
  GlareFound out;
  cv::Mat seen = seen_pixels(map, base_avg.roi);
  if (!view) {
    out.glare = detect_glare(base_avg, worn_avg, seen, o.glare);
    return out;
  }
  VignettingOptions vo = o.vignetting;
  vo.enabled = vo.enabled && base_map;
  BaselineAsWorn as_worn = baseline_as_worn(base_avg, worn_avg, map, base_map ? *base_map : map, *view, vo);
  cv::bitwise_and(seen, as_worn.comparable, seen);
  out.vignetting = std::move(as_worn.vignetting);
  out.glare = detect_glare(as_worn.average, worn_avg, seen, o.glare);
  return out;
}

/// The baseline's gap (baseline_gap.hpp), with the glare left out. A highlight is texture that does not move
/// with the skin: one that stays in the image reads as skin without parallax and pulls the gap towards 0, one in
/// a single phase matches nothing (the wristband's realistic preset: 0.953 ± 0.022 mm for a 1.0 mm gap, and at
/// the band's oblique end, where the gap's parallax is largest, a false 4.5 mm² place). The glare is found with
/// the baseline read at a first estimate and the gap estimated again without it.
GapEstimate estimate_gap_without_glare(const AssessmentScene& scene, const PhaseAverage& base_avg, const PhaseAverage& worn_avg,
                                       const AssessmentOptions& o) {
  const InverseMap& inv = *scene.inverse;
  ChartField worn_green = resample_to_chart(worn_avg, inv);
  const GapEstimate first = estimate_gap(*scene.baseline_rays, base_avg, worn_green, o.gap);
  if (!o.glare.enabled || !first.estimated) return first;
  const RefractionMap map = scene.baseline_rays->map(first.gap_mm);
  const InverseMap view = compute_inverse_map(map, scene.inverse_options, scene.contact);
  const GlareMask glare = find_glare(*scene.forward, base_avg, worn_avg, &map, &view, o).glare;
  if (glare.regions == 0) return first;
  // The mask is on the worn capture's pixels; the baseline's own highlights lie there too, up to the
  // parallax (its margin covers it) and the phases' residual shifts (sub-pixel to a few pixels).
  PhaseAverage base = base_avg;
  base.mean = base_avg.mean.clone();
  base.mean.setTo(std::numeric_limits<float>::quiet_NaN(), glare.mask);
  const std::vector<std::uint8_t> texels = glare_texels(glare, inv, worn_avg.residual_shift_px);
  for (std::size_t k = 0; k < texels.size(); ++k)
    if (texels[k]) worn_green.value[k] = std::numeric_limits<float>::quiet_NaN();
  const GapEstimate second = estimate_gap(*scene.baseline_rays, base, worn_green, o.gap);
  return second.estimated ? second : first;
}

/// The baseline's own map at the given or estimated gap; fills a.baseline_geometry and its warnings.
RefractionMap baseline_geometry(const AssessmentScene& scene, const PhaseAverage& base_avg, const PhaseAverage& worn_avg, Assessment& a,
                                const AssessmentOptions& o) {
  BaselineGeometryReport& r = a.baseline_geometry;
  r.part = scene.baseline_part;
  if (scene.baseline_gap_mm) {
    r.gap_mm = *scene.baseline_gap_mm;
  } else {
    if (o.progress) o.progress("estimating the baseline's gap", 0, 0);
    const GapEstimate e = estimate_gap_without_glare(scene, base_avg, worn_avg, o);
    r.estimate = e;
    r.gap_mm = e.gap_mm;
    r.gap_sigma_mm = e.sigma_mm;
    r.gap_estimated = e.estimated;
    r.phase_shift_measured = e.phase_shift_measured, r.phase_shift_px = e.phase_shift_px, r.phase_shift_sigma_px = e.phase_shift_sigma_px;
    // Does the gap matter? Over the searched range it moves the baseline's skin points by shift · range.
    const double moved_mm = e.shift_mm_per_mm * o.gap.max_mm;
    if (!e.estimated) {
      const std::string part = to_string(scene.baseline_part);
      if (moved_mm > scene.inverse->texel_mm)
        throw InputError(a.baseline.source, "baseline.gap_mm: auto",
                         "the gap between the skin and the part (" + part + ") in the not-worn capture cannot be estimated: " + e.problem +
                             "; it matters here (each mm moves the skin seen by " + fmt(e.shift_mm_per_mm, 3) + " mm)",
                         "give baseline.gap_mm (the distance from the part's contact surface to the skin when the not-worn capture "
                         "was filmed; 0 with the part resting on the skin), or film the not-worn capture with the part touching the "
                         "skin and set baseline.part: touching");
      a.warnings.push_back("the baseline's gap could not be estimated (" + e.problem + "); it hardly matters here (each mm moves the "
                           "skin seen by " + fmt(e.shift_mm_per_mm, 3) + " mm), so " + fmt(e.gap_mm, 2) + " mm is used");
    } else if (e.sigma_mm > o.gap.warn_sigma_mm) {
      a.warnings.push_back("the baseline's gap estimate is unsure: " + fmt(e.gap_mm, 3) + " ± " + fmt(e.sigma_mm, 3) + " mm (σ above " +
                           fmt(o.gap.warn_sigma_mm, 2) + " mm; it moves the skin seen by ± " + fmt(e.sigma_mm * e.shift_mm_per_mm, 3) +
                           " mm); give baseline.gap_mm if it is known");
    }
  }
  RefractionMap m = scene.baseline_rays->map(r.gap_mm);
  r.pixels_seeing_skin = m.stats.by_status[0];
  return m;
}

/// One video whose not-worn phase has its own geometry, read with a registration reference per
/// view (CaptureReadOptions::max_references): each averaging window must keep one reference, else
/// the view jumped within a phase (refused as motion). The worn window is placed where its frames
/// were, as a worn capture of its own is: the motion measured across the change of geometry (or
/// against another reference) is the change, not motion.
void place_worn_window(const CaptureSums& sums, const PhaseAverage& base, PhaseAverage& worn, double max_motion_px) {
  auto check = [&](const PhaseAverage& w, const std::string& phase) {
    const int first = w.window.first, last = std::min<int>(w.window.first + w.window.count, static_cast<int>(sums.reference.size())) - 1;
    for (int f = first + 1; f <= last; ++f)
      if (sums.reference[f] != sums.reference[first])
        throw InputError(sums.info.source.string(), "frame " + std::to_string(f),
                         "moved more than the " + fmt(max_motion_px, 1) + " px clearfit compensates within the " + phase +
                             " phase's averaging window (frames " + std::to_string(first) + ".." + std::to_string(last) + ")",
                         "hold the part and the skin still while filming (a fixture helps), or raise captures.max_motion_px "
                         "if the motion is a steady drift");
  };
  check(base, "not-worn");
  check(worn, "worn");
  if (worn.window.count <= 0) return;
  Vec2 mean = Vec2::Zero();
  for (int f = worn.window.first; f < worn.window.first + worn.window.count; ++f) mean += sums.shift_px[f];
  if (mean.allFinite()) worn.residual_shift_px -= mean / worn.window.count;
}
/// What reading the captures hands on to the later stages: the two phases' window averages, the
/// worn capture's last frame (and its content's displacement against the reference frame), and the
/// phases over time when the timeline is on.
struct Phases {
  PhaseAverage base_avg, worn_avg;
  cv::Mat worn_frame;
  Vec2 worn_frame_shift = Vec2::Zero();
  std::optional<TimeSeriesRecorder> base_series, worn_series;  // the worn phase over time (timeseries.hpp)
};

/// The options both phases are read with: the roi that sees the skin (in either geometry, with
/// room for the motion compensated), the sums kept, the expected image size.
CaptureReadOptions capture_read_options(const AssessmentScene& scene, bool own_geometry, const AssessmentOptions& o) {
  const RefractionMap& map = *scene.forward;
  CaptureReadOptions ro;
  ro.roi = seen_roi(map, own_geometry ? scene.baseline_rays : nullptr, static_cast<int>(std::ceil(o.max_motion_px)) + 2);
  ro.chunk_frames = o.chunk_frames;
  ro.register_motion = o.compensate_motion;
  ro.seen = seen_pixels(map, ro.roi);
  ro.colour = o.glare.enabled;
  ro.red = o.phase_registration.enabled;
  ro.max_motion_px = o.max_motion_px;
  ro.expected_width = scene.camera->width;
  ro.expected_height = scene.camera->height;
  return ro;
}

/// Stage 1: reads both phases into their window averages, from one video holding both (split at
/// the press) or from two files (each one's last frames); fills a.baseline, a.worn, a.split and the
/// reading times.
void read_phases(const AssessmentScene& scene, const CaptureSources& captures, bool own_geometry, const AssessmentOptions& o,
                 Assessment& a, Phases& p) {
  const RefractionMap& map = *scene.forward;
  CaptureReadOptions ro = capture_read_options(scene, own_geometry, o);
  // With its own geometry the not-worn capture sees the skin through other pixels: its registration's patches go
  // there (one video holding both phases: where either phase sees it).
  cv::Mat base_seen;
  if (own_geometry && ro.roi.area() > 0) base_seen = baseline_seen_pixels(*scene.baseline_rays, ro.roi);
  if (!base_seen.empty() && !captures.both.empty()) cv::bitwise_or(ro.seen, base_seen, ro.seen);
  // With its own geometry the baseline sees the skin elsewhere in the image: each phase is
  // registered to its own first frame, and the maps bring both onto the chart. With the phase
  // registration too: the skin's move between the phases is the registration's, not the camera's.
  MotionReference reference, worn_reference;
  if (o.timeseries.enabled) o.timeseries.validate();
  // One read: its own copy of the options (both phases may be read at once), its times added by the caller.
  auto read = [&](const std::filesystem::path& path, const std::string& role, std::optional<TimeSeriesRecorder>* series,
                  std::function<void(int, int)> progress) {
    CaptureReadOptions r = ro;
    r.role = role;
    if (role == "baseline" && !base_seen.empty()) r.seen = base_seen;
    MotionReference& ref = (own_geometry || o.phase_registration.enabled) && role == "worn" ? worn_reference : reference;
    r.on_frame = nullptr;
    if (o.timeseries.enabled && series && r.roi.area() > 0) {
      series->emplace(r.roi & cv::Rect(0, 0, map.width, map.height), o.timeseries);
      r.on_frame = [series](const cv::Mat& frame, cv::Point shift) { (*series)->add(frame, shift); };
    }
    r.progress = std::move(progress);
    return read_capture(path, r, ref);
  };
  auto progress_of = [&](const std::string& stage) {
    return [&o, stage](int done, int total) {
      if (o.progress) o.progress(stage, done, total);
    };
  };
  auto add_times = [&a](const CaptureSums& sums) { a.read_ms += sums.read_ms, a.work_ms += sums.work_ms; };
  const bool split_mode = !captures.both.empty();
  if (split_mode) {
    // The not-worn phase's own geometry changes the view at the press (and back at the removal):
    // a registration reference per geometry (capture.hpp).
    if (own_geometry) ro.max_references = 4;
    ro.max_sums_mb = o.max_sums_mb;
    CaptureSums sums = read(captures.both, "capture", &p.worn_series, progress_of("reading the capture"));
    add_times(sums);
    const PhaseSplit split = split_phases(sums, o.window_frames);
    if (sums.sums_dropped) {  // a long capture: read again for its two windows only (bounded memory)
      ro.max_sums_mb = 0;
      ro.keep_windows = {split.baseline, split.worn};
      sums = read(captures.both, "capture", nullptr, progress_of("reading the capture again, for its windows"));
      add_times(sums);
    }
    p.base_avg = average_window(sums, split.baseline, o.window_frames, o.normalise_gains);
    p.worn_avg = average_window(sums, split.worn, o.window_frames, o.normalise_gains);
    if (own_geometry || o.phase_registration.enabled) place_worn_window(sums, p.base_avg, p.worn_avg, o.max_motion_px);
    a.baseline = phase_report(sums, p.base_avg, o.compensate_motion);
    a.worn = phase_report(sums, p.worn_avg, o.compensate_motion);
    a.split = split;
    p.worn_frame = sums.last_frame;
    if (!sums.shift_px.empty() && sums.shift_px.back().allFinite()) p.worn_frame_shift = sums.shift_px.back();
  } else {
    if (captures.baseline.empty() || captures.worn.empty())
      throw InputError("", "captures", "a phase is missing: give both 'baseline' (not worn) and 'worn', or 'both' for one video holding both",
                       "see the scene file format in README.md");
    // Each capture's window is its last frames: only those chunk sums are kept (bounded memory).
    ro.keep_last_frames = o.window_frames + 2 * o.chunk_frames;
    std::optional<CaptureSums> base_read, worn_read;
    if (own_geometry || o.phase_registration.enabled) {
      // The worn capture has a registration reference of its own: both are read at once (each read is a decoding
      // thread and the work on its frames, which alone leaves part of the machine idle), with one progress.
      std::mutex m;
      std::array<int, 2> done{0, 0}, total{0, 0};
      auto share = [&](int k) {
        return [&, k](int d, int t) {
          const std::lock_guard<std::mutex> lock(m);
          done[k] = d, total[k] = t;
          const bool known = total[0] > 0 && total[1] > 0;  // percentages once both captures' lengths are known
          if (o.progress) o.progress("reading the baseline and worn captures", done[0] + done[1], known ? total[0] + total[1] : 0);
        };
      };
      auto base_task = std::async(std::launch::async, [&] { return read(captures.baseline, "baseline", &p.base_series, share(0)); });
      std::exception_ptr worn_failed;
      try {
        worn_read = read(captures.worn, "worn", &p.worn_series, share(1));
      } catch (...) {
        worn_failed = std::current_exception();
      }
      base_read = base_task.get();  // the baseline's failure first, as when read one after the other
      if (worn_failed) std::rethrow_exception(worn_failed);
    } else {  // the worn capture is registered to the baseline's first frames
      base_read = read(captures.baseline, "baseline", &p.base_series, progress_of("reading the baseline capture"));
      worn_read = read(captures.worn, "worn", &p.worn_series, progress_of("reading the worn capture"));
    }
    const CaptureSums& base = *base_read;
    const CaptureSums& worn = *worn_read;
    add_times(base), add_times(worn);
    p.base_avg = average_window(base, last_frames(base, o.window_frames), o.window_frames, o.normalise_gains);
    a.baseline = phase_report(base, p.base_avg, o.compensate_motion);
    p.worn_avg = average_window(worn, last_frames(worn, o.window_frames), o.window_frames, o.normalise_gains);
    a.worn = phase_report(worn, p.worn_avg, o.compensate_motion);
    p.worn_frame = worn.last_frame;
    if (!worn.shift_px.empty() && worn.shift_px.back().allFinite()) p.worn_frame_shift = worn.shift_px.back();
  }
}

/// Stage 1b: each capture's exposure, before anything is estimated from the captures (the baseline's
/// gap, the registration, the glare), so that a black or saturated capture is refused as such and under
/// its own file. The glare mask is not known yet: saturation is allowed up to the most glare that
/// check_glare lets through (GlareOptions::max_fraction of the seen skin, which bounds its share of the roi),
/// so this refuses only what check_captures would refuse too; check_captures repeats the check with the
/// glare actually found.
void refuse_unusable_exposure(const Phases& p, const Assessment& a, const AssessmentOptions& o) {
  check_exposure(p.base_avg, a.baseline.source, "baseline", o, o.glare.max_fraction);
  check_exposure(p.worn_avg, a.worn.source, "worn", o, o.glare.max_fraction);
}

/// Stage 2a: where the camera stood at each capture's first frame against the pose, from the contact
/// surface's outline in each average (outline.hpp); the worn capture is then read where its outline says
/// the part is. Each average's content at frame-0 pixel x lies at x + residual_shift_px, so the outline's
/// shift less residual_shift_px is where that first frame stood against the map. The worn capture is placed
/// by its own outline, not by its difference to the baseline's: a held baseline's outline on the simulator
/// lies 0.2-0.65 px off its map's (rays beside the contact face's edge that miss the offset skin), and the
/// baseline's own offset is the phase registration's to follow. `baseline_map`: the not-worn capture's own
/// map (held or absent), reported only.
void measure_phase_move(const AssessmentScene& scene, const RefractionMap& baseline_map, Phases& p, const AssessmentOptions& o,
                        Assessment& a) {
  PhaseMoveReport& r = a.phase_move;
  if (!o.outline.enabled) return;
  const OutlineFit w = locate_outline(p.worn_avg.mean, seen_shares(*scene.forward, p.worn_avg.roi), {}, o.outline);
  const OutlineFit b = locate_outline(p.base_avg.mean, seen_shares(baseline_map, p.base_avg.roi), {}, o.outline);
  r.contrast = w.contrast;
  if (b.found) r.baseline_px = b.shift_px - p.base_avg.residual_shift_px;
  if (!w.found) {
    r.problem = "worn capture: " + w.problem;
    // An outline that is there but placed unsurely is worth saying; a capture without one (the skin beside the
    // part as bright as through it) is not.
    if (w.contrast >= o.outline.min_contrast)
      a.warnings.push_back("the worn capture was not placed by the contact surface's outline: " + w.problem +
                           "; a move of the camera since the not-worn capture is followed as if the skin had slid");
    return;
  }
  r.measured = true;
  r.worn_px = w.shift_px - p.worn_avg.residual_shift_px;
  r.move_px = r.worn_px;
  r.sigma_px = w.sigma_px;
  p.worn_avg.residual_shift_px += r.move_px;
  r.applied = true;
}

/// How the baseline is read on the chart: its own geometry's map and inverse map (held off the
/// skin, or no part), and the inverse map displaced by the phase registration.
struct BaselineView {
  std::optional<RefractionMap> map;
  std::optional<InverseMap> inverse;
  std::optional<InverseMap> moved_inverse;
  /// The baseline's inverse map from here on (nullptr: the worn one serves both).
  const InverseMap* view() const { return moved_inverse ? &*moved_inverse : inverse ? &*inverse : nullptr; }
};

/// Stage 2: the baseline's own geometry (its map at the given or estimated gap) and the phase
/// registration; fills a.baseline_geometry, a.phase_registration and their warnings.
void register_baseline(const AssessmentScene& scene, bool own_geometry, Phases& p, const AssessmentOptions& o, Assessment& a,
                       BaselineView& b) {
  const InverseMap& inv = *scene.inverse;
  if (own_geometry) {
    b.map = baseline_geometry(scene, p.base_avg, p.worn_avg, a, o);
    b.inverse = compute_inverse_map(*b.map, scene.inverse_options, scene.contact);
  }
  measure_phase_move(scene, b.map ? *b.map : *scene.forward, p, o, a);
  // Skin that slid or bulged between the phases: the baseline is read where its skin went
  // (phase_registration.hpp), from whichever inverse map reads it (its own geometry's or the worn one).
  const InverseMap& from = b.inverse ? *b.inverse : inv;
  if (o.phase_registration.enabled) {
    if (o.progress) o.progress("registering the phases", 0, 0);
    a.phase_registration = register_phases(p.base_avg, p.worn_avg, from, inv, {}, o.phase_registration);
    for (const auto& w : a.phase_registration.warnings) a.warnings.push_back(w);
    // A field under half a texel almost everywhere is noise on still skin: the baseline is left where it is.
    // An unsure field (its warnings say why, with figures) is not applied either: on lossy video the flow
    // follows the codec's blocks (a still H.264 capture gave 0.11 mm median, 3.3 mm max).
    const PhaseRegistration& r = a.phase_registration;
    if (r.applied && r.p95_mm > 0.5 * inv.texel_mm) {
      if (r.warnings.empty())
        b.moved_inverse = displaced_inverse(from, r);
      else
        a.warnings.push_back("the phases' registration was not applied because it is unsure (above); the baseline is read where it was "
                             "filmed: give --no-phase-registration to silence this, or film the phases without the skin moving");
    }
  }
}

/// Stage 3: the glare mask, then the exposure (refused when it cannot be assessed), the gains, the
/// motion and the saturation of each phase; fills a.glare and the warnings.
void check_captures(const AssessmentScene& scene, const Phases& p, const BaselineView& b, const AssessmentOptions& o, Assessment& a) {
  const RefractionMap& map = *scene.forward;
  // Glare first: a mostly-glare capture is refused as such, and saturated glare is not overexposure.
  // The phases are compared where they see the same skin.
  // With its own geometry the baseline is read where it sees the same skin, through its own
  // transmittance and share of the fall-off (estimated here); only the skin both phases see is compared.
  GlareFound found = find_glare(map, p.base_avg, p.worn_avg, b.map ? &*b.map : nullptr, b.view(), o);
  a.glare = std::move(found.glare);
  if (b.view()) {
    if (b.map) warn_vignetting(found.vignetting, a.warnings);
    a.baseline_geometry.vignetting = std::move(found.vignetting);
  }
  check_glare(a.glare, a.baseline, a.worn, o.glare, a.warnings);
  const double glare_of_roi = a.glare.empty() ? 0.0 : cv::countNonZero(a.glare.mask) / static_cast<double>(a.glare.mask.total());
  check_exposure(p.base_avg, a.baseline.source, "baseline", o, glare_of_roi);
  check_exposure(p.worn_avg, a.worn.source, "worn", o, glare_of_roi);
  warn_gains(a.baseline, "baseline", a.warnings);
  warn_gains(a.worn, "worn", a.warnings);
  for (const auto* r : {&a.baseline, &a.worn}) {
    const std::string role = r == &a.baseline ? "baseline" : "worn";
    if (r->motion_px_max > 0.5)
      a.warnings.push_back("motion during the " + role + " capture: up to " + fmt(r->motion_px_max) + " px, compensated" +
                           (r->jitter_px_rms > 0.2 ? " (jitter of " + fmt(r->jitter_px_rms, 2) + " px rms left as blur)" : ""));
    if (r->rotation_scale_px_max > 0.5)
      a.warnings.push_back("the image turned or scaled during the " + role + " capture (up to " + fmt(r->rotation_deg_max, 2) +
                           "°): frames are aligned at the centre of the view, so up to " + fmt(r->rotation_scale_px_max, 2) +
                           " px of it is left as blur at its edges");
    if (r->saturated_fraction > 0.001)
      a.warnings.push_back(fmt(100 * r->saturated_fraction, 2) + " % of the pixels that see the skin are saturated in the " + role +
                           " capture: their blanching is underestimated");
  }
}

/// Lossy captures (AssessmentOptions::lossy_outline_px): sets `out[k]` for the texels that `inv` reads (moved by
/// `shift`) within `px` camera pixels of a pixel `map` does not see or, with `glare` (in the same pixels), within
/// `px` / 2 of a masked one (a highlight's edge is an edge in the image too, but a softer one).
void mark_near_outline(const RefractionMap& map, const InverseMap& inv, const Vec2& shift, double px, const GlareMask* glare,
                       std::vector<std::uint8_t>& out) {
  cv::Mat seen = seen_pixels(map, cv::Rect(0, 0, map.width, map.height)), dist;
  cv::Mat glare_dist;
  if (glare && !glare->empty()) {
    cv::Mat clear(seen.size(), CV_8U, cv::Scalar(255));
    const cv::Rect r = glare->roi & cv::Rect(0, 0, seen.cols, seen.rows);
    clear(r).setTo(0, glare->mask(r - glare->roi.tl()));
    cv::distanceTransform(clear, glare_dist, cv::DIST_L2, cv::DIST_MASK_PRECISE);
  }
  cv::copyMakeBorder(seen, seen, 1, 1, 1, 1, cv::BORDER_CONSTANT, cv::Scalar(0));  // the image's edge is an outline too
  cv::distanceTransform(seen, dist, cv::DIST_L2, cv::DIST_MASK_PRECISE);
  for (int j = 0; j < inv.height; ++j)
    for (int i = 0; i < inv.width; ++i) {
      const auto k = inv.index(i, j);
      if (!inv.valid[k]) continue;
      const int x = static_cast<int>(std::lround(inv.map_x[k] + shift.x())) + 1, y = static_cast<int>(std::lround(inv.map_y[k] + shift.y())) + 1;
      if (x < 0 || y < 0 || x >= dist.cols || y >= dist.rows || dist.at<float>(y, x) <= px) out[k] = 1;
      else if (!glare_dist.empty() && glare_dist.at<float>(y - 1, x - 1) <= 0.5 * px) out[k] = 1;
    }
}

/// The gap's σ in the signal, per texel: the signal again with the baseline read at its gap ± σ (its own map,
/// inverse and the phases' registration as applied), the larger change of the two. A gap estimated wrong by σ
/// moves where the baseline is read by σ times the parallax, which is largest where the part is seen obliquely:
/// on the wristband at a quarter of its resolution the band's ends read 0.1-0.5 signal per mm of gap, the middle
/// about 0.01, and a gap 0.03 mm off (1.2 σ) left a bias of 8 noise σ there (a false place) and none mid-band.
/// NaN where either reading does not see the texel (unsee_off_gap); empty when the gap was given or is not used.
ChartField gap_signal_sigma(const AssessmentScene& scene, const Phases& p, const BaselineView& b, const BlanchingOptions& bo, const Assessment& a) {
  const BaselineGeometryReport& r = a.baseline_geometry;
  if (!r.gap_estimated || !(r.gap_sigma_mm > 0) || !scene.baseline_rays) return {};
  const InverseMap& inv = *scene.inverse;
  const ChartGrid& g = a.signal.y.grid;
  ChartField out{g, std::vector<float>(g.size(), kNaN)};
  std::vector<std::uint8_t> lost(g.size(), 0);
  for (const double side : {-1.0, 1.0}) {
    const double gap = r.gap_mm + side * r.gap_sigma_mm;
    if (gap < 0) continue;
    const RefractionMap map = scene.baseline_rays->map(gap);
    InverseMap view = compute_inverse_map(map, scene.inverse_options, scene.contact);
    if (b.moved_inverse) view = displaced_inverse(view, a.phase_registration);
    BlanchingOptions o = bo;
    o.log_transmittance_ratio = log_phase_ratio(*scene.forward, inv, map, view, r.vignetting.v);
    BlanchingSignal moved;
    try {
      moved = compute_blanching(nan_where_unseen(p.base_avg, map), nan_where_unseen(p.worn_avg, *scene.forward), inv, o, &view);
    } catch (const InputError&) {
      continue;  // nothing seen at this gap: the other side (or none) gives the term
    }
    if (moved.y.value.size() != g.size()) continue;
    for (std::size_t k = 0; k < g.size(); ++k) {
      const float d = std::abs(moved.y.value[k] - a.signal.y.value[k]);
      if (std::isfinite(d)) out.value[k] = std::isfinite(out.value[k]) ? std::max(out.value[k], d) : d;
      else if (std::isfinite(a.signal.y.value[k])) lost[k] = 1;
    }
  }
  for (std::size_t k = 0; k < g.size(); ++k)
    if (lost[k]) out.value[k] = kNaN;
  return out;
}

/// A texel the baseline sees at its gap but not at gap + σ or gap − σ is read at the edge of its seen skin, where a
/// gap within its σ moves the edge across it: it is unseen. On the wristband sample at a quarter of its resolution
/// (seed 7, gap 0.958 ± 0.037 mm for 1.0) texels at the band's ends read a signal of 0.05-0.1 (30-60 noise σ) there,
/// false saturated places of 7.2 mm² (without the gap's σ) or 0.15 mm² (with the texels seen at neither side unseen,
/// 0.95 mm²); with either side, 4.5 mm² of 805 are unseen and no place is false. Returns the texels unseen.
long long unsee_off_gap(const ChartField& gap_sigma, BlanchingSignal& s) {
  long long n = 0;
  for (std::size_t k = 0; k < gap_sigma.value.size() && k < s.y.value.size(); ++k) {
    if (std::isfinite(gap_sigma.value[k]) || !std::isfinite(s.y.value[k])) continue;
    for (ChartField* f : {&s.y, &s.sigma_y, &s.plain_difference, &s.worn_green, &s.baseline_green})
      if (k < f->value.size()) f->value[k] = kNaN;
    ++n;
  }
  s.texels_seen -= n;
  return n;
}

/// Stage 4: the blanching signal on the chart (glare texels excluded), the chart's raster and the
/// signal's σ with the pose's (`calibrated`: the σ of the sharpened signal the pressure is read from, its noise
/// times the deblur's gain); returns the options the signal was computed with (the later stages read its
/// spatial noise and transmittance ratio).
BlanchingOptions chart_signal(const AssessmentScene& scene, bool own_geometry, bool calibrated, const Phases& p, const BaselineView& b,
                              const AssessmentOptions& o, Assessment& a) {
  const InverseMap& inv = *scene.inverse;
  a.glare_texels = glare_texels(a.glare, inv, p.worn_avg.residual_shift_px);
  BlanchingOptions bo = o.blanching;
  if (!a.glare.empty()) bo.excluded = a.glare_texels;
  bo.spatial_noise = a.baseline.lossy || a.worn.lossy;
  if (bo.spatial_noise && o.lossy_outline_px > 0) {
    if (bo.excluded.empty()) bo.excluded.assign(static_cast<std::size_t>(inv.width) * inv.height, 0);
    mark_near_outline(*scene.forward, inv, p.worn_avg.residual_shift_px, o.lossy_outline_px, &a.glare, bo.excluded);
    if (b.view()) mark_near_outline(b.map ? *b.map : *scene.forward, *b.view(), p.base_avg.residual_shift_px, o.lossy_outline_px, nullptr, bo.excluded);
  }
  if (own_geometry) {
    // The phases see a texel at different pixels: their transmittances and fall-off differ, and a
    // texel whose taps reach past either phase's skin is unseen rather than a mixture.
    bo.log_transmittance_ratio = log_phase_ratio(*scene.forward, inv, *b.map, *b.view(), a.baseline_geometry.vignetting.v);
    bo.ratio_of_smoothed = true;
    bo.local_spatial_noise = true;
    a.signal = compute_blanching(nan_where_unseen(p.base_avg, *b.map), nan_where_unseen(p.worn_avg, *scene.forward), inv, bo, b.view());
    if (o.gap.sigma_in_signal) {
      if (o.progress) o.progress("the gap's sigma in the signal", 0, 0);
      a.gap_signal_sigma = gap_signal_sigma(scene, p, b, bo, a);
      if (!a.gap_signal_sigma.value.empty()) a.baseline_geometry.unseen_off_gap_mm2 = unsee_off_gap(a.gap_signal_sigma, a.signal) * std::pow(inv.texel_mm, 2);
      std::vector<float> v;
      for (float s : a.gap_signal_sigma.value)
        if (std::isfinite(s)) v.push_back(s);
      if (!v.empty()) {
        std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
        a.baseline_geometry.signal_sigma_median = v[v.size() / 2];
        a.baseline_geometry.signal_sigma_max = *std::max_element(v.begin(), v.end());
      }
    }
  } else {
    a.signal = compute_blanching(p.base_avg, p.worn_avg, inv, bo, b.view());
  }
  if (bo.spatial_noise) warn_lossy(a);
  for (const auto& w : a.signal.warnings) a.warnings.push_back(w);
  a.raster = rasterize_chart(*scene.mesh, *scene.chart, a.signal.y.grid);
  if (scene.pose_covariance) a.position_sigma_mm = position_sigma(a.raster, scene.cam_from_part, *scene.pose_covariance);
  IntrinsicsTerm intrinsics;
  if (scene.projection_uncertainty && scene.camera && inv.width == a.signal.y.grid.width && inv.height == a.signal.y.grid.height) {
    intrinsics = intrinsics_term(inv, a.signal.y, *scene.projection_uncertainty, scene.camera->width, scene.camera->height);
    a.projection_on_contact = projection_sigma_on_contact(intrinsics, a.signal.y, inv, o.max_projection_sigma_px);
    warn_projection_sigma(a.projection_on_contact, a.warnings);
  } else {
    a.warnings.push_back("the camera model carries no projection uncertainty (write it with `clearfit calibrate`): the pressure's "
                         "sigma has no term for the intrinsics (0 used)");
  }
  a.intrinsics_sigma_mm = intrinsics.position_mm;
  a.blur_effect = blur_effect(a.signal, bo);
  const double noise_gain = calibrated ? deblur_noise_gain(bo, a.signal.y.grid.texel_mm) : 1.0;
  a.signal_sigma = signal_sigma(a.signal, a.position_sigma_mm, intrinsics.signal, a.blur_effect, noise_gain);
  for (std::size_t k = 0; k < a.gap_signal_sigma.value.size() && k < a.signal_sigma.value.size(); ++k)
    if (std::isfinite(a.gap_signal_sigma.value[k])) a.signal_sigma.value[k] = std::hypot(a.signal_sigma.value[k], a.gap_signal_sigma.value[k]);
  return bo;
}

/// Stage 5: the pressure (with a calibration) and the hotspots above the thresholds, in kPa or in
/// the signal's own significance without one; fills a.thresholds, a.hotspots and their labels.
void pressure_and_hotspots(const AssessmentScene& scene, const std::optional<PressureCalibration>& calibration, bool spatial_noise,
                           const AssessmentOptions& o, Assessment& a) {
  const ChartGrid& g = a.signal.y.grid;
  HotspotOptions ho;
  ho.min_area_mm2 = o.min_hotspot_area_mm2;
  const double sigma_mm = std::max(o.blanching.smoothing_mm, 0.5 * g.texel_mm);
  ho.samples_per_mm2 = 1.0 / (4 * M_PI * sigma_mm * sigma_mm);
  if (calibration) {
    const std::vector<std::uint8_t> saturated = calibrated_pressure(*calibration, spatial_noise, o, a);
    const ChartField& search = a.pressure;
    a.thresholds = o.thresholds_kpa;
    warn_thresholds_below_detection(a.thresholds, a.detection_limit, a.warnings);
    ho.thresholds = a.thresholds;
    ho.shared_sigma = &a.pressure_sigma_parts.shared;
    ho.model_sigma = &a.pressure_sigma_parts.blur;
    ho.residual = &a.pressure_sigma_parts.residual;
    ho.outline_level = a.detection_limit.tail_kpa;  // a detected place is read down to its tail only
    a.hotspots = find_hotspots(search, &a.pressure_sigma, &saturated, a.raster, ho, &a.hotspot_labels, scene.mesh);
  } else {
    a.thresholds = o.signal_thresholds;
    // The significance threshold is for a texel of the capture's typical noise (the median σ_y); a place must hold a
    // texel significant by its own σ_y (local_gate), as a calibration's detection asks: beside a glare mask and at
    // the band's oblique end σ_y is up to twice the median, and 16 false places of 5.1-7.2 median σ came from there
    // on 32 quarter-scale wristband captures (27 with glare). A threshold given as a signal is taken as given.
    std::vector<std::uint8_t> seeds;
    if (a.thresholds.empty()) {
      a.thresholds = {o.signal_threshold_sigmas * std::max(a.signal.noise_sigma, 1e-6)};
      seeds.assign(g.size(), 0);
      for (std::size_t k = 0; k < g.size(); ++k)
        seeds[k] = a.signal.y.value[k] >= local_gate(a.thresholds.front(), detection_sigma(a, k), a.signal.noise_sigma);
      ho.seeds = &seeds;
    }
    ho.thresholds = a.thresholds;
    // The blur's first-order term and the gap's are the part of the signal's σ shared by a whole place (as with a
    // calibration).
    ChartField blur_size = a.blur_effect;
    for (std::size_t k = 0; k < blur_size.value.size(); ++k) {
      const float gap = k < a.gap_signal_sigma.value.size() && std::isfinite(a.gap_signal_sigma.value[k]) ? a.gap_signal_sigma.value[k] : 0.f;
      blur_size.value[k] = std::hypot(blur_size.value[k], gap);
    }
    if (blur_size.value.size() == g.size()) ho.shared_sigma = &blur_size;
    a.hotspots = find_hotspots(a.signal.y, &a.signal_sigma, nullptr, a.raster, ho, &a.hotspot_labels, scene.mesh);
    a.warnings.push_back("no pressure calibration: the report shows the blanching signal and where it is significant, not kPa");
  }
  add_position_to_centres(a.hotspots, a.hotspot_labels, position_sigma_total(a.position_sigma_mm, a.intrinsics_sigma_mm));
  flag_hotspots_at_mask(a.hotspots, a.hotspot_labels, a.glare_texels, g);
  for (const Hotspot& h : a.hotspots)
    if (h.touches_mask)
      a.warnings.push_back("hotspot " + std::to_string(h.id) + " touches the glare mask: it may extend under it, and its peak, area and "
                           "centroid may be larger or elsewhere than shown");
}

/// Stage 6: the timeline of the worn phase (timeseries.hpp), read through the same maps as the
/// averages; fills a.time and its warnings. Only with a recorded series.
void timeline(const AssessmentScene& scene, const std::optional<PressureCalibration>& calibration, bool own_geometry, const Phases& p,
              const BaselineView& b, const BlanchingOptions& bo, const AssessmentOptions& o, Assessment& a) {
  if (!p.worn_series) return;
  if (o.progress) o.progress("time series", 0, 0);
  TimeInputs ti;
  ti.series = &*p.worn_series;
  ti.baseline = p.base_series ? &*p.base_series : nullptr;
  ti.baseline_window = p.base_avg.window;
  ti.fps = a.worn.fps;
  if (a.split) ti.press_frame = a.split->press_frame, ti.release_frame = a.split->release_frame;
  ti.residual_shift_px = p.worn_avg.residual_shift_px;
  ti.inverse = scene.inverse;
  if (b.view()) {
    ti.baseline_inverse = b.view();
    ti.baseline_residual_shift_px = p.base_avg.residual_shift_px;
    if (own_geometry) ti.log_transmittance_ratio = &bo.log_transmittance_ratio;
  }
  ti.field = a.calibrated ? &a.pressure : &a.signal.y;
  ti.labels = &a.hotspot_labels;
  ti.hotspots = &a.hotspots;
  ti.thresholds = a.thresholds;
  std::sort(ti.thresholds.begin(), ti.thresholds.end());
  ti.calibration = calibration ? &*calibration : nullptr;
  a.time = analyse_time(ti, o.timeseries);
  for (const auto& w : a.time.warnings) a.warnings.push_back(w);
}

/// Coverage of the contact surface (seen, under glare, hidden behind the part or outside the view)
/// and the values at the mesh's vertices; fills a.coverage, a.vertex_* and the coverage warning.
void coverage_and_vertices(const AssessmentScene& scene, double smoothing_mm, Assessment& a) {
  const RefractionMap& map = *scene.forward;
  const ChartGrid& g = a.signal.y.grid;
  Coverage& c = a.coverage;
  long long by_status[kPixelStatusCount] = {};
  for (int k = 0; k < kPixelStatusCount; ++k) by_status[k] = map.stats.by_status[k];
  int dominant = -1;
  for (int k : {static_cast<int>(PixelStatus::contact_tir), static_cast<int>(PixelStatus::exits_elsewhere),
                static_cast<int>(PixelStatus::entry_tir), static_cast<int>(PixelStatus::contact_first)})
    if (by_status[k] > 0 && (dominant < 0 || by_status[k] > by_status[dominant])) dominant = k;
  c.blocked_reason = dominant < 0 ? "other" : to_string(static_cast<PixelStatus>(dominant));
  for (std::size_t k = 0; k < g.size(); ++k) {
    if (a.raster.face[k] < 0) continue;
    const double area = a.raster.area_mm2[k];
    c.contact_area_mm2 += area;
    if (std::isfinite(a.signal.y.value[k])) {
      c.seen_area_mm2 += area;
      continue;
    }
    if (!a.glare_texels.empty() && a.glare_texels[k]) {
      c.glare_masked_mm2 += area;
      continue;
    }
    const Vec3 in_cam = scene.cam_from_part.apply(a.raster.point[k]);
    const Vec2 px = in_cam.z() > 0 ? scene.camera->project(in_cam) : Vec2::Constant(-1e9);
    const bool inside = px.allFinite() && px.x() >= -0.5 && px.y() >= -0.5 && px.x() <= scene.camera->width - 0.5 &&
                        px.y() <= scene.camera->height - 0.5;
    (inside ? c.hidden_blocked_mm2 : c.hidden_outside_view_mm2) += area;
  }
  // Values at the vertices the camera sees in the worn capture (seen skin within two of its pixels,
  // measured where it lies), reaching as far again as the signal's smoothing for their value.
  const std::vector<float> reach = vertex_reach_texels(*scene.inverse, a.glare_texels, *scene.chart, 2);
  const double extra_mm = smoothing_mm;
  if (a.calibrated) {
    a.vertex_pressure = vertex_values(a.pressure, *scene.chart, reach, extra_mm);
    a.vertex_pressure_sigma = vertex_values(a.pressure_sigma, *scene.chart, reach, extra_mm);
    for (std::size_t v = 0; v < a.vertex_pressure_sigma.size(); ++v)  // no σ for a bound (below detection) or no value
      if (!(a.vertex_pressure[v] > 0)) a.vertex_pressure_sigma[v] = kNaN;
  }
  a.vertex_signal = vertex_values(a.signal.y, *scene.chart, reach, extra_mm);
  if (c.contact_area_mm2 > 0 && c.seen_area_mm2 < 0.5 * c.contact_area_mm2)
    a.warnings.push_back("the camera sees only " + fmt(100 * c.seen_area_mm2 / c.contact_area_mm2) +
                         " % of the contact surface through the part; the rest is not assessed");
}

/// Pictures: the worn capture as seen (the glare mask outlined), and resampled onto the chart.
void pictures(const AssessmentScene& scene, const Phases& p, Assessment& a) {
  a.skin_camera = p.worn_frame;
  if (a.glare.regions > 0) {  // the glare mask outlined (magenta) where it lies in this frame
    a.skin_camera = p.worn_frame.clone();
    std::vector<std::vector<cv::Point>> outlines;
    cv::findContours(a.glare.mask, outlines, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_SIMPLE);
    const cv::Point offset = a.glare.roi.tl() + cv::Point(static_cast<int>(std::lround(p.worn_frame_shift.x())),
                                                          static_cast<int>(std::lround(p.worn_frame_shift.y())));
    cv::drawContours(a.skin_camera, outlines, -1, cv::Scalar(255, 0, 255), std::max(1, p.worn_frame.cols / 640), cv::LINE_AA,
                     cv::noArray(), INT_MAX, offset);
  }
  a.skin_chart = chart_picture(p.worn_frame, *scene.inverse, p.worn_avg.residual_shift_px);
}
}  // namespace

Assessment assess_captures(const AssessmentScene& scene, const CaptureSources& captures,
                           const std::optional<PressureCalibration>& calibration, const AssessmentOptions& o) {
  if (!scene.mesh || !scene.contact || !scene.chart || !scene.camera || !scene.forward || !scene.inverse)
    throw std::invalid_argument("assess_captures: the scene is incomplete");
  if (o.window_frames < 1) throw InputError("", "captures.window_frames", "must be at least 1");
  const auto t0 = Clock::now();
  Assessment a;
  const bool own_geometry = scene.baseline_part != BaselinePart::touching;
  if (own_geometry && !scene.baseline_rays) throw std::invalid_argument("assess_captures: a held or absent baseline needs its rays");

  Phases p;  // read in place: the time series' frame callbacks point into it
  read_phases(scene, captures, own_geometry, o, a, p);
  refuse_unusable_exposure(p, a, o);
  BaselineView b;
  register_baseline(scene, own_geometry, p, o, a, b);
  check_captures(scene, p, b, o, a);
  if (o.progress) o.progress("blanching signal", 0, 0);
  const BlanchingOptions bo = chart_signal(scene, own_geometry, calibration.has_value(), p, b, o, a);
  pressure_and_hotspots(scene, calibration, bo.spatial_noise || bo.local_spatial_noise, o, a);
  timeline(scene, calibration, own_geometry, p, b, bo, o, a);
  coverage_and_vertices(scene, bo.smoothing_mm, a);
  pictures(scene, p, a);
  a.total_ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  return a;
}

}  // namespace clearfit
