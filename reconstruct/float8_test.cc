#include "reconstruct/float8.h"

#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

#include <gtest/gtest.h>

namespace hw::reconstruct::internal {
namespace {

// This file is compiled for the baseline target (no AVX): the helpers run here as the
// pipeline's default clones run them (two SSE halves), while the suite's other tests run
// the AVX2 clones on an AVX2 machine. Every helper must give the per-lane result.

uint32_t Bits(float f) {
  uint32_t u;
  std::memcpy(&u, &f, sizeof(u));
  return u;
}

TEST(Float8, TriplesLoadAsComponentsAndStoreBack) {
  std::mt19937 rng(1);
  std::uniform_real_distribution<float> value(-10.0f, 10.0f);
  for (int trial = 0; trial < 50; ++trial) {
    float xyz[24];
    for (float& f : xyz) f = value(rng);
    xyz[trial % 24] = std::numeric_limits<float>::quiet_NaN();  // NaN moves like any value
    Float8 c[3];
    LoadTriples8(xyz, c);
    for (int lane = 0; lane < 8; ++lane) {
      for (int k = 0; k < 3; ++k) {
        ASSERT_EQ(Bits(c[k][lane]), Bits(xyz[3 * lane + k])) << "lane " << lane << " component " << k;
      }
    }
    float back[24];
    StoreTriples8(c, back);
    ASSERT_EQ(std::memcmp(back, xyz, sizeof(xyz)), 0) << "trial " << trial;
  }
}

TEST(Float8, GatherReadsEachLanesOffset) {
  std::vector<float> base(1000);
  for (size_t i = 0; i < base.size(); ++i) base[i] = 0.5f * static_cast<float>(i) - 3.0f;
  const Int8 offset = {999, 0, 17, 17, 500, 3, 998, 1};
  const Float8 g = Gather8(base.data(), offset);
  for (int lane = 0; lane < 8; ++lane) EXPECT_EQ(g[lane], base[offset[lane]]);
}

TEST(Float8, SqrtIsCorrectlyRoundedLikeStdSqrt) {
  std::mt19937 rng(2);
  std::uniform_real_distribution<float> value(0.0f, 1e6f);
  const float specials[] = {0.0f, -0.0f, std::numeric_limits<float>::denorm_min(), 1e-30f, 2.0f,
                            std::numeric_limits<float>::infinity(), -1.0f, std::numeric_limits<float>::quiet_NaN()};
  for (int trial = 0; trial < 200; ++trial) {
    Float8 v;
    for (int lane = 0; lane < 8; ++lane) v[lane] = trial == 0 ? specials[lane] : value(rng);
    const Float8 r = Sqrt8(v);
    for (int lane = 0; lane < 8; ++lane) {
      const float expected = std::sqrt(v[lane]);
      if (std::isnan(expected)) {
        EXPECT_TRUE(std::isnan(r[lane])) << v[lane];
      } else {
        ASSERT_EQ(Bits(r[lane]), Bits(expected)) << v[lane];
      }
    }
  }
}

TEST(Float8, MasksSelectsAndFloors) {
  const Float8 v = {-2.5f, -0.0f, 0.0f, 0.25f, 1.0f, -1.0f, 3.75f, -1e-7f};
  const Int8 mask = {-1, 0, -1, 0, -1, 0, -1, 0};
  const Float8 masked = Masked8(v, mask), selected = Select8(mask, v, Splat8(9.0f));
  const Float8 abs = Abs8(v), max = Max8(v, Splat8(0.5f));
  const Int8 floor = Floor8(v);
  for (int lane = 0; lane < 8; ++lane) {
    const bool on = mask[lane] != 0;
    EXPECT_EQ(Bits(masked[lane]), on ? Bits(v[lane]) : Bits(0.0f)) << lane;
    EXPECT_EQ(selected[lane], on ? v[lane] : 9.0f) << lane;
    EXPECT_EQ(Bits(abs[lane]), Bits(std::abs(v[lane]))) << lane;
    EXPECT_EQ(max[lane], v[lane] > 0.5f ? v[lane] : 0.5f) << lane;
    EXPECT_EQ(floor[lane], static_cast<int>(std::floor(v[lane]))) << lane;
  }
  float row[10];
  for (int i = 0; i < 10; ++i) row[i] = static_cast<float>(i);
  Store8(row + 1, Load8(row) * 2.0f);  // unaligned, overlapping: all loaded, then stored
  EXPECT_EQ(row[0], 0.0f);
  for (int i = 1; i < 9; ++i) EXPECT_EQ(row[i], 2.0f * static_cast<float>(i - 1));
  EXPECT_EQ(row[9], 9.0f);
}

}  // namespace
}  // namespace hw::reconstruct::internal
