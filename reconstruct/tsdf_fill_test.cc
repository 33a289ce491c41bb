#include "reconstruct/tsdf_fill.h"

#include <cstring>
#include <limits>
#include <random>

#include <gtest/gtest.h>

#include "reconstruct/tsdf_test_support.h"
#include "reconstruct/tsdf_volume_impl.h"

namespace hw::reconstruct {
namespace {

constexpr float kSdfStep = 1.0f / Voxel::kSdfUnit;  // one storage step of sdf

Voxel& At(VoxelBlock& b, int x, int y, int z) { return b.voxels[x + kBlockSide * (y + kBlockSide * z)]; }

// ---------------------------------------------------------------- the fill alone

// A linear field on the even voxels comes back on every odd one: the means are exact, and so
// is the extrapolation at index 7 (1.5·v6 − 0.5·v4) — to the storage step, where a value
// is clamped to ±1 it stays clamped.
TEST(TsdfFill, ALinearFieldIsInterpolatedAndExtrapolatedExactly) {
  VoxelBlock block{};
  const auto field = [](int x, int y, int z) { return -0.4f + 0.031f * x - 0.017f * y + 0.05f * z; };
  for (int z = 0; z < kBlockSide; z += 2) {
    for (int y = 0; y < kBlockSide; y += 2) {
      for (int x = 0; x < kBlockSide; x += 2) {
        Voxel& v = At(block, x, y, z);
        v.set_sdf(field(x, y, z));
        v.set_weight(5 + x + y + z);
        v.colour = Rgb8(static_cast<std::uint8_t>(25 * (x / 2)), 100, static_cast<std::uint8_t>(200 - 10 * z));
        v.colour_weight = 7;
      }
    }
  }
  internal::FillOddVoxels(block.voxels.data());
  // The even neighbour whose weight an odd voxel takes along one axis (the smaller: the lower
  // one; at index 7, 1.5·v6 − 0.5·v4, index 4).
  const auto lower = [](int k) { return k % 2 == 0 ? k : (k == kBlockSide - 1 ? k - 3 : k - 1); };
  for (int z = 0; z < kBlockSide; ++z) {
    for (int y = 0; y < kBlockSide; ++y) {
      for (int x = 0; x < kBlockSide; ++x) {
        const Voxel& v = At(block, x, y, z);
        ASSERT_TRUE(v.observed()) << x << " " << y << " " << z;
        // The field's values are stored to half a step; each stage that fills along an axis
        // keeps its sources' error (a mean) or doubles it (1.5 + 0.5 at index 7) and rounds
        // once more: up to 7.5 steps at (7, 7, 7). The operations themselves are exact.
        float bound = 0.5f;
        for (const int k : {x, y, z}) {
          if (k % 2 == 1) bound = (k == kBlockSide - 1 ? 2.0f : 1.0f) * bound + 0.5f;
        }
        EXPECT_NEAR(v.sdf(), field(x, y, z), bound * kSdfStep) << x << " " << y << " " << z;
        EXPECT_EQ(v.weight_count, 5 + lower(x) + lower(y) + lower(z)) << x << " " << y << " " << z;
        EXPECT_EQ(v.colour[1], 100);
        EXPECT_EQ(v.colour_weight, 7);
      }
    }
  }
  // Means rounded up: red between 0 and 25 is 13; at index 7 a face copies index 6.
  EXPECT_EQ(At(block, 1, 0, 0).colour[0], 13);
  EXPECT_EQ(At(block, 7, 0, 0).colour[0], 75);
  EXPECT_EQ(At(block, 0, 0, 1).colour[2], 190);
  EXPECT_EQ(At(block, 0, 0, 7).colour[2], 140);
}

TEST(TsdfFill, ClampsToTheBand) {
  VoxelBlock block{};
  for (int x = 0; x < kBlockSide; x += 2) {
    At(block, x, 0, 0).set_sdf(x <= 4 ? 0.2f * static_cast<float>(x) : 1.0f);
    At(block, x, 0, 0).set_weight(1);
  }
  internal::FillOddVoxels(block.voxels.data());
  EXPECT_NEAR(At(block, 3, 0, 0).sdf(), 0.6f, kSdfStep);
  EXPECT_NEAR(At(block, 5, 0, 0).sdf(), 0.9f, kSdfStep);
  EXPECT_EQ(At(block, 7, 0, 0).sdf(), 1.0f);  // 1.5 · 1 − 0.5 · 0.8 = 1.1, clamped
}

// Where one neighbour is unobserved the odd voxel copies the other; where both are, it is
// left as it was. Colour follows the colour weights, not the distance's.
TEST(TsdfFill, UnobservedNeighboursAreNotAveraged) {
  VoxelBlock block{};
  Voxel seen;
  seen.set_sdf(0.25f);
  seen.set_weight(3);
  seen.colour = Rgb8(9, 8, 7);
  seen.colour_weight = 2;
  Voxel unpainted = seen;
  unpainted.colour = Rgb8(0, 0, 0);
  unpainted.colour_weight = 0;
  Voxel kept;  // unobserved, with a distance of its own
  kept.set_sdf(-0.5f);
  kept.colour = Rgb8(1, 2, 3);
  At(block, 0, 0, 0) = seen;       // voxel 1: between seen and unobserved (2)
  At(block, 4, 0, 0) = unpainted;  // voxel 3: between unobserved and unpainted
  At(block, 6, 0, 0) = seen;       // voxel 5: between unpainted and seen
  At(block, 1, 0, 2) = kept;       // between two unobserved voxels
  internal::FillOddVoxels(block.voxels.data());
  EXPECT_EQ(std::memcmp(&At(block, 1, 0, 0), &seen, sizeof(Voxel)), 0);
  EXPECT_EQ(At(block, 3, 0, 0).sdf(), 0.25f);
  EXPECT_EQ(At(block, 3, 0, 0).weight_count, 3);
  EXPECT_EQ(At(block, 3, 0, 0).colour_weight, 0);
  EXPECT_EQ(At(block, 5, 0, 0).sdf(), 0.25f);
  EXPECT_EQ(At(block, 5, 0, 0).colour, seen.colour);  // painted from 6 alone
  EXPECT_EQ(At(block, 5, 0, 0).colour_weight, 2);
  EXPECT_EQ(std::memcmp(&At(block, 1, 0, 2), &kept, sizeof(Voxel)), 0);
  // Row y = 1 copies row 0 where it is observed (row 2 is not).
  EXPECT_EQ(std::memcmp(&At(block, 5, 1, 0), &At(block, 5, 0, 0), sizeof(Voxel)), 0);
}

// The AVX2 fill writes the scalar one's bits, on blocks of random bytes (any distance,
// weight, colour; about a third of the voxels unobserved or unpainted).
TEST(TsdfFill, SimdFillWritesTheScalarBits) {
  if (!test::CpuRunsTheSimdKernel()) GTEST_SKIP() << "no AVX2 on this CPU";
  std::mt19937 random(3);
  std::uniform_int_distribution<int> steps(-16384, 16384), weight(0, 2), count(1, 64), byte(0, 255);
  for (int trial = 0; trial < 200; ++trial) {
    VoxelBlock a{};
    for (Voxel& v : a.voxels) {
      v.sdf_steps = static_cast<std::int16_t>(steps(random));
      v.weight_count = static_cast<std::uint16_t>(weight(random) == 0 ? 0 : count(random));
      v.colour = Rgb8(static_cast<std::uint8_t>(byte(random)), static_cast<std::uint8_t>(byte(random)),
                      static_cast<std::uint8_t>(byte(random)));
      v.colour_weight = static_cast<std::uint8_t>(weight(random) == 0 ? 0 : count(random));
    }
    VoxelBlock b = a;
    internal::FillOddVoxels(a.voxels.data());
    internal::FillOddVoxelsScalar(b.voxels.data());
    ASSERT_EQ(std::memcmp(a.voxels.data(), b.voxels.data(), sizeof(a.voxels)), 0) << "trial " << trial;
  }
}

// ---------------------------------------------------------------- integration

TEST(TsdfCoarse, BeyondWhereNoiseAndPixelsOutgrowAVoxel) {
  TsdfOptions options;  // 5 mm voxels, the Kinect noise model
  // σ_z = 1 cm at 0.4 + sqrt(0.0088 / 0.0019) = 2.552 m; a 525 px pixel is 5 mm at 2.625 m.
  EXPECT_NEAR(options.CoarseBeyondM(525), 2.625, 1e-12);
  EXPECT_NEAR(options.CoarseBeyondM(120), 0.4 + std::sqrt(0.0088 / 0.0019), 1e-12);
  options.voxel_size_m = 0.01;  // 1 cm: the pixel criterion, 5.25 m, beyond the range
  EXPECT_NEAR(options.CoarseBeyondM(525), 5.25, 1e-12);
  options.noise.quadratic_per_m = 0;  // noise that never reaches 2 cm: never
  EXPECT_EQ(options.CoarseBeyondM(525), std::numeric_limits<double>::infinity());
  options = TsdfOptions();
  options.coarse_far = false;
  EXPECT_EQ(options.CoarseBeyondM(525), std::numeric_limits<double>::infinity());
}

// A slanted wall at 3.3–3.8 m, fused coarsely and voxel by voxel: the field of one plane is
// linear to within the perspective's curvature over two voxels, so the interpolated voxels
// hold what their own update would have written.
TEST(TsdfCoarse, AFarPlaneComesOutAsFromEveryVoxel) {
  const PinholeCamera camera{640, 480, 525.0f, 525.0f, 319.5f, 239.5f};
  const core::Rigid3d pose = test::LookAt({0.1, -0.2, 0.0}, {0.3, 0.1, 3.5});
  const cv::Mat depth = test::RenderPlane(camera, pose, Eigen::Vector3d(0.3, 0.1, 1.0), 3.6);
  TsdfOptions fine_options, coarse_options;
  fine_options.coarse_far = false;
  fine_options.max_depth_m = coarse_options.max_depth_m = 5;
  TsdfVolume fine(fine_options), coarse(coarse_options);
  const IntegrateStats f = fine.Integrate(depth, camera, pose);
  const IntegrateStats c = coarse.Integrate(depth, camera, pose);
  EXPECT_EQ(f.blocks_coarse, 0);
  EXPECT_EQ(c.blocks_coarse, c.blocks_visible);  // all beyond 2.63 m
  EXPECT_EQ(f.blocks_visible, c.blocks_visible);
  EXPECT_LT(c.voxels_updated, f.voxels_updated / 6);  // an eighth of the voxels, give or take the band's edges
  const core::Rigid3d camera_from_world = pose.Inverse();
  int64_t compared = 0, edge = 0, missing = 0;
  float worst = 0, worst_edge = 0;
  fine.ForEachBlock([&](const VoxelBlock& block) {
    const VoxelBlock* other = coarse.FindBlock(block.key);
    ASSERT_NE(other, nullptr);
    for (int i = 0; i < kBlockVoxels; ++i) {
      const Voxel &a = block.voxels[i], &b = other->voxels[i];
      // Away from the band's clipped ends: a voxel at a block's last index along each axis
      // is extrapolated from voxels up to three away along each (here the field changes by
      // up to 0.085 of the band per voxel along one axis, 0.03 along the others: 0.43).
      if (!a.observed() || std::abs(a.sdf()) > 0.5f) continue;
      // Within 6 pixels of the image's edges (an extrapolation's three voxels and one more at
      // 3.3 m) a voxel may have even neighbours outside the view: it copies the one inside,
      // or keeps what it had.
      const Eigen::Vector3d centre =
          (block.key * kBlockSide + Eigen::Vector3i(i % kBlockSide, i / kBlockSide % kBlockSide, i / (kBlockSide * kBlockSide)))
              .cast<double>() * fine_options.voxel_size_m;
      const Eigen::Vector3d p = camera_from_world * centre;
      const double u = double{camera.fx} * p.x() / p.z() + double{camera.cx};
      const double v = double{camera.fy} * p.y() / p.z() + double{camera.cy};
      if (u < 6 || v < 6 || u > camera.width - 7 || v > camera.height - 7) {
        ++edge;
        if (!b.observed()) ++missing;
        else worst_edge = std::max(worst_edge, std::abs(a.sdf() - b.sdf()));
        continue;
      }
      ASSERT_TRUE(b.observed());
      worst = std::max(worst, std::abs(a.sdf() - b.sdf()));
      ++compared;
    }
  });
  EXPECT_GT(compared, 1000000);
  std::printf("interior %lld voxels, worst %.2g of the band; edge %lld, %lld unobserved, worst %.2g\n",
              static_cast<long long>(compared), double{worst}, static_cast<long long>(edge),
              static_cast<long long>(missing), double{worst_edge});
  // At the edge: at most the field across one coarse voxel (2 · 0.086 of the band here).
  EXPECT_LT(worst_edge, 0.2f);
  // The band of a voxel's reading is the nearest pixel's: piecewise constant, 0.3 % wider
  // from one pixel to the next down this slant (6 mm deeper), so half a band from the surface
  // a voxel's own value steps by 1.5e-3 of the band where the interpolated one does not.
  // Measured: 2.0e-3 (0.12 mm of the 5.8 cm band); bound 3e-3.
  EXPECT_LT(worst, 3e-3f);
}

// A block turns fine for good on its first update from nearer than CoarseBeyondM, from the
// interpolated values it had.
TEST(TsdfCoarse, ABlockSeenNearStaysFine) {
  const PinholeCamera camera{640, 480, 525.0f, 525.0f, 319.5f, 239.5f};
  TsdfOptions options, fine_options;
  options.max_depth_m = fine_options.max_depth_m = 5;
  fine_options.coarse_far = false;
  TsdfVolume volume(options), fine(fine_options);
  const Eigen::Vector3d normal(0, 0, 1);
  const core::Rigid3d far = core::Rigid3d::Identity();
  const core::Rigid3d near(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.0, 0.0, 2.0));
  std::vector<IntegrateStats> stats, fine_stats;
  for (const core::Rigid3d* pose : {&far, &near, &far}) {
    const cv::Mat depth = test::RenderPlane(camera, *pose, normal, 3.5);
    stats.push_back(volume.Integrate(depth, camera, *pose));
    fine_stats.push_back(fine.Integrate(depth, camera, *pose));
  }
  EXPECT_EQ(stats[0].blocks_coarse, stats[0].blocks_visible);
  // Seen from 1.5 m: every block fine, every voxel updated as without coarse blocks.
  EXPECT_EQ(stats[1].blocks_coarse, 0);
  EXPECT_EQ(stats[1].voxels_updated, fine_stats[1].voxels_updated);
  int near_blocks = 0;
  volume.ForEachBlock([&](const VoxelBlock& block) { near_blocks += block.seen_near; });
  EXPECT_EQ(near_blocks, stats[1].blocks_visible);
  // From 3.5 m again: the near view's blocks (all in this view) stay fine.
  EXPECT_EQ(stats[2].blocks_coarse, stats[2].blocks_visible - near_blocks);
  EXPECT_GT(stats[2].blocks_coarse, 0);
  EXPECT_LT(stats[2].voxels_updated, fine_stats[2].voxels_updated);
}

// The coarse update and the fill with the AVX2 kernel and the scalar one: the same bits. A
// far noisy wall (3.3–3.8 m) with holes and NaN behind a sphere at 1.2–1.5 m (its blocks
// fine), colour through a rolling shutter, a weight cap the voxels reach.
TEST(TsdfCoarse, SimdWritesTheScalarBits) {
  if (!test::CpuRunsTheSimdKernel()) GTEST_SKIP() << "no AVX2 on this CPU";
  TsdfOptions options;  // 5 mm voxels: coarse beyond 2.55 m at 120 px
  options.max_depth_m = 5;
  const test::SimdTotals totals = test::ExpectSimdWritesTheScalarBits(
      options, 8, {.target_z = 3.5, .wall_offset = 3.6, .sphere_z = 1.5, .sphere_radius = 0.3, .noise_m = 0.02f, .seed = 11});
  EXPECT_GT(totals.coarse_blocks, 1000);
  EXPECT_GT(totals.fine_blocks, 1000);
}

}  // namespace
}  // namespace hw::reconstruct
