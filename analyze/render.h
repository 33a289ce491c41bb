#pragma once

// Ray-traced rendering of a ThermalMesh with Embree 3: packets of 16 rays (rtcIntersect16)
// over pixel tiles, on our own threads, several jittered samples per pixel (anti-aliasing).
// The renderer only finds what every sample sees (face, barycentrics, depth, incidence);
// analyze/views.h turns samples into images (palettes, IH mapping, highlighting) and
// averages them per pixel in linear light.
//
// Camera frame: OpenCV's — x right, y down, z forward (the viewing direction); pixel (0, 0)'s
// top-left corner is at image coordinates (0, 0), its centre at (0.5, 0.5).

#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "analyze/thermal_mesh.h"

namespace hw::analyze {

struct Camera {
  Eigen::Isometry3d world_from_camera = Eigen::Isometry3d::Identity();
  bool orthographic = false;
  double fov_y_deg = 40;     // perspective: vertical field of view, degrees, in (0, 170)
  double ortho_height_m = 1; // orthographic: height of the view, metres, > 0
  int width = 1280;          // pixels, > 0
  int height = 960;          // pixels, > 0

  // Focal length in pixels (perspective).
  double FocalPx() const;
  // Image coordinates (pixels, continuous, see the frame note above) of a world point and
  // its depth along z (metres; negative: behind the camera, the pixel is then meaningless).
  Eigen::Vector2d Project(const Eigen::Vector3d& point_in_world, double* depth_m = nullptr) const;
  // Ray through image coordinates (x, y): origin and unit direction, world frame.
  void Ray(double x, double y, Eigen::Vector3d* origin_in_world, Eigen::Vector3d* direction_in_world) const;

  // "" when valid (field ranges above, a rotation in world_from_camera), else a message
  // naming the field, its value and the constraint.
  std::string Check() const;
};

// `camera` (its projection and size kept) placed at `eye_in_world` looking at
// `target_in_world` (camera +z), with `up_in_world` pointing up in the image (camera −y)
// as far as it can: when up is (nearly, < 1°) parallel to the viewing direction, another
// world axis is used instead, so a view straight down still has a defined roll. Asserts
// eye != target and a non-zero up.
Camera LookAt(const Eigen::Vector3d& eye_in_world, const Eigen::Vector3d& target_in_world,
              const Eigen::Vector3d& up_in_world, Camera camera = {});

struct RenderOptions {
  // Samples per pixel, a square number 1, 4, 9 or 16: stratified jittered positions (a
  // fixed pattern: images are reproducible). 4 removes the staircase of edges and iso-lines
  // at 1280×960; 1 for speed.
  int samples_per_pixel = 4;
  // Threads rendering tiles; 0 = std::thread::hardware_concurrency().
  int num_threads = 0;
  // Tile side in pixels (16×16 pixels per task), in [4, 256].
  int tile_px = 16;
  // Ignore faces seen from behind (the ray along the face's counter-clockwise normal): an
  // overview of a room scanned from inside, shot from outside, then sees through the near
  // walls into the interior instead of their backs. Unoccluded() never culls.
  bool cull_back_faces = false;

  std::string Check() const;
};

// What every sample of a render saw. Index of sample s of pixel (x, y):
// (y·width + x)·samples_per_pixel + s.
struct SampleBuffer {
  int width = 0;
  int height = 0;
  int samples_per_pixel = 1;
  std::vector<int> face;          // hit face index into ThermalMesh::faces, −1 for a miss
  std::vector<float> bary_u;      // barycentric weight of the face's vertex 1
  std::vector<float> bary_v;      // barycentric weight of vertex 2 (vertex 0: 1 − u − v)
  std::vector<float> depth_m;     // distance along the camera's z to the hit; +inf for a miss
  std::vector<float> cos_incidence;  // |cos| of the angle between the ray and the face normal

  size_t Index(int x, int y, int s) const {
    return (static_cast<size_t>(y) * static_cast<size_t>(width) + static_cast<size_t>(x)) *
               static_cast<size_t>(samples_per_pixel) + static_cast<size_t>(s);
  }
  size_t NumSamples() const { return face.size(); }
};

// Where sample s of pixel (x, y) lies inside the pixel, each coordinate in [0, 1) (add x,
// y for image coordinates): the pixel centre (0.5, 0.5) for 1 sample per pixel; otherwise
// stratified: sample s lies in cell (s mod n, s div n) of the n×n grid (n² =
// samples_per_pixel), jittered within it by a hash of (x, y, s), so the pattern is fixed
// (reproducible images, independent of threads and tiles) yet does not repeat per pixel.
Eigen::Vector2d SampleOffset(int x, int y, int s, int samples_per_pixel);

// A per-vertex scalar at a sample: barycentric interpolation over the face's vertices whose
// value is finite, renormalised; NaN when those vertices carry less than half of the
// sample's barycentric weight (so unobserved surface stays unobserved up to the midpoint
// towards observed vertices, never extrapolated) or for a miss.
float InterpolateAtSample(const ThermalMesh& mesh, const std::vector<double>& per_vertex,
                          const SampleBuffer& samples, size_t sample_index);
// The same rule at barycentrics (u, v) of face f (−1: NaN), e.g. a MeshRenderer::Hit's.
double InterpolateOnFace(const ThermalMesh& mesh, const std::vector<double>& per_vertex, int f, double u, double v);

// The Embree scene of one mesh, built once (BVH) and rendered from many cameras.
class MeshRenderer {
 public:
  // Builds the BVH (Embree's high-quality build for static scenes). Asserts the mesh has
  // faces. Throws std::runtime_error with Embree's message if the device fails.
  explicit MeshRenderer(const ThermalMesh& mesh);
  ~MeshRenderer();
  MeshRenderer(const MeshRenderer&) = delete;
  MeshRenderer& operator=(const MeshRenderer&) = delete;

  // Seconds the BVH build took.
  double build_seconds() const;

  // Renders every sample. Asserts options.Check() == "" and a valid camera.
  SampleBuffer Render(const Camera& camera, const RenderOptions& options) const;
  // The same into *samples, reusing its vectors' memory: renders of one size in a row
  // then allocate nothing (fresh pages cost a fault each: 98 MB at 4 spp, 1280×960).
  void Render(const Camera& camera, const RenderOptions& options, SampleBuffer* samples) const;

  // True when the segment from `from_in_world` to `to_in_world` hits no surface (both ends
  // excluded by `epsilon_m`): occlusion tests for labels and close-up views.
  bool Unoccluded(const Eigen::Vector3d& from_in_world, const Eigen::Vector3d& to_in_world,
                  double epsilon_m = 1e-4) const;

  // The first surface along origin + t·direction (unit direction, world frame) with t in
  // (t_min_m, t_max_m), back faces included: face index (into ThermalMesh::faces),
  // barycentric weights of its vertices 1 and 2, and t; face −1 for a miss.
  struct Hit {
    int face = -1;
    float bary_u = 0, bary_v = 0;
    double t_m = 0;
  };
  Hit Intersect(const Eigen::Vector3d& origin_in_world, const Eigen::Vector3d& direction_in_world, double t_min_m,
                double t_max_m) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace hw::analyze
