#include "analyze/render.h"

#include <embree3/rtcore.h>

#include <algorithm>
#include <atomic>
#include <cassert>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>

#include "core/option_check.h"

namespace hw::analyze {

using core::InRange;
using core::OptionFail;

double Camera::FocalPx() const {
  return 0.5 * static_cast<double>(height) / std::tan(0.5 * fov_y_deg * M_PI / 180.0);
}

Eigen::Vector2d Camera::Project(const Eigen::Vector3d& point_in_world, double* depth_m) const {
  const Eigen::Vector3d p = world_from_camera.inverse() * point_in_world;
  if (depth_m != nullptr) *depth_m = p.z();
  const Eigen::Vector2d centre(0.5 * width, 0.5 * height);
  if (orthographic) return centre + p.head<2>() * (static_cast<double>(height) / ortho_height_m);
  return centre + p.head<2>() * (FocalPx() / p.z());
}

void Camera::Ray(double x, double y, Eigen::Vector3d* origin_in_world,
                 Eigen::Vector3d* direction_in_world) const {
  const Eigen::Vector2d offset = Eigen::Vector2d(x, y) - Eigen::Vector2d(0.5 * width, 0.5 * height);
  const Eigen::Matrix3d r = world_from_camera.linear();
  if (orthographic) {
    const Eigen::Vector2d xy_m = offset * (ortho_height_m / static_cast<double>(height));
    *origin_in_world = world_from_camera * Eigen::Vector3d(xy_m.x(), xy_m.y(), 0);
    *direction_in_world = r.col(2);
  } else {
    *origin_in_world = world_from_camera.translation();
    *direction_in_world = (r * Eigen::Vector3d(offset.x() / FocalPx(), offset.y() / FocalPx(), 1)).normalized();
  }
}

std::string Camera::Check() const {
  if (!(fov_y_deg > 0 && fov_y_deg < 170)) return OptionFail("fov_y_deg", fov_y_deg, "in (0, 170)");
  if (!(ortho_height_m > 0 && std::isfinite(ortho_height_m))) {
    return OptionFail("ortho_height_m", ortho_height_m, "> 0 and finite");
  }
  if (width <= 0) return OptionFail("width", width, "> 0");
  if (height <= 0) return OptionFail("height", height, "> 0");
  const Eigen::Matrix3d r = world_from_camera.linear();
  const double error = (r.transpose() * r - Eigen::Matrix3d::Identity()).norm();
  if (!(error < 1e-6) || !(r.determinant() > 0)) {
    return OptionFail("world_from_camera", error, "a rotation (|RᵀR − I| < 1e-6, det > 0)");
  }
  if (!world_from_camera.translation().allFinite()) {
    return "world_from_camera: the translation must be finite";
  }
  return "";
}

Camera LookAt(const Eigen::Vector3d& eye_in_world, const Eigen::Vector3d& target_in_world,
              const Eigen::Vector3d& up_in_world, Camera camera) {
  assert((target_in_world - eye_in_world).norm() > 0 && up_in_world.norm() > 0);
  const Eigen::Vector3d z = (target_in_world - eye_in_world).normalized();
  Eigen::Vector3d up = up_in_world.normalized();
  // sin 1°: closer to parallel and the roll is numerically arbitrary.
  if (z.cross(up).norm() < 0.0175) {
    Eigen::Index axis = 0;
    z.cwiseAbs().minCoeff(&axis);
    up = Eigen::Vector3d::Unit(axis);
  }
  // OpenCV frame: x right, y down, z forward, right-handed: x = y × z.
  const Eigen::Vector3d y_down = (-up - (-up).dot(z) * z).normalized();
  const Eigen::Vector3d x_right = y_down.cross(z);
  Eigen::Matrix3d r;
  r.col(0) = x_right;
  r.col(1) = y_down;
  r.col(2) = z;
  camera.world_from_camera = Eigen::Isometry3d::Identity();
  camera.world_from_camera.linear() = r;
  camera.world_from_camera.translation() = eye_in_world;
  return camera;
}

std::string RenderOptions::Check() const {
  if (samples_per_pixel != 1 && samples_per_pixel != 4 && samples_per_pixel != 9 && samples_per_pixel != 16) {
    return OptionFail("samples_per_pixel", samples_per_pixel, "1, 4, 9 or 16");
  }
  if (num_threads < 0) return OptionFail("num_threads", num_threads, ">= 0");
  if (!InRange(tile_px, 4, 256)) return OptionFail("tile_px", tile_px, "in [4, 256]");
  return "";
}

namespace {

// A 32-bit integer hash (lowbias32, Chris Wellons): good avalanche for neighbouring
// pixels, so the jitter of adjacent pixels is uncorrelated.
uint32_t Hash32(uint32_t v) {
  v ^= v >> 16;
  v *= 0x7feb352dU;
  v ^= v >> 15;
  v *= 0x846ca68bU;
  v ^= v >> 16;
  return v;
}

// [0, 1) from the top 24 bits (exact in float and double).
double Unit(uint32_t v) { return static_cast<double>(v >> 8) * (1.0 / 16777216.0); }

int GridSide(int samples_per_pixel) {
  return samples_per_pixel == 16 ? 4 : samples_per_pixel == 9 ? 3 : samples_per_pixel == 4 ? 2 : 1;
}

}  // namespace

Eigen::Vector2d SampleOffset(int x, int y, int s, int samples_per_pixel) {
  if (samples_per_pixel == 1) return Eigen::Vector2d(0.5, 0.5);
  const int n = GridSide(samples_per_pixel);
  const uint32_t h = Hash32(static_cast<uint32_t>(x) * 0x9e3779b1U ^
                            Hash32(static_cast<uint32_t>(y) * 0x85ebca77U ^ static_cast<uint32_t>(s)));
  const double jx = Unit(h);
  const double jy = Unit(Hash32(h ^ 0x68e31da4U));
  return Eigen::Vector2d((s % n + jx) / n, (s / n + jy) / n);
}

double InterpolateOnFace(const ThermalMesh& mesh, const std::vector<double>& per_vertex, int f, double u, double v) {
  assert(per_vertex.size() == mesh.points_in_world.size());
  if (f < 0) return std::numeric_limits<double>::quiet_NaN();
  // Float barycentrics can stray a hair below 0 at an edge: clamped, and the half-weight
  // rule taken against their sum.
  const double weights[3] = {std::max(0.0, 1.0 - u - v), std::max(0.0, u), std::max(0.0, v)};
  const double total = weights[0] + weights[1] + weights[2];
  const Eigen::Vector3i& face = mesh.faces[static_cast<size_t>(f)];
  double weight_sum = 0, value_sum = 0;
  for (int k = 0; k < 3; ++k) {
    const double value = per_vertex[static_cast<size_t>(face[k])];
    if (!std::isfinite(value)) continue;
    weight_sum += weights[k];
    value_sum += weights[k] * value;
  }
  if (!(weight_sum > 0) || weight_sum < 0.5 * total) return std::numeric_limits<double>::quiet_NaN();
  return value_sum / weight_sum;
}

float InterpolateAtSample(const ThermalMesh& mesh, const std::vector<double>& per_vertex,
                          const SampleBuffer& samples, size_t sample_index) {
  return static_cast<float>(InterpolateOnFace(mesh, per_vertex, samples.face[sample_index],
                                              samples.bary_u[sample_index], samples.bary_v[sample_index]));
}

// ---------------------------------------------------------------------------------------

namespace {

// The intersection context of a render: Embree hands it to the filter, which finds the
// face normals behind it (the documented way to pass per-query data to a filter).
struct CullContext {
  RTCIntersectContext context;  // first member: Embree's pointer is this struct's
  const Eigen::Vector3f* face_normals = nullptr;
};

// Rejects hits on faces whose counter-clockwise normal points along the ray.
void CullBackFaces(const RTCFilterFunctionNArguments* args) {
  const auto* cull = reinterpret_cast<const CullContext*>(args->context);
  for (unsigned i = 0; i < args->N; ++i) {
    if (args->valid[i] != -1) continue;
    const unsigned face = RTCHitN_primID(args->hit, args->N, i);
    const Eigen::Vector3f& n = cull->face_normals[face];
    const float along = n.x() * RTCRayN_dir_x(args->ray, args->N, i) +
                        n.y() * RTCRayN_dir_y(args->ray, args->N, i) +
                        n.z() * RTCRayN_dir_z(args->ray, args->N, i);
    if (along > 0) args->valid[i] = 0;
  }
}

// One ray for rtcIntersect1 / rtcOccluded1: origin + t·direction, t in [t_near, t_far].
RTCRay SingleRay(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction, double t_near, double t_far) {
  RTCRay ray;
  ray.org_x = static_cast<float>(origin.x());
  ray.org_y = static_cast<float>(origin.y());
  ray.org_z = static_cast<float>(origin.z());
  ray.dir_x = static_cast<float>(direction.x());
  ray.dir_y = static_cast<float>(direction.y());
  ray.dir_z = static_cast<float>(direction.z());
  ray.tnear = static_cast<float>(t_near);
  ray.tfar = static_cast<float>(t_far);
  ray.time = 0;
  ray.mask = 0xffffffffU;
  ray.id = 0;
  ray.flags = 0;
  return ray;
}

}  // namespace

struct MeshRenderer::Impl {
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  std::vector<Eigen::Vector3f> face_normals;  // unit, counter-clockwise (outward)
  double build_seconds = 0;
  std::mutex error_mutex;
  std::string error;  // first Embree error not yet thrown

