// Speed of the analyzer's renderer (analyze/render.h) on a million-triangle mesh, side by
// side with Open3D 0.16's RaycastingScene::CastRays on the same mesh and the same rays.
//
//   build/bench/bench_render_speed [--scene equipment] [--max-edge 0.012] [--threads 2]
//                                  [--repeats 7] [--ply out.ply]
//
// The mesh: the fixture scene tessellated finely (Scene::Tessellate, max_edge_m). Views at
// 1280×960: "sweep" from the scene's suggested hand-held viewpoint (middle of the standoff
// range, looking at the target), and "overview-1" of analyze/view_select.h seen from
// outside with back faces culled. Times are wall-clock medians of --repeats renders; the
// CPU time per thread is printed too (the machine may be shared). The target: a
// 1280×960 view of a million-triangle mesh in < 50 ms on 2 cores.
//
// Open3D (when built with it) casts the pixel-centre rays of the spp-1 render, the same
// origins and directions, through its own Embree scene; the ratio is Open3D's time over
// ours. Its scene is committed inside the first CastRays: that call is timed as its build.

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <unordered_map>
#include <vector>

#include "analyze/render.h"
#include "analyze/thermal_mesh.h"
#include "analyze/view_select.h"
#include "bench/bench_timing.h"
#include "fixtures/scenes.h"

#ifdef HW_WITH_OPEN3D
#include <dlfcn.h>
#include <embree3/rtcore.h>
#include <open3d/core/Tensor.h>
#include <open3d/t/geometry/RaycastingScene.h>

// Debian's Open3D 0.16 links Debian's Embree 3.13, built with ray masks on
// (RTC_DEVICE_PROPERTY_RAY_MASK_SUPPORTED = 1), but casts its rays with mask 0 (it is made
// for its bundled Embree, built without masks), so every CastRays misses: t_hit = inf for
// a ray straight at a triangle. This definition interposes on the rtcIntersect1M that
// libOpen3D calls (the executable's symbol wins the dynamic lookup), sets every ray's mask
// to all ones and forwards to Embree's: one store per ray, negligible against traversal.
extern "C" void rtcIntersect1M(RTCScene scene, RTCIntersectContext* context, RTCRayHit* rayhit,
                               unsigned int count, size_t byte_stride) {
  using Function = void (*)(RTCScene, RTCIntersectContext*, RTCRayHit*, unsigned int, size_t);
  static const Function embree = reinterpret_cast<Function>(dlsym(RTLD_NEXT, "rtcIntersect1M"));
  for (unsigned int i = 0; i < count; ++i) {
    reinterpret_cast<RTCRayHit*>(reinterpret_cast<char*>(rayhit) + i * byte_stride)->ray.mask = 0xffffffffU;
  }
  embree(scene, context, rayhit, count, byte_stride);
}
#endif

namespace {

using hw::bench::Clock;
using hw::bench::CpuMs;
using hw::bench::Ms;

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

struct Timing {
  double wall_ms = 0;
  double cpu_per_thread_ms = 0;
};

Timing TimeRenders(const hw::analyze::MeshRenderer& renderer, const hw::analyze::Camera& camera,
                   const hw::analyze::RenderOptions& options, int repeats, hw::analyze::SampleBuffer* last) {
  std::vector<double> wall, cpu;
  for (int r = 0; r < repeats; ++r) {
    const double c0 = CpuMs();
    const auto t0 = Clock::now();
    renderer.Render(camera, options, last);
    wall.push_back(Ms(t0, Clock::now()));
    cpu.push_back((CpuMs() - c0) / options.num_threads);
  }
  return {Median(wall), Median(cpu)};
}

// Wall time of Render() returning a fresh SampleBuffer (allocation and page faults
// included), median.
double TimeFreshRenders(const hw::analyze::MeshRenderer& renderer, const hw::analyze::Camera& camera,
                        const hw::analyze::RenderOptions& options, int repeats) {
  std::vector<double> wall;
  for (int r = 0; r < repeats; ++r) {
    const auto t0 = Clock::now();
    const hw::analyze::SampleBuffer samples = renderer.Render(camera, options);
    wall.push_back(Ms(t0, Clock::now()));
  }
  return Median(wall);
}

}  // namespace

