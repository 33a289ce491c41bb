#include "reconstruct/tsdf_volume.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <cstring>
#include <limits>
#include <random>
#include <set>
#include <tuple>
#include <vector>

#include <gtest/gtest.h>

#include "reconstruct/tsdf_test_support.h"
#include "reconstruct/tsdf_volume_impl.h"

namespace hw::reconstruct {
namespace {

// One storage step of a voxel's sdf (2^-14 of the band): a stored value is the exact one
// rounded to the nearest step, so within half a step of it.
constexpr float kSdfStep = 1.0f / Voxel::kSdfUnit;

using test::SmallCamera;
using test::SmallOptions;

// ---------------------------------------------------------------- storage

TEST(TsdfStorage, FindVoxelAcrossNegativeCoordinates) {
  TsdfVolume volume(SmallOptions());
  VoxelBlock& minus = volume.GetOrCreateBlock(BlockKey(-1, -1, -1));
  VoxelBlock& plus = volume.GetOrCreateBlock(BlockKey(0, 0, 0));
  EXPECT_EQ(volume.NumBlocks(), 2u);
  // Voxel −1 is the last of block −1; voxel 0 the first of block 0; −8 the first of −1.
  EXPECT_EQ(volume.FindVoxel({-1, -1, -1}), &minus.voxels[7 + 8 * (7 + 8 * 7)]);
  EXPECT_EQ(volume.FindVoxel({-8, -8, -8}), &minus.voxels[0]);
  EXPECT_EQ(volume.FindVoxel({-8, -7, -6}), &minus.voxels[0 + 8 * (1 + 8 * 2)]);
  EXPECT_EQ(volume.FindVoxel({0, 0, 0}), &plus.voxels[0]);
  EXPECT_EQ(volume.FindVoxel({7, 6, 5}), &plus.voxels[7 + 8 * (6 + 8 * 5)]);
  EXPECT_EQ(volume.FindVoxel({-9, -1, -1}), nullptr);  // block (−2, −1, −1)
  EXPECT_EQ(volume.FindVoxel({8, 0, 0}), nullptr);     // block (1, 0, 0)
  EXPECT_EQ(volume.FindVoxel({-1, 0, 0}), nullptr);    // block (−1, 0, 0)
  EXPECT_EQ(volume.FindBlock(BlockKey(-1, -1, -1)), &minus);
  EXPECT_EQ(minus.key, BlockKey(-1, -1, -1));
  // Creating again returns the same block.
  EXPECT_EQ(&volume.GetOrCreateBlock(BlockKey(-1, -1, -1)), &minus);
  EXPECT_EQ(volume.NumBlocks(), 2u);
  // Far keys: distinct blocks (no aliasing of the packed key).
  volume.GetOrCreateBlock(BlockKey(100000, -100000, 7));
  volume.GetOrCreateBlock(BlockKey(-100000, 100000, 7));
  EXPECT_EQ(volume.NumBlocks(), 4u);
  EXPECT_EQ(volume.FindBlock(BlockKey(100000, -100000, 7))->key, BlockKey(100000, -100000, 7));
  EXPECT_EQ(volume.FindBlock(BlockKey(100000, 100000, 7)), nullptr);
}

// Fills blocks [lo, hi]³ (block keys) with sdf = a·x + b·y + c·z + d at voxel centres (metres).
void FillLinear(TsdfVolume& volume, int lo, int hi, const Eigen::Vector4f& field) {
  const float h = volume.voxel_size_m();
  for (int bz = lo; bz <= hi; ++bz) {
    for (int by = lo; by <= hi; ++by) {
      for (int bx = lo; bx <= hi; ++bx) {
        VoxelBlock& block = volume.GetOrCreateBlock(BlockKey(bx, by, bz));
        for (int i = 0; i < kBlockVoxels; ++i) {
          const Eigen::Vector3i v = block.key * kBlockSide + Eigen::Vector3i(i % 8, (i / 8) % 8, i / 64);
          const Eigen::Vector3f p = v.cast<float>() * h;
          block.voxels[i].set_sdf(field.head<3>().dot(p) + field.w());
          block.voxels[i].set_weight(1);
          block.voxels[i].colour = Rgb8(10, 20, 30);
          block.voxels[i].colour_weight = 1;
        }
      }
    }
  }
}

TEST(TsdfStorage, SdfAndNormalExactOnALinearField) {
  TsdfVolume volume(SmallOptions());
  const Eigen::Vector4f field(0.3f, -0.5f, 0.8f, 0.1f);
  FillLinear(volume, -2, 1, field);  // voxels −16 … 15 along each axis
  const float h = volume.voxel_size_m();
  std::mt19937 rng(5);
  // Points whose 4×4×4 neighbourhood stays inside: voxel coordinates in [−15, 13].
  std::uniform_real_distribution<float> coord(-15 * h, 13 * h);
  TsdfSampler sampler(volume);
  for (int i = 0; i < 2000; ++i) {
    const Eigen::Vector3f p(coord(rng), coord(rng), coord(rng));
    const float expected = field.head<3>().dot(p) + field.w();
    const auto sdf = volume.SdfAt(p);
    ASSERT_TRUE(sdf.has_value());
    // The voxels' storage (half a step: trilinear weights sum to 1) and float rounding of
    // values of order 0.1 (1e-5).
    EXPECT_NEAR(*sdf, expected, 0.5f * kSdfStep + 1e-5f) << p.transpose();
    float fast;
    ASSERT_TRUE(sampler.Sdf(p, fast));
    EXPECT_NEAR(fast, *sdf, 1e-6f);
    const auto normal = volume.NormalAt(p);
    ASSERT_TRUE(normal.has_value());
    // Each central difference spans 2 voxels and each of its two samples is within half a
    // storage step: a component of the gradient is off by at most one step in 2h·|∇| (this
    // field is shallow, 1 band per m: 0.3 % at 1 cm), the unit vector by √3 times that.
    const float storage = std::sqrt(3.0f) * kSdfStep / (2 * h * field.head<3>().norm());
    EXPECT_LT((*normal - field.head<3>().normalized()).norm(), storage + 1e-4f) << p.transpose();
    const auto colour = volume.ColourAt(p);
    ASSERT_TRUE(colour.has_value());
    EXPECT_EQ(*colour, Rgb8(10, 20, 30));
  }
  // At voxel centres: the stored value itself (the cell's first corner).
  const Voxel* v = volume.FindVoxel({-3, 4, -9});
  ASSERT_NE(v, nullptr);
  EXPECT_FLOAT_EQ(*volume.SdfAt(Eigen::Vector3f(-3, 4, -9) * h), v->sdf());
  // Outside the filled blocks: nothing.
  EXPECT_FALSE(volume.SdfAt(Eigen::Vector3f(20, 0, 0) * h).has_value());
  EXPECT_FALSE(volume.SdfAt(Eigen::Vector3f(15.5f, 0, 0) * h).has_value());  // corner at voxel 16
  EXPECT_FALSE(volume.NormalAt(Eigen::Vector3f(14.5f, 0, 0) * h).has_value());  // needs voxel 16
  EXPECT_TRUE(volume.NormalAt(Eigen::Vector3f(13.5f, 0, 0) * h).has_value());
  float unused;
  EXPECT_EQ(sampler.Sample(Eigen::Vector3f(16.5f, 0, 0) * h, unused), TsdfSampler::Status::kNoBlock);
}

TEST(TsdfStorage, UnobservedVoxelsAreNotInterpolated) {
  TsdfVolume volume(SmallOptions());
  FillLinear(volume, 0, 0, Eigen::Vector4f(1, 0, 0, 0));
  const float h = volume.voxel_size_m();
  const Eigen::Vector3f p(3.5f * h, 3.5f * h, 3.5f * h);
  EXPECT_TRUE(volume.SdfAt(p).has_value());
  VoxelBlock& block = volume.GetOrCreateBlock(BlockKey(0, 0, 0));
  block.voxels[4 + 8 * (4 + 8 * 4)].set_weight(0);  // corner (4, 4, 4) of the cell at 3.5
  EXPECT_FALSE(volume.SdfAt(p).has_value());
  EXPECT_FALSE(volume.ColourAt(p).has_value());
  EXPECT_FALSE(volume.NormalAt(Eigen::Vector3f(2.5f, 3.5f, 3.5f) * h).has_value());
  TsdfSampler sampler(volume);
  float sdf;
  EXPECT_EQ(sampler.Sample(p, sdf), TsdfSampler::Status::kUnobserved);
  // A cell reaching into a missing block is unobserved, not "no block".
  EXPECT_EQ(sampler.Sample(Eigen::Vector3f(7.5f, 1, 1) * h, sdf), TsdfSampler::Status::kUnobserved);
}

TEST(TsdfStorage, BoundsAndMemory) {
  TsdfVolume volume(SmallOptions());
  Eigen::Vector3f lo, hi;
  volume.Bounds(lo, hi);
  EXPECT_EQ(lo, Eigen::Vector3f::Zero());
  EXPECT_EQ(hi, Eigen::Vector3f::Zero());
  const size_t empty = volume.MemoryBytes();
  volume.GetOrCreateBlock(BlockKey(-2, 0, 3));
  const size_t one = volume.MemoryBytes();
  EXPECT_GE(one, empty + sizeof(VoxelBlock));
  volume.GetOrCreateBlock(BlockKey(1, -1, 3));
  EXPECT_GE(volume.MemoryBytes(), one + sizeof(VoxelBlock));
  volume.Bounds(lo, hi);
  const float b = 0.08f, h = 0.01f;
  EXPECT_NEAR(lo.x(), -2 * b, 1e-6);
  EXPECT_NEAR(lo.y(), -1 * b, 1e-6);
  EXPECT_NEAR(lo.z(), 3 * b, 1e-6);
  EXPECT_NEAR(hi.x(), 1 * b + 7 * h, 1e-6);
  EXPECT_NEAR(hi.y(), 0 * b + 7 * h, 1e-6);
  EXPECT_NEAR(hi.z(), 3 * b + 7 * h, 1e-6);
  int n = 0;
  volume.ForEachBlock([&](const VoxelBlock&) { ++n; });
  EXPECT_EQ(n, 2);
}

// Blocks live in chunks of memory handed out in order (BlockArena): several chunks' worth
// must come out at the defaults, keep their addresses as more are made, and not overlap.
TEST(TsdfStorage, BlocksKeepTheirAddressesAndDefaultsAcrossChunks) {
  TsdfVolume volume(SmallOptions());
  constexpr int kBlocks = 4000;  // ~3 chunks of 8 MB
  std::vector<const VoxelBlock*> made;
  for (int i = 0; i < kBlocks; ++i) {
    VoxelBlock& block = volume.GetOrCreateBlock(BlockKey(i % 20 - 10, (i / 20) % 20, i / 400 - 5));
    // Marks its first and last voxels: a later block overlapping it would overwrite them.
    block.voxels.front().weight_count = static_cast<std::uint16_t>(i);
    block.voxels.back().sdf_steps = static_cast<std::int16_t>(-i);
    made.push_back(&block);
  }
  ASSERT_EQ(volume.NumBlocks(), static_cast<size_t>(kBlocks));
  for (int i = 0; i < kBlocks; ++i) {
    const BlockKey key(i % 20 - 10, (i / 20) % 20, i / 400 - 5);
    ASSERT_EQ(volume.FindBlock(key), made[i]) << i;
    ASSERT_EQ(made[i]->key, key) << i;
    ASSERT_EQ(made[i]->voxels.front().weight_count, i) << i;
    ASSERT_EQ(made[i]->voxels.back().sdf_steps, -i) << i;
    for (int v = 1; v < kBlockVoxels; ++v) {
      const Voxel& voxel = made[i]->voxels[v];
      if (v < kBlockVoxels - 1) {
        ASSERT_EQ(voxel.sdf(), 1.0f) << i << " " << v;
      }
      ASSERT_EQ(voxel.weight(), 0.0f) << i << " " << v;
      ASSERT_EQ(voxel.colour, Rgb8::Zero()) << i << " " << v;
      ASSERT_EQ(voxel.colour_weight, 0) << i << " " << v;
    }
  }
}

// Every block is reported once, with its region's box holding it; regions failing the test
// hide exactly their blocks; blocks created between calls are indexed.
TEST(TsdfStorage, ForEachBlockInRegions) {
  TsdfVolume volume(SmallOptions());  // 8 cm blocks, 64 cm regions
  const BlockKey keys[] = {{0, 0, 0}, {7, 7, 7}, {8, 0, 0}, {-1, 0, 0}, {-8, -9, 3}, {3, 4, 15}};
  for (const BlockKey& k : keys) volume.GetOrCreateBlock(k);
  std::vector<BlockKey> seen;
  const float block_m = 0.08f;
  volume.ForEachBlockInRegions(
      [&](const Eigen::Vector3f& min_m, const Eigen::Vector3f& max_m) {
        EXPECT_NEAR((max_m - min_m).maxCoeff(), 8 * block_m, 1e-6);
        EXPECT_NEAR((max_m - min_m).minCoeff(), 8 * block_m, 1e-6);
        return true;
      },
      [&](const VoxelBlock& b) { seen.push_back(b.key); });
  ASSERT_EQ(seen.size(), std::size(keys));
  for (const BlockKey& k : keys) EXPECT_EQ(std::count(seen.begin(), seen.end(), k), 1) << k.transpose();
  // Keep only the region of (0, 0, 0): blocks 0…7 on each axis, box [0, 0.64) m.
  auto origin_only = [](const Eigen::Vector3f& min_m, const Eigen::Vector3f&) {
    return min_m.norm() < 1e-6f;
  };
  seen.clear();
  volume.ForEachBlockInRegions(origin_only, [&](const VoxelBlock& b) { seen.push_back(b.key); });
  EXPECT_EQ(seen, (std::vector<BlockKey>{{0, 0, 0}, {7, 7, 7}}));
  volume.GetOrCreateBlock(BlockKey(2, 5, 1));
  volume.GetOrCreateBlock(BlockKey(-2, 5, 1));
  seen.clear();
  volume.ForEachBlockInRegions(origin_only, [&](const VoxelBlock& b) { seen.push_back(b.key); });
  EXPECT_EQ(seen, (std::vector<BlockKey>{{0, 0, 0}, {7, 7, 7}, {2, 5, 1}}));
}

TEST(TsdfOptions, CheckNamesTheField) {
  TsdfOptions o;
  EXPECT_EQ(o.Check(), "");
  o.truncation_m = 0.005;
  EXPECT_NE(o.Check().find("truncation_m"), std::string::npos);
  // A voxel counts its weight in 16 bits: whole frames only.
  for (const double w : {0.5, 2.5, 65536.0}) {
    TsdfOptions bad;
    bad.max_weight = w;
    EXPECT_NE(bad.Check().find("max_weight"), std::string::npos) << w;
  }
  o = TsdfOptions();
  o.max_weight = 65535;
  EXPECT_EQ(o.Check(), "");
}

TEST(TsdfOptions, TheBandFollowsTheDepthNoiseWhereItIsWider) {
  TsdfOptions o;
  // Nguyen et al.'s Kinect model: σ = 1.2 mm + 1.9 mm/m² · (z − 0.4 m)²; 3σ passes 2 cm at 2.1 m.
  EXPECT_FLOAT_EQ(o.TruncationAt(0.5f), 0.02f);
  EXPECT_FLOAT_EQ(o.TruncationAt(2.0f), 0.02f);
  EXPECT_NEAR(o.TruncationAt(3.0f), 3 * (0.0012 + 0.0019 * 2.6 * 2.6), 1e-6);
  EXPECT_NEAR(o.TruncationAt(4.0f), 3 * (0.0012 + 0.0019 * 3.6 * 3.6), 1e-6);
  o.truncation_noise_sigmas = 0;
  EXPECT_FLOAT_EQ(o.TruncationAt(4.0f), 0.02f);
  {
    TsdfOptions bad;
    bad.truncation_noise_sigmas = -0.1;
    EXPECT_NE(bad.Check().find("truncation_noise_sigmas"), std::string::npos);
    bad.truncation_noise_sigmas = std::numeric_limits<double>::infinity();
    EXPECT_NE(bad.Check().find("truncation_noise_sigmas"), std::string::npos);
  }
  // The noise model's own check, named through the field that holds it.
  for (auto [field, name] : {std::pair{&DepthNoiseModel::base_m, "noise.base_m"},
                             std::pair{&DepthNoiseModel::quadratic_per_m, "noise.quadratic_per_m"},
                             std::pair{&DepthNoiseModel::reference_m, "noise.reference_m"}}) {
    TsdfOptions bad;
    bad.noise.*field = -0.1;
    EXPECT_NE(bad.Check().find(name), std::string::npos) << name;
    bad.noise.*field = std::numeric_limits<double>::infinity();
    EXPECT_NE(bad.Check().find(name), std::string::npos) << name;
    bad.noise.*field = 0;
    EXPECT_EQ(bad.Check(), "") << name;
  }
}

// A far frontal plane seen with depth noise about as wide as the fixed band: each voxel on
// the surface keeps the readings in front (clipped to +1) and drops those more than a band
// behind, so the fused zero crossing lies behind the plane, by what the same readings give in
// closed form (the mean of the kept, clipped distances is 0 there). The band widened to 3σ
// puts it on the plane. 64 frames whose whole image is offset by the 64 quantiles of the
// noise (a deterministic sample of it; weight cap 64: the voxels hold the exact mean).
TEST(TsdfIntegrate, FarSurfaceIsNotPushedBackByNoise) {
  const PinholeCamera camera = SmallCamera();
  const core::Rigid3d pose = core::Rigid3d::Identity();
  const float plane_z = 3.5f;
  const double sigma = 0.0012 + 0.0019 * static_cast<double>((plane_z - 0.4f) * (plane_z - 0.4f));  // 19.5 mm
  std::vector<float> offsets;
  for (int i = 0; i < 64; ++i) {
    const double p = (i + 0.5) / 64;
    double lo = -10, hi = 10;  // the standard normal quantile of p, by bisection
    for (int k = 0; k < 100; ++k) {
      const double mid = 0.5 * (lo + hi);
      (0.5 * std::erfc(-mid / std::sqrt(2.0)) < p ? lo : hi) = mid;
    }
    offsets.push_back(static_cast<float>(sigma * 0.5 * (lo + hi)));
  }
  // Fine: every voxel updated; coarse (the default at 3.5 m): the even ones, the others
  // between them.
  for (const bool coarse : {false, true}) {
    for (const double sigmas : {0.0, 3.0}) {
      TsdfOptions options;  // 5 mm voxels, 2 cm band: the defaults
      options.coarse_far = coarse;
      options.truncation_noise_sigmas = sigmas;
      options.max_weight = 64;
      TsdfVolume volume(options);
      for (const float n : offsets) {
        // A 16×16-pixel patch around the optical axis (0.4 m across at 3.5 m): the rest of
        // the plane would only cost time.
        cv::Mat depth(camera.height, camera.width, CV_32FC1, cv::Scalar(0));
        depth(cv::Rect(camera.width / 2 - 8, camera.height / 2 - 8, 16, 16)).setTo(plane_z + n);
        volume.Integrate(depth, camera, pose);
      }
      // The crossing the readings imply (x = plane − z: in front of it), the mean of every
      // kept reading clipped to the band, and what the grid holds of it: the same mean at the
      // voxel centres of a layer (all alike), of the readings that voxel was updated with —
      // those not more than a band behind it, whose band reaches its block (integration
      // visits only the blocks around each frame's surface: one farther in front keeps its
      // voxels unchanged, not +1) — linear between the two layers around the crossing (of the
      // even voxels when coarse: the layers between are their means).
      const float band = options.TruncationAt(plane_z);  // for the trace
      const float h = volume.voxel_size_m() * (coarse ? 2 : 1), block_m = kBlockSide * volume.voxel_size_m();
      auto mean_kept = [&](float z, bool blocks) {
        const float block_lo = std::floor(z / block_m) * block_m;
        double sum = 0;
        int kept = 0;
        for (const float n : offsets) {
          const float d = plane_z + n, band_d = options.TruncationAt(d);  // each reading its band
          if (d - z < -band_d) continue;
          if (blocks && !(d + band_d >= block_lo && d - band_d < block_lo + block_m)) continue;
          sum += static_cast<double>(std::min(1.0f, (d - z) * (1.0f / band_d)));
          ++kept;
        }
        return sum / kept;
      };
      float lo = plane_z - 0.05f, hi = plane_z + 0.05f;  // mean_kept decreases with z
      for (int k = 0; k < 60; ++k) (mean_kept(0.5f * (lo + hi), false) > 0 ? lo : hi) = 0.5f * (lo + hi);
      const float implied_z = 0.5f * (lo + hi);
      float z0 = std::round(plane_z / h) * h;
      while (mean_kept(z0, true) <= 0) z0 -= h;
      while (mean_kept(z0 + h, true) > 0) z0 += h;
      const double v0 = mean_kept(z0, true), v1 = mean_kept(z0 + h, true);
      const float expected_z = z0 + h * static_cast<float>(v0 / (v0 - v1));
      // The fused crossing along a ray near the optical axis (off the voxel grid's planes).
      TsdfSampler sampler(volume);
      auto sdf_at = [&](float z) {
        float s = 0;
        EXPECT_TRUE(sampler.Sdf(Eigen::Vector3f(0.0123f, -0.0071f, z), s)) << z;
        return s;
      };
      float near = plane_z - 0.04f, far = plane_z + 0.04f;
      ASSERT_GT(sdf_at(near), 0);
      ASSERT_LT(sdf_at(far), 0);
      for (int k = 0; k < 40; ++k) (sdf_at(0.5f * (near + far)) > 0 ? near : far) = 0.5f * (near + far);
      const float fused_z = 0.5f * (near + far);
      SCOPED_TRACE(testing::Message() << "sigmas " << sigmas << ", band " << band << " m, coarse " << coarse);
      // The running means in float, the bisections: 0.05 mm.
      EXPECT_NEAR(fused_z, expected_z, 5e-5f);
      if (sigmas == 0) {
        EXPECT_GT(implied_z - plane_z, 0.007f);  // 7.8 mm behind (σ ≈ the band) ...
        EXPECT_GT(fused_z - plane_z, 0.006f);    // ... 6.6 mm in the grid's blocks
      } else {
        // Not quite on it: each reading has its own depth's band (±1.7 mm over the readings
        // here), which weighs the nearer ones' distances more: 0.2 mm.
        EXPECT_NEAR(implied_z, plane_z, 5e-4f);
        EXPECT_NEAR(fused_z, plane_z, 5e-4f);
      }
    }
  }
}

// ---------------------------------------------------------------- integration

// The truncated projective distance of a frontal plane at depth `plane_z` is exact:
// sdf = min(1, (plane_z − z) / truncation) for every voxel in view up to one truncation behind.
// VoxelBlock::min_band_m, which the ray march steps by, must never exceed the band of a
// reading fused into the block (else a step could pass a surface): a frontal plane at 3.5 m
// (every reading's band 5.9 cm at the defaults) leaves each block it touched a bound in
// [the bound's own slack, band(3.5 m)]; the same plane from 1 m away lowers the blocks it
// reaches to the fixed band; carving lowers a block to the carved range's band; a block made
// otherwise reads 0 (unknown: the march then keeps truncation_m).
TEST(TsdfIntegrate, BlocksKeepALowerBoundOfTheirReadingsBands) {
  const PinholeCamera camera = SmallCamera();
  TsdfOptions options;  // 5 mm voxels, 2 cm band widened to 3 σ of the depth noise
  TsdfVolume volume(options);
  const TsdfOptions::NoiseBand band = options.Band();
  const float far_m = 3.5f, near_m = 1.0f;
  const core::Rigid3d far_pose = core::Rigid3d::Identity();
  volume.Integrate(test::RenderPlane(camera, far_pose, Eigen::Vector3d::UnitZ(), far_m), camera, far_pose);
  const float band_far = band.At(far_m);
  ASSERT_GT(band_far, 2.5f * static_cast<float>(options.truncation_m));  // the case that matters
  // The bound's slack: readings from z_near − band(z_near) − the bilinear spread (half a
  // truncation and 4 / f per metre of depth) of a block's nearest voxel, which lies up to half
  // the centres' diagonal (1.52 cm) before its centre, itself up to the band and half a
  // block's depth (2 cm) before the plane.
  const float block_m = static_cast<float>(options.voxel_size_m) * kBlockSide;
  const float lowest_z = far_m - band_far - 0.5f * block_m - 0.5f * std::sqrt(3.0f) * block_m;
  const float spread_m = 0.5f * static_cast<float>(options.truncation_m) + lowest_z * 4.0f / camera.fx;
  const float slack_band = band.At(lowest_z - band.At(lowest_z) - spread_m);
  int blocks = 0;
  volume.ForEachBlock([&](const VoxelBlock& block) {
    ++blocks;
    EXPECT_LE(block.min_band_m, band_far);
    EXPECT_GE(block.min_band_m, slack_band);
  });
  ASSERT_GT(blocks, 100);
  RecordProperty("band_far_m", std::to_string(band_far));
  RecordProperty("slack_band_m", std::to_string(slack_band));

  // From 1 m: the blocks around the plane's middle are seen again, with the fixed band.
  const core::Rigid3d near_pose{Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, 0, far_m - near_m)};
  volume.Integrate(test::RenderPlane(camera, near_pose, Eigen::Vector3d::UnitZ(), far_m), camera, near_pose);
  int narrowed = 0, kept = 0;
  volume.ForEachBlock([&](const VoxelBlock& block) {
    EXPECT_LE(block.min_band_m, band_far);
    if (block.min_band_m == static_cast<float>(options.truncation_m)) {
      ++narrowed;
    } else {
      ++kept;
    }
  });
  EXPECT_GT(narrowed, 20);
  EXPECT_GT(kept, 20);  // the outer blocks the near view does not reach