  static void OnError(void* user, RTCError code, const char* message) {
    auto* impl = static_cast<Impl*>(user);
    const std::lock_guard<std::mutex> lock(impl->error_mutex);
    if (impl->error.empty()) {
      impl->error = "Embree error " + std::to_string(static_cast<int>(code)) + ": " +
                    (message != nullptr ? message : "(no message)");
    }
  }

  // Embree reports errors through the callback from inside its C API, where an exception
  // must not unwind: they are recorded there and thrown here, after each call.
  void ThrowIfError() {
    std::string message;
    {
      const std::lock_guard<std::mutex> lock(error_mutex);
      message.swap(error);
    }
    if (!message.empty()) throw std::runtime_error(message);
  }

  ~Impl() {
    if (scene != nullptr) rtcReleaseScene(scene);
    if (device != nullptr) rtcReleaseDevice(device);
  }
};

MeshRenderer::MeshRenderer(const ThermalMesh& mesh) : impl_(std::make_unique<Impl>()) {
  assert(mesh.NumFaces() > 0);
  const auto start = std::chrono::steady_clock::now();
  Impl& m = *impl_;
  m.device = rtcNewDevice(nullptr);
  if (m.device == nullptr) {
    throw std::runtime_error("Embree: cannot create a device (error " +
                             std::to_string(static_cast<int>(rtcGetDeviceError(nullptr))) + ")");
  }
  rtcSetDeviceErrorFunction(m.device, &Impl::OnError, &m);

  m.scene = rtcNewScene(m.device);
  // The high-quality build (spatial splits) pays off up to a million triangles; beyond, its
  // time (seconds) outweighs a few per cent of render speed.
  const RTCBuildQuality quality = mesh.NumFaces() > 1000000 ? RTC_BUILD_QUALITY_MEDIUM : RTC_BUILD_QUALITY_HIGH;
  rtcSetSceneBuildQuality(m.scene, quality);
  // The back-face filter is a context filter, set per render: no cost when not culling.
  rtcSetSceneFlags(m.scene, RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION);
  RTCGeometry geometry = rtcNewGeometry(m.device, RTC_GEOMETRY_TYPE_TRIANGLE);
  m.ThrowIfError();
  rtcSetGeometryBuildQuality(geometry, quality);
  auto* vertices = static_cast<float*>(rtcSetNewGeometryBuffer(
      geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), mesh.points_in_world.size()));
  auto* indices = static_cast<unsigned*>(rtcSetNewGeometryBuffer(
      geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), mesh.faces.size()));
  if (vertices == nullptr || indices == nullptr) {
    rtcReleaseGeometry(geometry);
    m.ThrowIfError();
    throw std::runtime_error("Embree: cannot allocate the mesh buffers");
  }
  for (size_t i = 0; i < mesh.points_in_world.size(); ++i) {
    const Eigen::Vector3f p = mesh.points_in_world[i].cast<float>();
    vertices[3 * i] = p.x();
    vertices[3 * i + 1] = p.y();
    vertices[3 * i + 2] = p.z();
  }
  m.face_normals.resize(mesh.faces.size());
  for (size_t f = 0; f < mesh.faces.size(); ++f) {
    const Eigen::Vector3i& face = mesh.faces[f];
    for (int k = 0; k < 3; ++k) indices[3 * f + static_cast<size_t>(k)] = static_cast<unsigned>(face[k]);
    const Eigen::Vector3d& a = mesh.points_in_world[static_cast<size_t>(face[0])];
    const Eigen::Vector3d& b = mesh.points_in_world[static_cast<size_t>(face[1])];
    const Eigen::Vector3d& c = mesh.points_in_world[static_cast<size_t>(face[2])];
    m.face_normals[f] = (b - a).cross(c - a).normalized().cast<float>();
  }
  rtcCommitGeometry(geometry);
  rtcAttachGeometry(m.scene, geometry);
  rtcReleaseGeometry(geometry);
  rtcCommitScene(m.scene);
  m.ThrowIfError();
  m.build_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

