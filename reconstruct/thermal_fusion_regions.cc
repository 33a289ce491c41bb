#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>
#include <vector>

#include "reconstruct/thermal_fusion_impl.h"
#include "reconstruct/thermal_update.h"
#include "reconstruct/tsdf_volume_impl.h"

// ThermalFusion's regions: splatting a frame's rays onto voxels, the update rules, the
// compaction of the kept observations (thermal_fusion.h), and the mirror sources read from
// them (thermal_reflections.h).

namespace hw::reconstruct {

void ThermalFusion::Impl::CorrectFrame(std::vector<Ray>& fused, double frozen_s, ThermalFrameRecord& record) {
  const SceneCorrectionOptions& o = options.scene_correction;
  // The latest shutter event (ffc.txt, or a frozen frame: the closure). Its offset is measured
  // once, on the first frame fused within the window after it with enough pairs, against the
  // views taken before it (views after it, fused before the measurement, carry the new offset
  // uncorrected): once, because every measurement stands on views that earlier ones corrected,
  // so that a bias of one is carried on — measured in every frame, it accumulates.
  const double since_ffc = record.time_since_ffc_s;
  double event_s = std::isfinite(since_ffc) ? record.timestamp_s - since_ffc : -std::numeric_limits<double>::infinity();
  if (frozen_s <= record.timestamp_s) event_s = std::max(event_s, frozen_s);
  if (std::isfinite(event_s) && event_s != event_time_s) {
    event_time_s = event_s;
    event_frame = fused_frames;  // the views before this frame are the event's references
    event_measured = false;
  }
  // The window: c5 rejects the frames after an event for ffc_settle_s and weighs them down for
  // ffc_ramp_s; event_window_s more to find a frame with enough pairs.
  const double window_s = o.event_window_s + options.confidence.ffc_settle_s + options.confidence.ffc_ramp_s;
  const bool measure = o.frame_offset && std::isfinite(event_time_s) && !event_measured &&
                       record.timestamp_s - event_time_s <= window_s;
  // Residuals against the regions the earlier frames made references: enough views, and
  // views that agree (a temperature edge reads differently with every sub-pixel shift).
  std::vector<SceneResidual>& residuals = residual_scratch;
  std::vector<SceneResidual>& pairs = temporal_scratch;
  residuals.clear();
  pairs.clear();
  const float max_variance = static_cast<float>(o.max_reference_std_k * o.max_reference_std_k);
  const int width = rays.width();
  const int max_shift = o.max_pair_shift_px;
  uint64_t cached_key = ~uint64_t{0};
  int32_t cached_block = -1;
  // Between events with the pixel offsets off (frame only), nothing to look up: the held
  // offset is applied as it is.
  const size_t n_rays = measure || o.pixel_offset ? fused.size() : 0;
  for (size_t i = 0; i < n_rays; ++i) {
    const Ray& ray = fused[i];
    const Eigen::Vector3f g = ray.point_in_world / voxel_m;
    const int32_t r = FindRegion(FloorToInt(g.x() + 0.5f), FloorToInt(g.y() + 0.5f), FloorToInt(g.z() + 0.5f),
                                 cached_key, cached_block);
    if (r < 0) continue;
    const Region& region = regions[r];
    if (region.views < 2 || region.m2_surface > max_variance * static_cast<float>(region.views - 1)) continue;
    // Pairs: this ray and the region's latest view before the event, taken by (almost) the
    // same pixel, differ by the offset's jump plus the offset removed from that view, whatever
    // the optics do at that pixel (vignetting, narcissus, fixed pattern), which a comparison
    // with the region's mean over many pixels would carry into the offset.
    if (measure && region.latest_frame >= 0 && region.latest_frame < event_frame) {
      const int shift = std::max(std::abs(region.latest_pixel % width - ray.pixel % width),
                                 std::abs(region.latest_pixel / width - ray.pixel / width));
      if (shift <= max_shift) pairs.push_back(SceneResidual{ray.pixel, ray.apparent_c - region.latest_apparent_c, shift});
    }
    if (!o.pixel_offset || region.views < o.min_reference_views) continue;
    // In apparent kelvin: a reading δ higher moves the surface estimate by δ / ε (the band
    // radiance's slope at the two temperatures taken as equal: within 2 % for a surface
    // 10 K off room temperature).
    residuals.push_back(SceneResidual{ray.pixel, (ray.surface_c - region.mean_surface_c) * ray.emissivity});
  }
  const SceneCorrectionUpdate u = scene_correction.Update(pairs, residuals, measure);
  if (u.frame_estimated) event_measured = true;
  record.pair_rays = u.pair_rays;
  record.pair_shift_px = u.pair_shift_px;
  record.reference_rays = u.reference_rays;
  record.offset_estimated = u.frame_estimated;
  record.offset_correction_k = u.frame_offset_k;
  record.pixel_offset_rms_k = u.pixel_offset_rms_k;
  if (u.frame_offset_k == 0) return;
  const float offset = static_cast<float>(u.frame_offset_k);
  for (Ray& ray : fused) {
    ray.apparent_c -= offset;
    ray.surface_c -= offset / ray.emissivity;
  }
}

namespace {
// How far ahead the passes over a frame's splats and regions prefetch (elements).
constexpr size_t kPrefetchAhead = 8;
}  // namespace

void ThermalFusion::Impl::Splat(const std::vector<Ray>& fused, ThermalFrameRecord& record) {
  // Four passes, so that the hash lookups, the accumulation and the update rules run on
  // every thread while the result stays exactly that of one thread taking the splats in ray
  // order: (1) per ray chunk, each splat's voxel and its region if it exists (read-only
  // lookups); (2) one thread creates the missing regions in splat order (so region indices
  // do not depend on the thread count); (3) each thread sums, in splat order, the splats of
  // the regions it owns (runs of 64 region indices dealt round-robin, so that
  // two threads never write the same cache line); (4) each thread runs the update rules
  // on its own regions.
  const int num_threads = std::max(1, std::min(ResolveThreads(options.num_threads),
                                               static_cast<int>(fused.size() / 1024) + 1));
  constexpr int32_t kMissing = -1, kOutOfRange = -2;
  std::vector<std::vector<SplatRef>>& parts = splat_scratch;
  parts.resize(num_threads);
  const size_t n_rays = fused.size();
  internal::RunChunks(num_threads, [&](int chunk) {
    std::vector<SplatRef>& part = parts[chunk];
    part.clear();
    uint64_t cached_key = ~uint64_t{0};
    int32_t cached_block = -1;
    for (size_t r = chunk * n_rays / num_threads; r < (chunk + 1) * n_rays / num_threads; ++r) {
      const Ray& ray = fused[r];
      // A footprint wider than a voxel is covered by a grid of splats at most a voxel apart,
      // so that a far or grazing view leaves no voxel between its rays unobserved.
      const int nu = std::clamp(static_cast<int>(std::ceil(ray.footprint_u.norm() / voxel_m)), 1, kMaxFootprintSplats);
      const int nv = std::clamp(static_cast<int>(std::ceil(ray.footprint_v.norm() / voxel_m)), 1, kMaxFootprintSplats);
      const float share = 1.0f / static_cast<float>(nu * nv);
      // Points of one ray that land in the same voxel are one splat with their shares summed:
      // the grid is up to a voxel fine, so a footprint of 1–2 voxels puts 2–4 of its points in
      // one voxel (on a 2 s full-size scan, 4.4 points per ray for 2.4 voxels), and each splat
      // costs a lookup and a pass over the frame's sums.
      const size_t ray_begin = part.size();
      for (int a = 0; a < nu; ++a) {
        for (int b = 0; b < nv; ++b) {
          const Eigen::Vector3f point = ray.point_in_world +
                                        ((a + 0.5f) / static_cast<float>(nu) - 0.5f) * ray.footprint_u +
                                        ((b + 0.5f) / static_cast<float>(nv) - 0.5f) * ray.footprint_v;
          // The nearest voxel takes it (a trilinear splat would touch 8, twice the surface's
          // two layers of voxels, for no gain: Sample() interpolates between observed voxels).
          const Eigen::Vector3f g = point / voxel_m;
          const int i = FloorToInt(g.x() + 0.5f), j = FloorToInt(g.y() + 0.5f), k = FloorToInt(g.z() + 0.5f);
          auto same = std::find_if(part.begin() + ray_begin, part.end(),
                                   [&](const SplatRef& s) { return s.i == i && s.j == j && s.k == k; });
          if (same != part.end()) {
            same->share += share;
            continue;
          }
          int32_t region = kOutOfRange;
          if (internal::KeyInRange(i >> kBlockShift, j >> kBlockShift, k >> kBlockShift)) {
            region = FindRegion(i, j, k, cached_key, cached_block);
            if (region < 0) region = kMissing;
          }
          part.push_back(SplatRef{i, j, k, static_cast<int32_t>(r), region, share});
        }
      }
    }
  });
  {
    uint64_t cached_key = ~uint64_t{0};
    int32_t cached_block = -1;
    for (std::vector<SplatRef>& part : parts) {
      for (SplatRef& s : part) {
        // A region created by an earlier splat of this frame is found here, not re-created.
        if (s.region == kMissing) s.region = RegionOf(s.i, s.j, s.k, true, cached_key, cached_block);
      }
    }
  }
  const float max_weight = static_cast<float>(options.capped_mean_max_weight);
  std::vector<RecordChunk> chunk_records(num_threads);
  std::vector<int> chunk_touched(num_threads, 0), chunk_beyond_cap(num_threads, 0);
  internal::RunChunks(num_threads, [&](int chunk) {
    std::vector<int32_t> touched;
    for (const std::vector<SplatRef>& part : parts) {
      for (size_t n = 0; n < part.size(); ++n) {
        // The sums are scattered over the map's regions: fetch a few splats ahead (the loop
        // waits on memory, not on arithmetic).
        if (n + kPrefetchAhead < part.size() && part[n + kPrefetchAhead].region >= 0) {
          __builtin_prefetch(&frame_sums[part[n + kPrefetchAhead].region], 1);
        }
        const SplatRef& splat = part[n];
        if (splat.region < 0 || (splat.region >> 6) % num_threads != chunk) continue;
        const Ray& ray = fused[splat.ray];
        FrameSum& s = frame_sums[splat.region];
        if (s.weight == 0) touched.push_back(splat.region);
        const float wc = splat.share * ray.confidence;
        s.weight += splat.share;
        s.weight_confidence += wc;
        s.surface += wc * ray.surface_c;
        s.apparent += wc * ray.apparent_c;
        s.footprint += wc * ray.footprint_m;
        const Eigen::Vector3f view = camera_in_world - ray.point_in_world;
        s.view_x += wc * view.x();
        s.view_y += wc * view.y();
        s.view_z += wc * view.z();
        if (wc > s.best) {
          s.best = wc;
          s.pixel = ray.pixel;
        }
      }
    }
    RecordChunk& frame_records = chunk_records[chunk];
    if (options.keep_observations) frame_records.reserve(touched.size());
    int beyond_cap = 0;
    for (size_t n = 0; n < touched.size(); ++n) {
      if (n + kPrefetchAhead < touched.size()) {
        const char* region = reinterpret_cast<const char*>(&regions[touched[n + kPrefetchAhead]]);
        for (size_t line = 0; line < sizeof(Region); line += 64) __builtin_prefetch(region + line, 1);
        __builtin_prefetch(&frame_sums[touched[n + kPrefetchAhead]], 1);
      }
      beyond_cap += UpdateRegion(touched[n], max_weight, frame_records);
    }
    chunk_touched[chunk] = static_cast<int>(touched.size());
    chunk_beyond_cap[chunk] = beyond_cap;
  });
  for (int chunk = 0; chunk < num_threads; ++chunk) {
    record.regions_updated += chunk_touched[chunk];
    num_records += chunk_records[chunk].size();
    if (!chunk_records[chunk].empty()) records.push_back(std::move(chunk_records[chunk]));
    records_droppable += chunk_beyond_cap[chunk];
  }
  if (records_droppable >= std::max(kMinCompactDrop, num_records / 2)) Compact(nullptr);
  ++fused_frames;
}

void ThermalFusion::Impl::Compact(std::vector<uint32_t>* begin_out) {
  assert(num_records < std::numeric_limits<uint32_t>::max());
  const size_t n_regions = regions.size();
  // Each thread groups one range of regions: it reads every kept observation and counts,
  // then copies, those of its range, so that a region's stay in arrival order whatever the
  // thread count. (One thread took 0.4–0.5 s for the 10 M observations of a 4 s full-size
  // scan, most of it waiting on the scattered writes.)
  const int num_threads =
      std::max(1, std::min(ResolveThreads(options.num_threads), static_cast<int>(num_records >> 14) + 1));
  const auto range = [&](int t) {
    return std::pair<size_t, size_t>{n_regions * t / num_threads, n_regions * (t + 1) / num_threads};
  };
  std::vector<uint32_t> begin(n_regions + 1, 0);
  internal::RunChunks(num_threads, [&](int t) {
    const auto [lo, hi] = range(t);
    for (const RecordChunk& chunk : records) {
      for (const Record& r : chunk) {
        if (static_cast<size_t>(r.region) - lo < hi - lo) ++begin[r.region + 1];  // [lo + 1, hi]: this thread's
      }
    }
  });
  for (size_t i = 0; i < n_regions; ++i) begin[i + 1] += begin[i];
  RecordChunk grouped(num_records);  // uninitialised: every element is written below
  internal::RunChunks(num_threads, [&](int t) {
    const auto [lo, hi] = range(t);
    std::vector<uint32_t> next(begin.begin() + lo, begin.begin() + hi);
    for (const RecordChunk& chunk : records) {
      for (const Record& r : chunk) {
        if (static_cast<size_t>(r.region) - lo < hi - lo) grouped[next[r.region - lo]++] = r;
      }
    }
  });
  records.clear();
  // Without a droppable view (the count is exact) no region holds more than the cap.
  const size_t cap = static_cast<size_t>(options.max_views_per_region);
  if (cap > 0 && records_droppable > 0) {
    // In place: the write position never passes the read position (w <= b, and the k-th
    // survivor comes from b + order[k] >= b + k).
    size_t w = 0;
    std::vector<uint32_t> order;
    for (size_t i = 0; i < n_regions; ++i) {
      const size_t b = begin[i], e = begin[i + 1];
      begin[i] = static_cast<uint32_t>(w);
      if (e - b <= cap) {
        std::copy(grouped.begin() + b, grouped.begin() + e, grouped.begin() + w);
        w += e - b;
        continue;
      }
      order.resize(e - b);
      for (size_t k = 0; k < order.size(); ++k) order[k] = static_cast<uint32_t>(k);
      std::nth_element(order.begin(), order.begin() + cap, order.end(), [&](uint32_t x, uint32_t y) {
        const float cx = grouped[b + x].confidence, cy = grouped[b + y].confidence;
        return cx > cy || (cx == cy && x < y);
      });
      std::sort(order.begin(), order.begin() + cap);
      for (size_t k = 0; k < cap; ++k) grouped[w + k] = grouped[b + order[k]];
      w += cap;
      records_dropped += e - b - cap;
    }
    begin[n_regions] = static_cast<uint32_t>(w);
    grouped.resize(w);
    grouped.shrink_to_fit();
  }
  num_records = grouped.size();
  records_droppable = 0;
  if (!grouped.empty()) records.push_back(std::move(grouped));
  if (begin_out) *begin_out = std::move(begin);
}

bool ThermalFusion::Impl::UpdateRegion(int32_t r, float max_weight, RecordChunk& frame_records) {
  FrameSum& s = frame_sums[r];
  const float confidence = s.weight_confidence / s.weight;
  const float surface = s.surface / s.weight_confidence;
  const float apparent = s.apparent / s.weight_confidence;
  const float footprint = s.footprint / s.weight_confidence;
  const float view_x = s.view_x / s.weight_confidence, view_y = s.view_y / s.weight_confidence,
              view_z = s.view_z / s.weight_confidence;
  const int32_t pixel = s.pixel;
  s = FrameSum();
  Region& region = regions[r];
  region.latest_surface_c = surface;
  region.latest_apparent_c = apparent;
  region.latest_frame = fused_frames;
  region.latest_pixel = pixel;
  region.latest_confidence = confidence;
  if (region.views < std::numeric_limits<uint16_t>::max()) ++region.views;
  const float n = region.views;
  const float delta = surface - region.mean_surface_c;
  region.mean_surface_c += delta / n;
  region.m2_surface += delta * (surface - region.mean_surface_c);
  region.mean_apparent_c += (apparent - region.mean_apparent_c) / n;
  region.mean_confidence += (confidence - region.mean_confidence) / n;
  // Weighted by confidence: mean_confidence · views is the sum of the views' confidences.
  const float confidence_sum = region.mean_confidence * n;
  const float step = confidence_sum > 0 ? confidence / confidence_sum : 1.0f;
  region.footprint_m += (footprint - region.footprint_m) * step;
  region.view_x += (view_x - region.view_x) * step;
  region.view_y += (view_y - region.view_y) * step;
  region.view_z += (view_z - region.view_z) * step;
  double capped_value = region.capped_surface_c, capped_weight = region.capped_weight;
  CappedMeanUpdate(max_weight, surface, capped_value, capped_weight);
  double capped_apparent = region.capped_apparent_c, apparent_weight = region.capped_weight;
  CappedMeanUpdate(max_weight, apparent, capped_apparent, apparent_weight);
  region.capped_surface_c = static_cast<float>(capped_value);
  region.capped_apparent_c = static_cast<float>(capped_apparent);
  region.capped_weight = static_cast<float>(capped_weight);
  double value_a = region.online_surface_c, confidence_a = region.online_confidence;
  const double q = OnlineUpdate(options.recency_bias, surface, confidence, value_a, confidence_a);
  region.online_surface_c = static_cast<float>(value_a);
  region.online_confidence = static_cast<float>(confidence_a);
  region.online_apparent_c = static_cast<float>(
      q >= 1 ? static_cast<double>(apparent)
             : q * static_cast<double>(apparent) + (1 - q) * static_cast<double>(region.online_apparent_c));
  if (!options.keep_observations) return false;
  frame_records.push_back(Record{r, surface, apparent, confidence});
  return options.max_views_per_region > 0 && region.views > options.max_views_per_region;
}

double ThermalFusion::Impl::ReflectedC(const PointMap& map, const cv::Mat& apparent_c,
                                       const core::Rigid3d& world_from_thermal, size_t i,
                                       const PixelReflection& reflection, MirrorSource* source) const {
  const ThermalReflectionOptions& o = options.reflections;
  const SurfaceEmissivity& e = reflection.surface;
  const Eigen::Vector3f& point = map.points[i];
  const Eigen::Vector3f origin = world_from_thermal.translation.cast<float>();
  const Eigen::Vector3f mirror = MirrorDirection((point - origin).normalized(), map.normals[i]);
  const double room = band.Radiance(core::CelsiusToKelvin(e.reflected_c));
  double mirror_radiance = room;
  *source = MirrorSource::kRoom;
  const std::optional<double> body =
      IntersectOperatorBody(o, world_from_thermal, point.cast<double>(), mirror.cast<double>());
  if (body && *body < static_cast<double>(reflection.mirror_m)) {
    mirror_radiance = band.Radiance(core::CelsiusToKelvin(o.operator_apparent_c));
    *source = MirrorSource::kOperator;
  } else if (std::isfinite(reflection.mirror_m)) {
    const Eigen::Vector3f hit = point + reflection.mirror_m * mirror;
    // This frame's reading, where it sees the hit.
    const Eigen::Vector3d hit_in_camera = world_from_thermal.rotation.conjugate() * (hit - origin).cast<double>();
    if (hit_in_camera.z() > 1e-3) {
      const Eigen::Vector2d uv = rig.thermal->Project(hit_in_camera);
      if (rig.thermal->IsInImage(uv)) {
        const int u = static_cast<int>(std::lround(uv.x())), v = static_cast<int>(std::lround(uv.y()));
        const size_t j = map.Index(u, v);
        const float tolerance_m = std::max(3 * voxel_m, 0.01f * static_cast<float>(hit_in_camera.norm()));
        if (IsValid(map.points[j]) && (map.points[j] - hit).norm() <= tolerance_m) {
          double radiance = band.Radiance(core::CelsiusToKelvin(apparent_c.at<float>(v, u)));
          if (!vignetting_gain.empty()) radiance /= static_cast<double>(vignetting_gain[j]);
          mirror_radiance = radiance;
          *source = MirrorSource::kSurface;
        }
      }
    }
    // Else what the regions around it have seen so far.
    if (*source == MirrorSource::kRoom) {
      std::array<Eigen::Vector3i, 8> voxel;
      std::array<float, 8> weight;
      Corners(hit, voxel, weight);
      uint64_t cached_key = ~uint64_t{0};
      int32_t cached_block = -1;
      double radiance = 0, weight_sum = 0;
      for (int c = 0; c < 8; ++c) {
        const int32_t r = FindRegion(voxel[c].x(), voxel[c].y(), voxel[c].z(), cached_key, cached_block);
        if (r < 0 || regions[r].views == 0 || weight[c] <= 0) continue;
        const double w = weight[c];
        radiance += w * band.Radiance(core::CelsiusToKelvin(static_cast<double>(regions[r].mean_apparent_c)));
        weight_sum += w;
      }
      if (weight_sum > 0) {
        mirror_radiance = radiance / weight_sum;
        *source = MirrorSource::kSurface;
      }
    }
  }
  const double s = SpecularFraction(e);
  return core::KelvinToCelsius(band.Temperature((1 - s) * room + s * mirror_radiance));
}

}  // namespace hw::reconstruct