  // Carving through a point of the plane outside the near view (something left), from
  // 1.5 m: that block's bound falls to the band at 1.5 m (the fixed one).
  const Eigen::Vector3f point(1.2f, 0.9f, far_m);
  const VoxelBlock* carved = volume.FindBlock(
      BlockKey(FloorToInt(point.x() / block_m), FloorToInt(point.y() / block_m), FloorToInt(point.z() / block_m)));
  ASSERT_NE(carved, nullptr);
  ASSERT_GT(carved->min_band_m, band.At(1.5f));
  EXPECT_GT(volume.CarveFreeSpace({point}, Eigen::Vector3f(1.2f, 0.9f, far_m - 1.5f)), 0);
  EXPECT_EQ(carved->min_band_m, band.At(1.5f));
  // A block made by hand has no readings: unknown.
  EXPECT_EQ(volume.GetOrCreateBlock(BlockKey(500, 500, 500)).min_band_m, 0.0f);
}

TEST(TsdfIntegrate, FrontalPlaneIsExact) {
  const PinholeCamera camera = SmallCamera();
  TsdfVolume volume(SmallOptions());
  const core::Rigid3d pose = core::Rigid3d::Identity();
  const cv::Mat depth = test::RenderPlane(camera, pose, Eigen::Vector3d::UnitZ(), 1.0);
  const IntegrateStats stats = volume.Integrate(depth, camera, pose);
  EXPECT_EQ(stats.blocks_allocated, static_cast<int>(volume.NumBlocks()));
  EXPECT_EQ(stats.blocks_visible, stats.blocks_allocated);
  EXPECT_GT(stats.voxels_updated, 0);
  const float h = volume.voxel_size_m(), t = 0.03f;
  int checked = 0;
  int64_t observed = 0;
  volume.ForEachBlock([&](const VoxelBlock& block) {
    for (int i = 0; i < kBlockVoxels; ++i) {
      const Eigen::Vector3i v = block.key * kBlockSide + Eigen::Vector3i(i % 8, (i / 8) % 8, i / 64);
      const Eigen::Vector3f p = v.cast<float>() * h;
      const Voxel& voxel = block.voxels[i];
      observed += voxel.weight() > 0;
      int px, py;
      const bool in_view = camera.NearestPixel(camera.Project(p), px, py);
      if (!in_view || p.z() > 1.0f + t + 1e-4f) {
        EXPECT_EQ(voxel.weight(), 0) << p.transpose();
        EXPECT_EQ(voxel.sdf(), 1.0f) << p.transpose();  // made by the update's thread: the default
        continue;
      }
      if (p.z() > 1.0f + t - 1e-4f) continue;  // on the cut-off, either way
      ASSERT_EQ(voxel.weight(), 1) << p.transpose();
      EXPECT_NEAR(voxel.sdf(), std::min(1.0f, (1.0f - p.z()) / t), 0.5f * kSdfStep + 1e-5f) << p.transpose();
      ++checked;
    }
  });
  EXPECT_GT(checked, 10000);
  EXPECT_EQ(observed, stats.voxels_updated);
  // Blocks only around z = 1 m: the band [0.97, 1.03] lies in block layer 12 ([0.96, 1.04)).
  volume.ForEachBlock([&](const VoxelBlock& block) { EXPECT_EQ(block.key.z(), 12); });
  // The plane seen is 160/120 × 120/120 m: blocks of 8 cm over it, with the partly covered
  // ones at the rim: between the fully covered ones and those touching the footprint.
  const int inner = 16 * 12, outer = 18 * 14;
  EXPECT_GE(static_cast<int>(volume.NumBlocks()), inner);
  EXPECT_LE(static_cast<int>(volume.NumBlocks()), outer);
}

// Allocation samples the frame's pixels at a spacing of up to half a block at its farthest
// depth: a surface patch half a block wide is fused wherever it lies against the pixel grid
// (the only valid depth of the frame: a 4 cm square 1 m away, 4.8 px of this camera, where
// the samples are 4 px apart), and a narrower one may fall between the samples.
TEST(TsdfIntegrate, PatchesHalfABlockWideAreAlwaysAllocated) {
  const PinholeCamera camera = SmallCamera();
  const core::Rigid3d pose = core::Rigid3d::Identity();
  const auto fused_voxels = [&](double side_m, double u, double v) {
    cv::Mat depth(camera.height, camera.width, CV_32FC1, cv::Scalar(0));
    const double fx = camera.fx, fy = camera.fy, cx = camera.cx, cy = camera.cy;
    const double x0 = (u - cx) / fx, y0 = (v - cy) / fy;  // the centre's ray at z = 1 m
    for (int y = 0; y < camera.height; ++y) {
      for (int x = 0; x < camera.width; ++x) {
        const double px = (x - cx) / fx, py = (y - cy) / fy;
        if (std::abs(px - x0) <= 0.5 * side_m && std::abs(py - y0) <= 0.5 * side_m) depth.at<float>(y, x) = 1.0f;
      }
    }
    TsdfVolume volume(SmallOptions());
    return volume.Integrate(depth, camera, pose).voxels_updated;
  };
  const double half_block_m = 0.5 * kBlockSide * SmallOptions().voxel_size_m;
  int missed_narrow = 0;
  for (int dy = 0; dy < 8; ++dy) {
    for (int dx = 0; dx < 8; ++dx) {
      const double u = 70 + dx + 0.25, v = 50 + dy + 0.25;
      EXPECT_GT(fused_voxels(half_block_m, u, v), 0) << "patch at " << u << ", " << v;
      missed_narrow += fused_voxels(0.3 * half_block_m, u, v) == 0;
    }
  }
  // 1.4 px wide: the samples, 4 px apart, miss it somewhere.
  EXPECT_GT(missed_narrow, 0);
}

TEST(TsdfIntegrate, WeightsCountFramesAndCap) {
  const PinholeCamera camera = SmallCamera();
  const core::Rigid3d pose = core::Rigid3d::Identity();
  const cv::Mat depth = test::RenderPlane(camera, pose, Eigen::Vector3d::UnitZ(), 1.0);
  TsdfOptions options = SmallOptions();
  TsdfVolume volume(options);
  options.max_weight = 2;
  TsdfVolume capped(options);
  for (int frame = 0; frame < 3; ++frame) {
    const IntegrateStats stats = volume.Integrate(depth, camera, pose);
    EXPECT_EQ(stats.blocks_allocated, frame == 0 ? static_cast<int>(volume.NumBlocks()) : 0);
    EXPECT_EQ(stats.blocks_visible, static_cast<int>(volume.NumBlocks()));
    capped.Integrate(depth, camera, pose);
  }
  // 1 cm in front of the plane. Tolerances: the voxel's z is 99 · 0.01f in float, and 1 − z
  // loses 5 digits to cancellation (1e-5); each update rounds the mean to a storage step, and
  // an earlier rounding shrinks by w / (w + 1) per update: within 1 step after any number.
  const Eigen::Vector3i v(0, 0, 99);
  ASSERT_NE(volume.FindVoxel(v), nullptr);
  EXPECT_EQ(volume.FindVoxel(v)->weight(), 3);
  EXPECT_NEAR(volume.FindVoxel(v)->sdf(), 1.0f / 3, kSdfStep + 1e-5f);
  EXPECT_EQ(capped.FindVoxel(v)->weight(), 2);
  EXPECT_NEAR(capped.FindVoxel(v)->sdf(), 1.0f / 3, kSdfStep + 1e-5f);
  // A moved plane: the capped volume follows it faster (it weighs the old one 2:1, not 3:1).
  const cv::Mat nearer = test::RenderPlane(camera, pose, Eigen::Vector3d::UnitZ(), 0.995);
  volume.Integrate(nearer, camera, pose);
  capped.Integrate(nearer, camera, pose);
  const float new_sdf = (0.995f - 0.99f) / 0.03f;
  EXPECT_NEAR(volume.FindVoxel(v)->sdf(), (3 * (1.0f / 3) + new_sdf) / 4, kSdfStep + 1e-5f);
  EXPECT_NEAR(capped.FindVoxel(v)->sdf(), (2 * (1.0f / 3) + new_sdf) / 3, kSdfStep + 1e-5f);
}

TEST(TsdfIntegrate, SameResultOnAnyThreadCount) {
  const PinholeCamera camera = SmallCamera();
  const core::Rigid3d pose = test::LookAt({0.1, -0.2, 0}, {0, 0, 1.2});
  const cv::Mat depth = test::RenderSphere(camera, pose, {0, 0, 1.2}, 0.3);
  TsdfVolume one(SmallOptions(1)), three(SmallOptions(3));
  one.Integrate(depth, camera, pose);
  three.Integrate(depth, camera, pose);
  ASSERT_EQ(one.NumBlocks(), three.NumBlocks());
  one.ForEachBlock([&](const VoxelBlock& block) {
    const VoxelBlock* other = three.FindBlock(block.key);
    ASSERT_NE(other, nullptr);
    for (int i = 0; i < kBlockVoxels; ++i) {
      EXPECT_EQ(block.voxels[i].sdf(), other->voxels[i].sdf());
      EXPECT_EQ(block.voxels[i].weight(), other->voxels[i].weight());
    }
  });
}

// A sphere: the projective distance d(pixel) − z is not the Euclidean distance δ to the
// sphere. Along the viewing ray, the surface lies at distance δ / cos θ (θ between the ray and
// the normal) to first order, plus a curvature term of order δ² / R; bilinear depth adds
// the error of interpolating the depth between pixel centres (second order: depth slope
// change over a pixel, below 0.2 mm here away from the rim). The stored value must lie within
// that bound of the truth — and carry its sign.
TEST(TsdfIntegrate, SphereDistanceBiasIsBounded) {
  const PinholeCamera camera = SmallCamera();
  const core::Rigid3d pose = core::Rigid3d::Identity();
  const Eigen::Vector3d centre(0.05, 0, 1.0);
  const double radius = 0.3;
  const cv::Mat depth = test::RenderSphere(camera, pose, centre, radius);
  TsdfVolume volume(SmallOptions());
  volume.Integrate(depth, camera, pose);
  const double h = volume.options().voxel_size_m, t = volume.options().truncation_m;
  int checked = 0;
  double worst = 0;
  volume.ForEachBlock([&](const VoxelBlock& block) {
    for (int i = 0; i < kBlockVoxels; ++i) {
      const Voxel& voxel = block.voxels[i];
      if (voxel.weight() == 0) continue;
      const Eigen::Vector3i v = block.key * kBlockSide + Eigen::Vector3i(i % 8, (i / 8) % 8, i / 64);
      const Eigen::Vector3d p = v.cast<double>() * h;
      const double delta = (p - centre).norm() - radius;  // true signed distance
      const Eigen::Vector3d normal = (p - centre).normalized();
      const double cos_theta = std::abs(normal.dot(p.normalized()));
      if (cos_theta < 0.7 || std::abs(delta) > 0.6 * t) continue;  // rim; saturated band
      const double stored = static_cast<double>(voxel.sdf()) * t;
      const double bound = std::abs(delta) * (1 / cos_theta - 1) + 2 * delta * delta / radius + 2e-4;
      EXPECT_NEAR(stored, delta, bound) << p.transpose();
      if (std::abs(delta) > 2e-4) {
        EXPECT_EQ(stored > 0, delta > 0) << p.transpose();
      }
      worst = std::max(worst, std::abs(stored - delta));
      ++checked;
    }
  });
  EXPECT_GT(checked, 3000);
  RecordProperty("worst_error_m", std::to_string(worst));
  // Blocks only near the surface: the band (2 · truncation, 6 cm) over the visible cap
  // (at most a hemisphere, 2πR² = 0.57 m²) is at most 0.034 m³; whole blocks
  // (0.08³ m³ = 5.1e-4 m³) around it: a band widened by a block diagonal each side.
  const double band_blocks = 2 * M_PI * radius * radius * (2 * t + 2 * 0.08 * std::sqrt(3.0)) / std::pow(0.08, 3);
  EXPECT_LE(static_cast<double>(volume.NumBlocks()), band_blocks);
  // ... and at least the blocks of one layer under the sphere's disc (πR² / 0.08²).
  EXPECT_GE(static_cast<double>(volume.NumBlocks()), M_PI * radius * radius / std::pow(0.08, 2));
  Eigen::Vector3f lo, hi;
  volume.Bounds(lo, hi);
  EXPECT_GE(static_cast<double>(lo.z()), 1.0 - radius - t - 0.08 - 1e-4);  // a block of slack
  EXPECT_LE(static_cast<double>(hi.z()), 1.0 + t + 0.08);                 // nothing past the rim's band
}

TEST(TsdfIntegrate, UniformColour) {
  const PinholeCamera camera = SmallCamera();
  const core::Rigid3d pose = core::Rigid3d::Identity();
  const cv::Mat depth = test::RenderPlane(camera, pose, Eigen::Vector3d::UnitZ(), 1.0);
  ColourView colour;
  colour.rgb = cv::Mat(camera.height, camera.width, CV_8UC3, cv::Scalar(200, 100, 50));
  colour.camera = camera;
  // A colour camera 3 cm to the side, as on a rig: the plane is uniform, so it sees the same.
  colour.world_from_camera = core::Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.03, 0, 0));
  TsdfVolume volume(SmallOptions());
  volume.Integrate(depth, camera, pose, &colour);
  volume.Integrate(depth, camera, pose, &colour);
  const Voxel* in_band = volume.FindVoxel({0, 0, 98});
  ASSERT_NE(in_band, nullptr);
  EXPECT_EQ(in_band->colour, Rgb8(200, 100, 50));
  EXPECT_EQ(in_band->colour_weight, 2);
  const Voxel* in_front = volume.FindVoxel({0, 0, 96});  // 4 cm in front: outside the band
  ASSERT_NE(in_front, nullptr);
  EXPECT_EQ(in_front->weight(), 2);
  EXPECT_EQ(in_front->colour_weight, 0);
  const auto at_surface = volume.ColourAt(Eigen::Vector3f(0.004f, 0.002f, 1.0f));
  ASSERT_TRUE(at_surface.has_value());
  EXPECT_EQ(*at_surface, Rgb8(200, 100, 50));
}