MeshRenderer::~MeshRenderer() = default;

double MeshRenderer::build_seconds() const { return impl_->build_seconds; }

SampleBuffer MeshRenderer::Render(const Camera& camera, const RenderOptions& options) const {
  SampleBuffer out;
  Render(camera, options, &out);
  return out;
}

void MeshRenderer::Render(const Camera& camera, const RenderOptions& options, SampleBuffer* samples) const {
  assert(options.Check().empty());
  assert(camera.Check().empty());
  assert(samples != nullptr);
  const int spp = options.samples_per_pixel;
  SampleBuffer& out = *samples;
  out.width = camera.width;
  out.height = camera.height;
  out.samples_per_pixel = spp;
  const size_t n = static_cast<size_t>(camera.width) * static_cast<size_t>(camera.height) * static_cast<size_t>(spp);
  out.face.assign(n, -1);
  out.bary_u.assign(n, 0.0f);
  out.bary_v.assign(n, 0.0f);
  out.depth_m.assign(n, std::numeric_limits<float>::infinity());
  out.cos_incidence.assign(n, 0.0f);

  // Rays in camera coordinates scaled to z = 1 (perspective) or unit z (orthographic), so
  // Embree's hit distance is the depth along the camera's z.
  const Eigen::Matrix3f r = camera.world_from_camera.linear().cast<float>();
  const Eigen::Vector3f t = camera.world_from_camera.translation().cast<float>();
  const float cx = 0.5f * static_cast<float>(camera.width);
  const float cy = 0.5f * static_cast<float>(camera.height);
  const float px_scale = camera.orthographic
                             ? static_cast<float>(camera.ortho_height_m / camera.height)
                             : static_cast<float>(1.0 / camera.FocalPx());
  const bool ortho = camera.orthographic;

  const int tile = options.tile_px;
  const int tiles_x = (camera.width + tile - 1) / tile;
  const int tiles_y = (camera.height + tile - 1) / tile;
  const int num_tiles = tiles_x * tiles_y;
  std::atomic<int> next_tile{0};
  const Impl& m = *impl_;

  auto worker = [&]() {
    CullContext cull;
    rtcInitIntersectContext(&cull.context);
    cull.context.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
    cull.context.filter = options.cull_back_faces ? &CullBackFaces : nullptr;
    cull.face_normals = m.face_normals.data();
    alignas(64) RTCRayHit16 packet;
    alignas(64) int valid[16];
    int pixel_x[16], pixel_y[16];
    for (int tile_index = next_tile.fetch_add(1); tile_index < num_tiles; tile_index = next_tile.fetch_add(1)) {
      const int x0 = (tile_index % tiles_x) * tile;
      const int y0 = (tile_index / tiles_x) * tile;
      const int x1 = std::min(x0 + tile, camera.width);
      const int y1 = std::min(y0 + tile, camera.height);
      for (int s = 0; s < spp; ++s) {
        for (int by = y0; by < y1; by += 4) {
          for (int bx = x0; bx < x1; bx += 4) {
            for (int i = 0; i < 16; ++i) {
              const int x = bx + (i & 3);
              const int y = by + (i >> 2);
              pixel_x[i] = x;
              pixel_y[i] = y;
              valid[i] = (x < x1 && y < y1) ? -1 : 0;
              const Eigen::Vector2d offset = SampleOffset(x, y, s, spp);
              const float u = (static_cast<float>(x) + static_cast<float>(offset.x()) - cx) * px_scale;
              const float v = (static_cast<float>(y) + static_cast<float>(offset.y()) - cy) * px_scale;
              Eigen::Vector3f origin, direction;
              if (ortho) {
                origin = t + r.col(0) * u + r.col(1) * v;
                direction = r.col(2);
              } else {
                origin = t;
                direction = r.col(0) * u + r.col(1) * v + r.col(2);
              }
              packet.ray.org_x[i] = origin.x();
              packet.ray.org_y[i] = origin.y();
              packet.ray.org_z[i] = origin.z();
              packet.ray.dir_x[i] = direction.x();
              packet.ray.dir_y[i] = direction.y();
              packet.ray.dir_z[i] = direction.z();
              packet.ray.tnear[i] = 0.0f;
              packet.ray.tfar[i] = std::numeric_limits<float>::infinity();
              packet.ray.time[i] = 0.0f;
              packet.ray.mask[i] = 0xffffffffU;
              packet.ray.id[i] = static_cast<unsigned>(i);
              packet.ray.flags[i] = 0;
              packet.hit.geomID[i] = RTC_INVALID_GEOMETRY_ID;
              packet.hit.primID[i] = RTC_INVALID_GEOMETRY_ID;
            }
            rtcIntersect16(valid, m.scene, &cull.context, &packet);
            for (int i = 0; i < 16; ++i) {
              if (valid[i] == 0 || packet.hit.geomID[i] == RTC_INVALID_GEOMETRY_ID) continue;
              const size_t index = out.Index(pixel_x[i], pixel_y[i], s);
              const unsigned face = packet.hit.primID[i];
              out.face[index] = static_cast<int>(face);
              out.bary_u[index] = packet.hit.u[i];
              out.bary_v[index] = packet.hit.v[i];
              out.depth_m[index] = packet.ray.tfar[i];
              const Eigen::Vector3f direction(packet.ray.dir_x[i], packet.ray.dir_y[i], packet.ray.dir_z[i]);
              out.cos_incidence[index] = std::abs(m.face_normals[face].dot(direction)) / direction.norm();
            }
          }
        }
      }
    }
  };

  int threads = options.num_threads > 0 ? options.num_threads
                                        : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  threads = std::min(threads, num_tiles);
  std::vector<std::thread> pool;
  pool.reserve(static_cast<size_t>(threads - 1));
  for (int i = 1; i < threads; ++i) pool.emplace_back(worker);
  worker();
  for (std::thread& thread : pool) thread.join();
  impl_->ThrowIfError();
}