int main(int argc, char** argv) {
  std::string scene_name = "equipment";
  double max_edge_m = 0.012;
  int threads = 2;
  int repeats = 7;
  std::string ply_out;
  for (int i = 1; i < argc; ++i) {
    const bool has_value = i + 1 < argc;
    if (!std::strcmp(argv[i], "--scene") && has_value) scene_name = argv[++i];
    else if (!std::strcmp(argv[i], "--max-edge") && has_value) max_edge_m = std::atof(argv[++i]);
    else if (!std::strcmp(argv[i], "--threads") && has_value) threads = std::atoi(argv[++i]);
    else if (!std::strcmp(argv[i], "--repeats") && has_value) repeats = std::atoi(argv[++i]);
    else if (!std::strcmp(argv[i], "--ply") && has_value) ply_out = argv[++i];
    else {
      std::fprintf(stderr, "usage: %s [--scene NAME] [--max-edge M] [--threads N] [--repeats N] [--ply OUT]\n",
                   argv[0]);
      return 2;
    }
  }
  if (threads < 1 || repeats < 1 || !(max_edge_m > 0)) {
    std::fprintf(stderr, "--threads and --repeats must be >= 1, --max-edge > 0\n");
    return 2;
  }

  const auto t0 = Clock::now();
  const hw::fixtures::SceneSpec spec = hw::fixtures::MakeSceneSpec(scene_name);
  const hw::core::PlyMesh ply = spec.scene.Tessellate(max_edge_m);
  if (!ply_out.empty()) hw::core::WritePly(ply_out, ply);
  const hw::analyze::ThermalMesh mesh = hw::analyze::MakeThermalMesh(ply, scene_name);
  std::printf("mesh: scene %s, max edge %.4g m: %d vertices, %d triangles (tessellated in %.1f s)\n",
              scene_name.c_str(), max_edge_m, mesh.NumVertices(), mesh.NumFaces(), Ms(t0, Clock::now()) / 1e3);

  const hw::analyze::MeshRenderer renderer(mesh);
  std::printf("BVH build (Embree; medium quality above 1 M triangles): %.1f ms\n", renderer.build_seconds() * 1e3);

  hw::analyze::ViewSelectOptions view_options;
  const hw::fixtures::ViewRegion& region = spec.view;
  const Eigen::Vector3d eye =
      region.look_at_in_world + 0.5 * (region.standoff_min_m + region.standoff_max_m) * region.approach_direction;
  hw::analyze::Camera base;
  struct View {
    const char* name;
    hw::analyze::Camera camera;
    bool cull;
  };
  const std::vector<View> views = {
      {"sweep", hw::analyze::LookAt(eye, region.look_at_in_world, region.up_in_world, base), false},
      {"overview-1", hw::analyze::OverviewViews(mesh, view_options).front().camera, true}};

#ifdef HW_WITH_OPEN3D
  namespace o3c = open3d::core;
  std::vector<float> vertices;
  vertices.reserve(3 * mesh.points_in_world.size());
  for (const Eigen::Vector3d& p : mesh.points_in_world) {
    for (int k = 0; k < 3; ++k) vertices.push_back(static_cast<float>(p[k]));
  }
  std::vector<uint32_t> indices;
  indices.reserve(3 * mesh.faces.size());
  for (const Eigen::Vector3i& f : mesh.faces) {
    for (int k = 0; k < 3; ++k) indices.push_back(static_cast<uint32_t>(f[k]));
  }
  open3d::t::geometry::RaycastingScene open3d_scene(threads);
  open3d_scene.AddTriangles(
      o3c::Tensor(vertices, {static_cast<int64_t>(mesh.points_in_world.size()), 3}, o3c::Float32),
      o3c::Tensor(indices, {static_cast<int64_t>(mesh.faces.size()), 3}, o3c::UInt32));
  bool open3d_built = false;
#endif

  for (const View& view : views) {
    for (const int spp : {1, 4}) {
      hw::analyze::RenderOptions options;
      options.samples_per_pixel = spp;
      options.num_threads = threads;
      options.cull_back_faces = view.cull;
      hw::analyze::SampleBuffer samples;
      const Timing ours = TimeRenders(renderer, view.camera, options, repeats, &samples);
      const double fresh_ms = TimeFreshRenders(renderer, view.camera, options, repeats);
      size_t hits = 0;
      for (const int f : samples.face) hits += f >= 0;
      std::printf("%-10s spp %d%s: %8.1f ms/frame wall (median of %d), %8.1f ms CPU/thread, %.1f Mrays/s, "
                  "%.0f %% hit; with a fresh buffer %.1f ms\n",
                  view.name, spp, view.cull ? " culled" : "", ours.wall_ms, repeats, ours.cpu_per_thread_ms,
                  static_cast<double>(samples.NumSamples()) / ours.wall_ms * 1e-3,
                  100.0 * static_cast<double>(hits) / static_cast<double>(samples.NumSamples()), fresh_ms);
#ifdef HW_WITH_OPEN3D
      // Open3D has no back-face culling: compare on the unculled view only.
      if (view.cull) continue;
      // The same rays: the sample positions of this render.
      const hw::analyze::Camera& camera = view.camera;
      const Eigen::Matrix3d r = camera.world_from_camera.linear();
      const Eigen::Vector3d t = camera.world_from_camera.translation();
      const double f = camera.FocalPx();
      std::vector<float> rays;
      rays.reserve(samples.NumSamples() * 6);
      for (int y = 0; y < camera.height; ++y) {
        for (int x = 0; x < camera.width; ++x) {
          for (int s = 0; s < spp; ++s) {
            const Eigen::Vector2d o = hw::analyze::SampleOffset(x, y, s, spp);
            const Eigen::Vector3d d =
                r * Eigen::Vector3d((x + o.x() - 0.5 * camera.width) / f, (y + o.y() - 0.5 * camera.height) / f, 1);
            for (int k = 0; k < 3; ++k) rays.push_back(static_cast<float>(t[k]));
            for (int k = 0; k < 3; ++k) rays.push_back(static_cast<float>(d[k]));
          }
        }
      }
      const o3c::Tensor ray_tensor(rays, {static_cast<int64_t>(samples.NumSamples()), 6}, o3c::Float32);
      if (!open3d_built) {
        const auto b0 = Clock::now();
        open3d_scene.CastRays(ray_tensor, threads);
        std::printf("Open3D RaycastingScene: first CastRays (commits its Embree scene) %.1f ms\n",
                    Ms(b0, Clock::now()));
        open3d_built = true;
      }
      std::vector<double> wall, cpu;
      std::unordered_map<std::string, o3c::Tensor> result;
      for (int rep = 0; rep < repeats; ++rep) {
        const double c0 = CpuMs();
        const auto w0 = Clock::now();
        result = open3d_scene.CastRays(ray_tensor, threads);
        wall.push_back(Ms(w0, Clock::now()));
        cpu.push_back((CpuMs() - c0) / threads);
      }
      // Agreement: the same face for the same ray (float ties on edges may differ).
      const uint32_t* prim = result["primitive_ids"].GetDataPtr<uint32_t>();
      size_t same = 0;
      for (size_t i = 0; i < samples.NumSamples(); ++i) {
        const int theirs = prim[i] == open3d::t::geometry::RaycastingScene::INVALID_ID()
                               ? -1
                               : static_cast<int>(prim[i]);
        same += theirs == samples.face[i];
      }
      std::printf("%-10s spp %d Open3D CastRays: %8.1f ms/frame wall, %8.1f ms CPU/thread; "
                  "Open3D / ours = %.2f; same face on %.3f %% of rays\n",
                  view.name, spp, Median(wall), Median(cpu), Median(wall) / ours.wall_ms,
                  100.0 * static_cast<double>(same) / static_cast<double>(samples.NumSamples()));
#endif
    }
  }
  return 0;
}