// The colour camera 5 cm to the right of the depth camera (x): its image is red left of
// column 79.5 and blue right of it, so on the plane z = 1 m the boundary lies at
// x = 0.05 + (79.5 − cx) / fx = 0.05 m in the world. A transform taken the wrong way round
// would put it at −0.05 m.
TEST(TsdfIntegrate, ColourGoesThroughTheColourCameraPose) {
  const PinholeCamera camera = SmallCamera();
  const core::Rigid3d pose = core::Rigid3d::Identity();
  const cv::Mat depth = test::RenderPlane(camera, pose, Eigen::Vector3d::UnitZ(), 1.0);
  ColourView colour;
  colour.rgb = cv::Mat(camera.height, camera.width, CV_8UC3, cv::Scalar(255, 0, 0));
  colour.rgb.colRange(80, camera.width).setTo(cv::Scalar(0, 0, 255));
  colour.camera = camera;
  colour.world_from_camera = core::Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.05, 0, 0));
  TsdfVolume volume(SmallOptions());
  volume.Integrate(depth, camera, pose, &colour);
  for (const float x : {-0.3f, 0.0f, 0.03f}) {
    const auto c = volume.ColourAt(Eigen::Vector3f(x, 0.0f, 1.0f));
    ASSERT_TRUE(c.has_value());
    EXPECT_EQ(*c, Rgb8(255, 0, 0)) << x;
  }
  for (const float x : {0.07f, 0.3f}) {
    const auto c = volume.ColourAt(Eigen::Vector3f(x, 0.0f, 1.0f));
    ASSERT_TRUE(c.has_value());
    EXPECT_EQ(*c, Rgb8(0, 0, 255)) << x;
  }
}