bool MeshRenderer::Unoccluded(const Eigen::Vector3d& from_in_world, const Eigen::Vector3d& to_in_world,
                              double epsilon_m) const {
  const Eigen::Vector3d direction = to_in_world - from_in_world;
  const double length = direction.norm();
  if (length <= 2 * epsilon_m) return true;
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  // Distances in units of the segment: the direction is not normalised.
  RTCRay ray = SingleRay(from_in_world, direction, epsilon_m / length, 1.0 - epsilon_m / length);
  rtcOccluded1(impl_->scene, &context, &ray);
  impl_->ThrowIfError();
  // Embree sets tfar to −inf when it finds a hit.
  return ray.tfar >= 0;
}

MeshRenderer::Hit MeshRenderer::Intersect(const Eigen::Vector3d& origin_in_world,
                                          const Eigen::Vector3d& direction_in_world, double t_min_m,
                                          double t_max_m) const {
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  RTCRayHit query;
  query.ray = SingleRay(origin_in_world, direction_in_world, t_min_m, t_max_m);
  query.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  query.hit.primID = RTC_INVALID_GEOMETRY_ID;
  query.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(impl_->scene, &context, &query);
  impl_->ThrowIfError();
  Hit hit;
  if (query.hit.geomID == RTC_INVALID_GEOMETRY_ID) return hit;
  hit.face = static_cast<int>(query.hit.primID);
  hit.bary_u = query.hit.u;
  hit.bary_v = query.hit.v;
  hit.t_m = query.ray.tfar;
  return hit;
}

}  // namespace hw::analyze
