#include "reconstruct/emissivity_map.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "core/error.h"
#include "tests/support.h"

namespace hw::reconstruct {
namespace {

using core::EmissivityLaw;
using hw::test::LineOf;
using hw::test::Replace;
using ::testing::HasSubstr;
using Shape = EmissivityRegion::Shape;

const char* const kPath = "scan/emissivity.yaml";

// The README's example, plus a box turned 45° about z.
const std::string kFile = R"(version: 1
default: { emissivity: 0.9, law: dielectric, reflected_c: 21.0 }
regions:
  - name: motor-boss
    emissivity: 0.30
    law: metal
    reflected_c: 25.0
    box: { centre_m: [0.41, -0.12, 1.85], size_m: [0.2, 0.1, 0.1], q_xyzw: [0, 0, 0, 1] }
  - name: pipe-tape
    emissivity: 0.97
    sphere: { centre_m: [0.1, 0.2, 1.5], radius_m: 0.05 }
  - name: label
    emissivity: 0.85
    box: { centre_m: [1, 0, 2], size_m: [0.4, 0.1, 0.02],
           q_xyzw: [0, 0, 0.3826834323650898, 0.9238795325112867] }
)";

core::ThermalSettings RigThermal() {
  core::ThermalSettings thermal;
  thermal.emissivity = 0.93;
  thermal.reflected_c = 18.5;
  return thermal;
}

EmissivityMap ParseText(const std::string& text) {
  return EmissivityMap::Parse(text, kPath, RigThermal());
}

void ExpectSurface(const SurfaceEmissivity& s, double emissivity, EmissivityLaw law,
                   double reflected_c, int region) {
  EXPECT_EQ(s.emissivity, emissivity);
  EXPECT_EQ(s.law, law);
  EXPECT_EQ(s.reflected_c, reflected_c);
  EXPECT_EQ(s.region, region);
}

TEST(EmissivityMap, RigOnlyMapIsTheRigsThermalBlockEverywhere) {
  const EmissivityMap map(RigThermal());
  EXPECT_EQ(map.num_regions(), 0);
  ExpectSurface(map.At({0, 0, 0}), 0.93, EmissivityLaw::kDielectric, 18.5, -1);
  ExpectSurface(map.At({1e3f, -5, 2}), 0.93, EmissivityLaw::kDielectric, 18.5, -1);
}

TEST(EmissivityMap, ReadsTheFileAndLooksUpEachShape) {
  const std::filesystem::path path = hw::test::TestFolder() / "emissivity.yaml";
  std::ofstream(path) << kFile;
  const EmissivityMap map = EmissivityMap::Read(path, RigThermal());
  ASSERT_EQ(map.num_regions(), 3);
  EXPECT_EQ(map.region_name(0), "motor-boss");
  EXPECT_EQ(map.region_name(1), "pipe-tape");
  EXPECT_EQ(map.region_name(2), "label");
  EXPECT_EQ(map.region(0).line, 4);
  EXPECT_EQ(map.region(2).line, 12);
  ExpectSurface(map.default_surface(), 0.9, EmissivityLaw::kDielectric, 21.0, -1);

  // Box (identity rotation): half sizes 0.1, 0.05, 0.05 about (0.41, -0.12, 1.85).
  ExpectSurface(map.At({0.41f, -0.12f, 1.85f}), 0.30, EmissivityLaw::kMetal, 25.0, 0);
  ExpectSurface(map.At({0.509f, -0.169f, 1.801f}), 0.30, EmissivityLaw::kMetal, 25.0, 0);
  ExpectSurface(map.At({0.511f, -0.12f, 1.85f}), 0.9, EmissivityLaw::kDielectric, 21.0, -1);
  ExpectSurface(map.At({0.41f, -0.12f, 1.902f}), 0.9, EmissivityLaw::kDielectric, 21.0, -1);
  // Sphere: law and reflected_c from the region's defaults (dielectric, the file's 21 °C).
  ExpectSurface(map.At({0.1f, 0.2f, 1.5f}), 0.97, EmissivityLaw::kDielectric, 21.0, 1);
  ExpectSurface(map.At({0.128f, 0.228f, 1.528f}), 0.97, EmissivityLaw::kDielectric, 21.0, 1);
  ExpectSurface(map.At({0.13f, 0.23f, 1.53f}), 0.9, EmissivityLaw::kDielectric, 21.0, -1);
  // Box turned 45° about z: its long axis runs along (1, 1, 0)/√2. 0.18 m along that axis
  // is inside; 0.18 m along world x (local (0.127, -0.127)) is outside, though the box
  // without its rotation would hold it.
  const float s = static_cast<float>(0.18 / std::sqrt(2.0));
  EXPECT_EQ(map.At({1 + s, s, 2}).region, 2);
  EXPECT_EQ(map.At({1 - s, -s, 2.009f}).region, 2);
  EXPECT_EQ(map.At({1.18f, 0, 2}).region, -1);
  EXPECT_EQ(map.At({1 + s, s, 2.011f}).region, -1);
  // Just across the short side: local y = ±0.05 at local x = 0.
  const float t = static_cast<float>(0.049 / std::sqrt(2.0)),
              u = static_cast<float>(0.051 / std::sqrt(2.0));
  EXPECT_EQ(map.At({1 - t, t, 2}).region, 2);
  EXPECT_EQ(map.At({1 - u, u, 2}).region, -1);
  EXPECT_EQ(map.At({NAN, 0, 2}).region, -1);
  // No `specular` anywhere: each block's law decides it (NaN here, thermal_reflections.h).
  EXPECT_TRUE(std::isnan(map.At({0.41f, -0.12f, 1.85f}).specular_fraction));
  EXPECT_TRUE(std::isnan(map.default_surface().specular_fraction));
}

TEST(EmissivityMap, SpecularFractionWhereGivenAndOnlyThere) {
  const EmissivityMap map = ParseText(
      Replace(Replace(kFile, "law: dielectric,", "law: dielectric, specular: 0.05,"), "law: metal\n",
              "law: metal\n    specular: 0.7\n"));
  EXPECT_EQ(map.default_surface().specular_fraction, 0.05);
  EXPECT_EQ(map.At({0.41f, -0.12f, 1.85f}).specular_fraction, 0.7);
  // A region without the key takes its own law's, not the default block's.
  EXPECT_TRUE(std::isnan(map.At({0.1f, 0.2f, 1.5f}).specular_fraction));
  EXPECT_EQ(map.At({5.0f, 5.0f, 5.0f}).specular_fraction, 0.05);
}

TEST(EmissivityMap, DefaultsComeFromTheRigWhereTheFileLeavesThemOut) {
  const std::string no_default =
      Replace(kFile, "default: { emissivity: 0.9, law: dielectric, reflected_c: 21.0 }\n", "");
  const EmissivityMap map = ParseText(no_default);
  ExpectSurface(map.default_surface(), 0.93, EmissivityLaw::kDielectric, 18.5, -1);
  EXPECT_EQ(map.At({0.1f, 0.2f, 1.5f}).reflected_c, 18.5);  // the region's default
  EXPECT_EQ(map.At({0.41f, -0.12f, 1.85f}).reflected_c, 25.0);

  const EmissivityMap partial = ParseText(Replace(
      kFile, "{ emissivity: 0.9, law: dielectric, reflected_c: 21.0 }", "{ emissivity: 0.8 }"));
  ExpectSurface(partial.default_surface(), 0.8, EmissivityLaw::kDielectric, 18.5, -1);

  const EmissivityMap metal_scene =
      ParseText("version: 1\ndefault: { emissivity: 0.1, law: metal }\n");
  EXPECT_EQ(metal_scene.num_regions(), 0);
  ExpectSurface(metal_scene.At({0, 0, 0}), 0.1, EmissivityLaw::kMetal, 18.5, -1);
}

// ---------------------------------------------------------------------------------------
// Bad files: every message names the file, the key and the line.

struct BadFile {
  std::string name;
  std::string text;
  std::string expected;  // substring of what()
  std::string line_of;   // the reported line is the one holding this text
};

std::string Region(const std::string& name, const std::string& shape) {
  return "  - name: " + name + "\n    emissivity: 0.9\n    " + shape + "\n";
}

std::string TwoRegions(const std::string& shape_a, const std::string& shape_b) {
  return "version: 1\nregions:\n" + Region("a", shape_a) + Region("b", shape_b);
}

std::vector<BadFile> BadFiles() {
  const std::string box = "box: { centre_m: [0, 0, 0], size_m: [1, 1, 1] }";
  const std::string q45 = "q_xyzw: [0, 0, 0.3826834323650898, 0.9238795325112867]";
  const std::string cube = "box: { centre_m: [0, 0, 0], size_m: [0.2, 0.2, 0.2] }";
  return {
      {"unknown key in a region",
       Replace(kFile, "    emissivity: 0.97\n", "    emissivity: 0.97\n    colour: red\n"),
       "regions[1]: unknown key 'colour'", "colour: red"},
      {"unknown key in the default",
       Replace(kFile, "law: dielectric,", "law: dielectric, albedo: 1,"),
       "default: unknown key 'albedo'", "albedo"},
      {"unknown top-level key", kFile + "units: mm\n", "top level: unknown key 'units'", "units"},
      {"emissivity 0", Replace(kFile, "emissivity: 0.97", "emissivity: 0"),
       "regions[1].emissivity: must be in [0.01, 1], got 0", "emissivity: 0\n"},
      {"emissivity 1.2", Replace(kFile, "emissivity: 0.30", "emissivity: 1.2"),
       "regions[0].emissivity: must be in [0.01, 1], got 1.2", "emissivity: 1.2"},
      {"default emissivity 0", Replace(kFile, "{ emissivity: 0.9,", "{ emissivity: 0,"),
       "default.emissivity: must be in [0.01, 1], got 0", "default:"},
      {"reflected below absolute zero", Replace(kFile, "reflected_c: 25.0", "reflected_c: -300"),
       "regions[0].reflected_c: must be in (-273.15, 3000] °C (above absolute zero), got -300",
       "reflected_c: -300"},
      {"specular above 1", Replace(kFile, "law: metal\n", "law: metal\n    specular: 1.5\n"),
       "regions[0].specular: must be in [0, 1], got 1.5", "specular: 1.5"},
      {"negative default specular", Replace(kFile, "law: dielectric,", "law: dielectric, specular: -0.1,"),
       "default.specular: must be in [0, 1], got -0.1", "default:"},
      {"unknown law", Replace(kFile, "law: metal", "law: steel"),
       "regions[0].law: must be dielectric or metal, got 'steel'", "law: steel"},
      {"metal above the metal range", Replace(kFile, "emissivity: 0.30", "emissivity: 0.6"),
       "regions[0].emissivity: must be <= 0.4805", "emissivity: 0.6"},
      {"metal default at the rig's emissivity",
       Replace(kFile, "{ emissivity: 0.9, law: dielectric,", "{ law: metal,"),
       "default.law: metal needs emissivity <= 0.4805", "default:"},
      {"missing version", Replace(kFile, "version: 1\n", ""), "version: missing required key",
       "default:"},
      {"version 2", Replace(kFile, "version: 1", "version: 2"), "version: unsupported version 2",
       "version"},
      {"missing emissivity", Replace(kFile, "    emissivity: 0.97\n", ""),
       "regions[1].emissivity: missing required key", "name: pipe-tape"},
      {"duplicate name", Replace(kFile, "name: label", "name: motor-boss"),
       "regions[2].name: duplicate region name 'motor-boss' (also regions[0], line 4)",
       "name: motor-boss\n    emissivity: 0.85"},
      {"empty name", Replace(kFile, "name: label", "name: ''"),
       "regions[2].name: must not be empty", "name: ''"},
      {"size 0", Replace(kFile, "size_m: [0.2, 0.1, 0.1]", "size_m: [0.2, 0, 0.1]"),
       "regions[0].box.size_m[1]: must be in (0, 1e6] m, got 0", "size_m: [0.2, 0"},
      {"negative radius", Replace(kFile, "radius_m: 0.05", "radius_m: -0.05"),
       "regions[1].sphere.radius_m: must be in (0, 1e6] m, got -0.05", "radius_m"},
      {"non-unit quaternion", Replace(kFile, "q_xyzw: [0, 0, 0, 1]", "q_xyzw: [0, 0, 0, 1.00001]"),
       "regions[0].box.q_xyzw: not a unit quaternion (norm 1.00001)", "q_xyzw: [0, 0, 0, 1.00001]"},
      {"no shape",
       Replace(kFile, "    sphere: { centre_m: [0.1, 0.2, 1.5], radius_m: 0.05 }\n", ""),
       "regions[1]: needs a shape: box or sphere", "name: pipe-tape"},
      {"two shapes",
       Replace(kFile, "    emissivity: 0.97\n", "    emissivity: 0.97\n    " + box + "\n"),
       "regions[1]: has both box and sphere", "name: pipe-tape"},
      {"regions not a list", "version: 1\nregions: { a: 1 }\n",
       "regions: must be a list of regions", "regions"},
      // Overlaps, named with both regions and both lines.
      {"overlapping boxes",
       TwoRegions(box, "box: { centre_m: [0.9, 0.5, 0.5], size_m: [1, 1, 1] }"),
       "regions[1]: region 'b' overlaps region 'a' (regions[0], line 3); regions must not overlap",
       "name: b"},
      {"boxes that overlap only when rotated",
       TwoRegions(box, "box: { centre_m: [1.1, 0, 0], size_m: [1, 1, 1], " + q45 + " }"),
       "regions[1]: region 'b' overlaps region 'a' (regions[0], line 3)", "name: b"},
      {"box and sphere overlapping at a face",
       TwoRegions(cube, "sphere: { centre_m: [0.15, 0, 0], radius_m: 0.051 }"),
       "region 'b' overlaps region 'a'", "name: b"},
      {"box and sphere overlapping at a corner",
       TwoRegions(cube, "sphere: { centre_m: [0.2, 0.2, 0.2], radius_m: 0.18 }"),
       "region 'b' overlaps region 'a'", "name: b"},
      {"sphere inside a box", TwoRegions(cube, "sphere: { centre_m: [0, 0, 0], radius_m: 0.01 }"),
       "region 'b' overlaps region 'a'", "name: b"},
      {"overlapping spheres",
       TwoRegions("sphere: { centre_m: [0, 0, 0], radius_m: 0.1 }",
                  "sphere: { centre_m: [0.19, 0, 0], radius_m: 0.1 }"),
       "region 'b' overlaps region 'a'", "name: b"},
  };
}

TEST(EmissivityMap, BadFilesNameTheFileKeyAndLine) {
  for (const BadFile& bad : BadFiles()) {
    SCOPED_TRACE(bad.name);
    try {
      ParseText(bad.text);
      ADD_FAILURE() << "no error for " << bad.name;
    } catch (const core::InputError& e) {
      const std::string what = e.what();
      EXPECT_THAT(what, HasSubstr(kPath));
      EXPECT_THAT(what, HasSubstr(bad.expected));
      const int line = LineOf(bad.text, bad.line_of);
      EXPECT_THAT(what, HasSubstr("(line " + std::to_string(line) + ")"));
    }
  }
}

TEST(EmissivityMap, TouchingRegionsAreAllowed) {
  const std::string box = "box: { centre_m: [0, 0, 0], size_m: [1, 1, 1] }";
  const std::string cube = "box: { centre_m: [0, 0, 0], size_m: [0.2, 0.2, 0.2] }";
  const std::string q45 = "q_xyzw: [0, 0, 0.3826834323650898, 0.9238795325112867]";
  const std::vector<std::string> files = {
      // Face to face, and apart by 0.1 m before the rotation that makes them overlap above.
      TwoRegions(box, "box: { centre_m: [1, 0.3, 0], size_m: [1, 1, 1] }"),
      TwoRegions(box, "box: { centre_m: [1.1, 0, 0], size_m: [1, 1, 1] }"),
      // A turned box whose edge touches the face x = 0.5: centre at 0.5 + √2/2.
      TwoRegions(box,
                 "box: { centre_m: [1.2071067811865475, 0, 0], size_m: [1, 1, 1], " + q45 + " }"),
      // Sphere on a face, on a corner (r = √3·0.1), two spheres touching.
      TwoRegions(cube, "sphere: { centre_m: [0.15, 0, 0], radius_m: 0.05 }"),
      TwoRegions(cube, "sphere: { centre_m: [0.2, 0.2, 0.2], radius_m: 0.17320508075688773 }"),
      TwoRegions("sphere: { centre_m: [0, 0, 0], radius_m: 0.1 }",
                 "sphere: { centre_m: [0.2, 0, 0], radius_m: 0.1 }"),
      // Long thin boxes side by side along a diagonal: their axis-aligned bounds overlap.
      TwoRegions("box: { centre_m: [0, 0, 0], size_m: [2, 0.1, 0.1], " + q45 + " }",
                 "box: { centre_m: [-0.1414213562373095, 0.1414213562373095, 0], "
                 "size_m: [2, 0.1, 0.1], " +
                     q45 + " }"),
  };
  for (const std::string& text : files) {
    EXPECT_EQ(ParseText(text).num_regions(), 2) << text;
  }
  // The shared face goes to the region listed first.
  const EmissivityMap map = ParseText(files[0]);
  EXPECT_EQ(map.At({0.5f, 0.3f, 0}).region, 0);
  EXPECT_EQ(map.At({0.51f, 0.3f, 0}).region, 1);
}

// ---------------------------------------------------------------------------------------
// The separating-axis test against an independent one: two boxes' closed intersection is a
// polytope bounded by their 12 face planes; it is non-empty iff some vertex (three planes
// meeting) satisfies all 12 inequalities.

EmissivityRegion Box(const Eigen::Vector3d& centre, const Eigen::Vector3d& size,
                     const Eigen::Quaterniond& q) {
  EmissivityRegion box;
  box.shape = Shape::kBox;
  box.centre_in_world = centre;
  box.half_size_m = 0.5 * size;
  box.world_from_box = q;
  return box;
}

// The boxes grown (margin > 0) or shrunk (< 0) by margin on every face intersect.
bool VerticesIntersect(const EmissivityRegion& a, const EmissivityRegion& b, double margin) {
  std::vector<Eigen::Vector3d> normals;
  std::vector<double> offsets;  // n·x <= offset
  for (const EmissivityRegion* box : {&a, &b}) {
    const Eigen::Matrix3d axes = box->world_from_box.toRotationMatrix();
    for (int i = 0; i < 3; ++i) {
      for (const double sign : {1.0, -1.0}) {
        const Eigen::Vector3d n = sign * axes.col(i);
        normals.push_back(n);
        offsets.push_back(n.dot(box->centre_in_world) + box->half_size_m[i] + margin);
      }
    }
  }
  for (size_t i = 0; i < 12; ++i) {
    for (size_t j = i + 1; j < 12; ++j) {
      for (size_t k = j + 1; k < 12; ++k) {
        Eigen::Matrix3d m;
        m << normals[i].transpose(), normals[j].transpose(), normals[k].transpose();
        if (std::abs(m.determinant()) < 1e-9) continue;
        const Eigen::Vector3d x = m.lu().solve(Eigen::Vector3d(offsets[i], offsets[j], offsets[k]));
        bool inside = true;
        for (size_t p = 0; p < 12 && inside; ++p) inside = normals[p].dot(x) <= offsets[p] + 1e-12;
        if (inside) return true;
      }
    }
  }
  return false;
}

TEST(EmissivityMap, SeparatingAxesAgreeWithVertexEnumeration) {
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> centre(-0.6, 0.6), size(0.05, 1.0);
  int overlapping = 0, apart = 0;
  for (int trial = 0; trial < 3000; ++trial) {
    const auto random_box = [&] {
      const Eigen::Quaterniond q = Eigen::Quaterniond::UnitRandom();
      return Box({centre(rng), centre(rng), centre(rng)}, {size(rng), size(rng), size(rng)}, q);
    };
    const EmissivityRegion a = random_box(), b = random_box();
    // Pairs within 1e-4 m of touching are left out: the two tests may rightly differ there.
    const bool surely_overlap = VerticesIntersect(a, b, -1e-4);
    const bool maybe_overlap = VerticesIntersect(a, b, 1e-4);
    if (surely_overlap != maybe_overlap) continue;
    EXPECT_EQ(RegionsOverlap(a, b), surely_overlap) << trial;
    EXPECT_EQ(RegionsOverlap(b, a), surely_overlap) << trial;
    (surely_overlap ? overlapping : apart)++;
  }
  // Both outcomes well represented (and edge-edge separations among the "apart").
  EXPECT_GT(overlapping, 500);
  EXPECT_GT(apart, 500);
}

TEST(EmissivityMap, LookupTiming) {
  // 100 spheres on a grid, 1e5 lookups spread over them: prints the cost per lookup.
  std::string text = "version: 1\nregions:\n";
  for (int i = 0; i < 100; ++i) {
    text +=
        Region("r" + std::to_string(i), "sphere: { centre_m: [" + std::to_string(i % 10) + ", " +
                                            std::to_string(i / 10) + ", 2], radius_m: 0.3 }");
  }
  const EmissivityMap map = ParseText(text);
  ASSERT_EQ(map.num_regions(), 100);
  const int n = 100000;
  int hits = 0;
  const auto start = std::chrono::steady_clock::now();
  for (int i = 0; i < n; ++i) {
    const float x = 10.0f * static_cast<float>(i) / n, y = static_cast<float>(i % 1000) / 100;
    hits += map.At({x, y, 2}).region >= 0;
  }
  const double ns =
      std::chrono::duration<double, std::nano>(std::chrono::steady_clock::now() - start).count() /
      n;
  std::printf("EmissivityMap::At with 100 regions: %.0f ns per lookup (%d hits)\n", ns, hits);
  // The points fill [0, 10)² (x in steps of 1e-4 m, y of 0.01 m); the discs of radius 0.3
  // about the integer centres cover (100 - 10/2 - 10/2 + 1/4)·π·0.3² / 100 = 0.255 of it
  // (the discs on the x = 0 and y = 0 edges are half outside).
  EXPECT_NEAR(static_cast<double>(hits) / n, 0.255, 0.01);
}

TEST(EmissivityMap, FromLookupAnswersWhereTheLookupDoesElseTheRigDefault) {
  core::ThermalSettings rig;
  rig.emissivity = 0.95;
  rig.reflected_c = 19.0;
  // A metal boss of radius 5 cm at the origin, nothing else known.
  const EmissivityMap map = EmissivityMap::FromLookup(rig, [](const Eigen::Vector3f& p, SurfaceEmissivity& out) {
    if (p.norm() > 0.05f) return false;
    out.emissivity = 0.3;
    out.law = core::EmissivityLaw::kMetal;
    out.region = 7;
    return true;
  });
  SurfaceEmissivity s = map.At({0.01f, 0.0f, 0.0f});
  EXPECT_EQ(s.emissivity, 0.3);
  EXPECT_EQ(s.law, core::EmissivityLaw::kMetal);
  EXPECT_EQ(s.region, 7);
  EXPECT_EQ(s.reflected_c, 19.0);  // left as the default gave it
  s = map.At({0.2f, 0.0f, 0.0f});
  EXPECT_EQ(s.region, -1);
  EXPECT_EQ(s.emissivity, 0.95);
  EXPECT_EQ(s.law, core::EmissivityLaw::kDielectric);
}

}  // namespace
}  // namespace hw::reconstruct