TEST(TsdfIntegrate, SimdKernelWritesTheScalarBits) {
  if (!test::CpuRunsTheSimdKernel()) GTEST_SKIP() << "no AVX2 kernel here: only the scalar one runs";
  test::ExpectSimdWritesTheScalarBits(SmallOptions(2));  // surfaces at 1-1.3 m: the fixed 3 cm band
}

// The band from the depth noise, varying from voxel to voxel: a noise model steep enough
// that 3σ is 5.8 cm at 1 m and 10 cm at 1.2 m.
TEST(TsdfIntegrate, SimdKernelWritesTheScalarBitsWithTheNoiseBand) {
  if (!test::CpuRunsTheSimdKernel()) GTEST_SKIP() << "no AVX2 kernel here: only the scalar one runs";
  TsdfOptions options = SmallOptions(2);
  options.noise.quadratic_per_m = 0.05;
  ASSERT_GT(options.TruncationAt(1.0f), 0.05f);
  test::ExpectSimdWritesTheScalarBits(options);
}

// ... and with a rolling-shutter colour camera (a pose per band of rows, gathered per lane).
TEST(TsdfIntegrate, SimdKernelWritesTheScalarBitsWithARollingShutter) {
  if (!test::CpuRunsTheSimdKernel()) GTEST_SKIP() << "no AVX2 kernel here: only the scalar one runs";
  test::ExpectSimdWritesTheScalarBits(SmallOptions(2), 16);
  // Rows of 8 voxels mostly within one band (their pose broadcast) and mostly across
  // several (gathered per lane): 55 and 1.7 image rows per band.
  test::ExpectSimdWritesTheScalarBits(SmallOptions(2), 2);
  test::ExpectSimdWritesTheScalarBits(SmallOptions(2), 64);
}

// A rolling-shutter colour camera moving sideways during its readout: band k of its 4 bands
// of rows (30 rows each) was exposed at x_k = 0.02 + 0.02 k m, the middle row at 0.05 m.
// Each row of its image shows the wall z = 1 m red left of x = 0.05 m and blue right of it,
// so the boundary lies at column 79.5 + 120 (0.05 − x_k) of band k. Projected with each
// band's pose the boundary lands at x = 0.05 m on every row; with the middle row's pose
// alone it would land at 0.08 m in the top band and 0.02 m in the bottom one.
TEST(TsdfIntegrate, RollingShutterColourIsProjectedWithThePoseOfItsRows) {
  const PinholeCamera camera = SmallCamera();
  const core::Rigid3d pose = core::Rigid3d::Identity();
  const cv::Mat depth = test::RenderPlane(camera, pose, Eigen::Vector3d::UnitZ(), 1.0);
  ColourView colour;
  colour.camera = camera;
  colour.rgb = cv::Mat(camera.height, camera.width, CV_8UC3, cv::Scalar(255, 0, 0));
  colour.world_from_camera = core::Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.05, 0, 0));
  for (int k = 0; k < 4; ++k) {
    const double x_k = 0.02 + 0.02 * k;
    colour.world_from_camera_bands.emplace_back(Eigen::Quaterniond::Identity(), Eigen::Vector3d(x_k, 0, 0));
    const double boundary = 79.5 + 120 * (0.05 - x_k);
    for (int v = 30 * k; v < 30 * (k + 1); ++v) {
      for (int u = 0; u < camera.width; ++u) {
        if (u > boundary) colour.rgb.at<cv::Vec3b>(v, u) = cv::Vec3b(0, 0, 255);
      }
    }
  }
  const auto colour_at = [](const TsdfVolume& volume, float x, float y) {
    const auto c = volume.ColourAt(Eigen::Vector3f(x, y, 1.0f));
    return c.has_value() ? *c : Rgb8(1, 2, 3);
  };
  TsdfVolume rolling(SmallOptions());
  rolling.Integrate(depth, camera, pose, &colour);
  // Rows 12 and 108 (y = ∓0.4 m): bands 0 and 3.
  for (const float y : {-0.4f, 0.4f}) {
    EXPECT_EQ(colour_at(rolling, 0.035f, y), Rgb8(255, 0, 0)) << y;
    EXPECT_EQ(colour_at(rolling, 0.065f, y), Rgb8(0, 0, 255)) << y;
  }
  colour.world_from_camera_bands.clear();
  TsdfVolume global(SmallOptions());
  global.Integrate(depth, camera, pose, &colour);
  EXPECT_EQ(colour_at(global, 0.065f, -0.4f), Rgb8(255, 0, 0));  // boundary at 0.08 m there
  EXPECT_EQ(colour_at(global, 0.035f, 0.4f), Rgb8(0, 0, 255));   // at 0.02 m there
}

TEST(TsdfIntegrate, NothingToFuse) {
  const PinholeCamera camera = SmallCamera();
  TsdfVolume volume(SmallOptions());
  cv::Mat zeros(camera.height, camera.width, CV_32FC1, cv::Scalar(0));
  IntegrateStats stats = volume.Integrate(zeros, camera, core::Rigid3d::Identity());
  EXPECT_EQ(stats.blocks_allocated, 0);
  EXPECT_EQ(stats.blocks_visible, 0);
  EXPECT_EQ(stats.voxels_updated, 0);
  cv::Mat nan(camera.height, camera.width, CV_32FC1, cv::Scalar(std::nan("")));
  stats = volume.Integrate(nan, camera, core::Rigid3d::Identity());
  EXPECT_EQ(stats.blocks_allocated, 0);
  // Beyond max_depth_m (4 m) or nearer than min_depth_m (0.3 m): not fused.
  cv::Mat far(camera.height, camera.width, CV_32FC1, cv::Scalar(4.5));
  cv::Mat near(camera.height, camera.width, CV_32FC1, cv::Scalar(0.2));
  volume.Integrate(far, camera, core::Rigid3d::Identity());
  volume.Integrate(near, camera, core::Rigid3d::Identity());
  EXPECT_EQ(volume.NumBlocks(), 0u);
}

}  // namespace
}  // namespace hw::reconstruct
