#include "core/trajectory.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "core/atomic_file.h"
#include "core/error.h"
#include "tests/support.h"

namespace hw::core {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

Rigid3d RandomPose(std::mt19937& rng) {
  std::normal_distribution<double> normal(0.0, 1.0);
  const Eigen::Quaterniond q(normal(rng), normal(rng), normal(rng), normal(rng));
  return Rigid3d(q, Eigen::Vector3d(normal(rng), normal(rng), normal(rng)));
}

Trajectory RandomTrajectory(std::mt19937& rng, int n) {
  std::uniform_real_distribution<double> dt(0.001, 0.1);
  Trajectory trajectory;
  double t = 1305031102.175304;  // a TUM-like epoch timestamp: large, many digits
  for (int i = 0; i < n; ++i) {
    trajectory.Add(t, RandomPose(rng));
    t += dt(rng);
  }
  return trajectory;
}

void ExpectSamePose(const Rigid3d& a, const Rigid3d& b, double tolerance) {
  const PoseError e = ComparePoses(a, b);
  EXPECT_LE(e.rotation_rad, tolerance);
  EXPECT_LE(e.translation_m, tolerance);
}

TEST(TrajectoryTest, AtSampleTimesIsExact) {
  std::mt19937 rng(1);
  const Trajectory trajectory = RandomTrajectory(rng, 50);
  for (const TimedPose& pose : trajectory.poses()) {
    const std::optional<Rigid3d> at = trajectory.At(pose.timestamp_s);
    ASSERT_TRUE(at.has_value());
    EXPECT_EQ(at->rotation.coeffs(), pose.world_from_sensor.rotation.coeffs());
    EXPECT_EQ(at->translation, pose.world_from_sensor.translation);
  }
  EXPECT_EQ(trajectory.StartTime(), trajectory.poses().front().timestamp_s);
  EXPECT_EQ(trajectory.EndTime(), trajectory.poses().back().timestamp_s);
}

TEST(TrajectoryTest, BetweenSamplesMatchesInterpolate) {
  Trajectory trajectory;
  const Rigid3d a(Eigen::Quaterniond(Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitY())),
                  Eigen::Vector3d(0, 0, 0));
  const Rigid3d b(Eigen::Quaterniond(Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitY())),
                  Eigen::Vector3d(1, 0, 0));
  const Rigid3d c(Eigen::Quaterniond(Eigen::AngleAxisd(-0.5, Eigen::Vector3d::UnitX())),
                  Eigen::Vector3d(1, 2, 0));
  trajectory.Add(10.0, a);
  trajectory.Add(10.5, b);
  trajectory.Add(12.5, c);
  // 10.125 is a quarter of the way from a to b; 11.0 a quarter from b to c.
  ExpectSamePose(*trajectory.At(10.125), Interpolate(a, b, 0.25), 1e-15);
  ExpectSamePose(*trajectory.At(11.0), Interpolate(b, c, 0.25), 1e-15);
  // And in absolute terms: angle 0.2 about y, x = 0.25.
  ExpectSamePose(*trajectory.At(10.125),
                 Rigid3d(Eigen::Quaterniond(Eigen::AngleAxisd(0.2, Eigen::Vector3d::UnitY())),
                         Eigen::Vector3d(0.25, 0, 0)),
                 1e-15);
}

TEST(TrajectoryTest, OutsideRangeIsNullopt) {
  Trajectory trajectory;
  EXPECT_FALSE(trajectory.At(0.0).has_value());  // empty
  trajectory.Add(1.0, Rigid3d::Identity());
  EXPECT_TRUE(trajectory.At(1.0).has_value());  // a single pose is defined at its time
  EXPECT_TRUE(trajectory.At(1.0 + 0.5e-9).has_value());
  EXPECT_FALSE(trajectory.At(1.0 + 2e-9).has_value());
  trajectory.Add(2.0, Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(1, 0, 0)));
  EXPECT_FALSE(trajectory.At(0.5).has_value());
  EXPECT_FALSE(trajectory.At(1.0 - 2e-9).has_value());
  EXPECT_FALSE(trajectory.At(2.0 + 2e-9).has_value());
  EXPECT_FALSE(trajectory.At(std::nan("")).has_value());
  EXPECT_FALSE(trajectory.At(INFINITY).has_value());
  // Within the 1e-9 s tolerance: the end poses themselves.
  ASSERT_TRUE(trajectory.At(1.0 - 0.5e-9).has_value());
  EXPECT_EQ(trajectory.At(1.0 - 0.5e-9)->translation, Eigen::Vector3d::Zero());
  ASSERT_TRUE(trajectory.At(2.0 + 0.5e-9).has_value());
  EXPECT_EQ(trajectory.At(2.0 + 0.5e-9)->translation, Eigen::Vector3d(1, 0, 0));
}

TEST(TrajectoryTest, GapsAreNotBridged) {
  Trajectory trajectory;
  trajectory.Add(0.0, Rigid3d::Identity());
  trajectory.Add(0.1, Rigid3d::Identity());
  trajectory.Add(1.1, Rigid3d::Identity());  // 1 s tracking gap
  trajectory.Add(1.2, Rigid3d::Identity());
  EXPECT_TRUE(trajectory.At(0.05, 0.2).has_value());
  EXPECT_FALSE(trajectory.At(0.6, 0.2).has_value());
  EXPECT_TRUE(trajectory.At(0.6).has_value());  // default: no gap limit
  EXPECT_TRUE(trajectory.At(0.6, 1.0).has_value());
  EXPECT_TRUE(trajectory.At(1.15, 0.2).has_value());
  // At the samples that border the gap, the pose is known: no bridging involved.
  EXPECT_TRUE(trajectory.At(0.1, 0.2).has_value());
  EXPECT_TRUE(trajectory.At(1.1, 0.2).has_value());
}

TEST(TrajectoryTest, WriteReadRoundTripIsExact) {
  const fs::path dir = hw::test::TestFolder("round_trip");
  std::mt19937 rng(2);
  const Trajectory trajectory = RandomTrajectory(rng, 200);
  const fs::path path = dir / "sub" / "groundtruth.txt";
  WriteTumTrajectory(path, trajectory);
  const Trajectory back = ReadTumTrajectory(path);
  ASSERT_EQ(back.size(), trajectory.size());
  double worst = 0;
  for (size_t i = 0; i < back.size(); ++i) {
    EXPECT_EQ(back.poses()[i].timestamp_s, trajectory.poses()[i].timestamp_s);
    EXPECT_EQ(back.poses()[i].world_from_sensor.translation,
              trajectory.poses()[i].world_from_sensor.translation);
    worst = std::max(worst, (back.poses()[i].world_from_sensor.rotation.coeffs() -
                             trajectory.poses()[i].world_from_sensor.rotation.coeffs())
                                .cwiseAbs()
                                .maxCoeff());
  }
  // The quaternion is renormalised on reading: at most an ulp or two.
  EXPECT_LE(worst, 1e-15);
  std::printf("TUM round trip: max quaternion coefficient change %.3g\n", worst);
  // No temporary files left behind.
  int files = 0;
  for ([[maybe_unused]] const auto& entry : fs::directory_iterator(dir / "sub")) ++files;
  EXPECT_EQ(files, 1);
}

TEST(TrajectoryTest, ParsesTumStyleText) {
  const std::string text =
      "# ground truth trajectory\n"
      "# timestamp tx ty tz qx qy qz qw\n"
      "\n"
      "1305031102.1753 1.3405 0.6266 1.6575 0.6574 0.6126 -0.2949 -0.3248\r\n"
      "  1305031102.1853\t1.3303 0.6256 1.6464 0.6579 0.6161 -0.2932 -0.3189  # trailing\n"
      "+1305031102.1953 -1e-3 .5 2. 0 0 0 1";  // no final newline; '+', exponents
  const Trajectory trajectory = ParseTumTrajectory(text, "groundtruth.txt");
  ASSERT_EQ(trajectory.size(), 3u);
  EXPECT_EQ(trajectory.poses()[0].timestamp_s, 1305031102.1753);
  EXPECT_EQ(trajectory.poses()[0].world_from_sensor.translation,
            Eigen::Vector3d(1.3405, 0.6266, 1.6575));
  // x y z w order in the file; near-unit quaternions (|q| = 0.99999...) are normalised.
  const Eigen::Quaterniond q0(-0.3248, 0.6574, 0.6126, -0.2949);
  EXPECT_NEAR(trajectory.poses()[0].world_from_sensor.rotation.angularDistance(q0), 0.0,
              1e-15);
  EXPECT_NEAR(trajectory.poses()[0].world_from_sensor.rotation.norm(), 1.0, 1e-15);
  EXPECT_EQ(trajectory.poses()[2].world_from_sensor.translation,
            Eigen::Vector3d(-1e-3, 0.5, 2.0));
  EXPECT_EQ(ParseTumTrajectory("", "x").size(), 0u);
  EXPECT_EQ(ParseTumTrajectory("# only a comment\n\n", "x").size(), 0u);
}

// Expects InputError whose message names the path and contains `needle`.
void ExpectInputError(const std::string& text, const std::string& needle) {
  try {
    ParseTumTrajectory(text, "scan/groundtruth.txt");
    ADD_FAILURE() << "no error for:\n" << text;
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("scan/groundtruth.txt: ")) << text;
    EXPECT_THAT(e.what(), HasSubstr(needle)) << text;
    EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << "one line";
  }
}

TEST(TrajectoryTest, MalformedLinesNameTheLine) {
  const std::string good = "1 0 0 0 0 0 0 1\n";
  ExpectInputError(good + "2 0 0 0 0 0 1\n", "line 2: expected 8 numbers (timestamp tx ty tz "
                                             "qx qy qz qw), got 7");
  ExpectInputError(good + "2 0 0 0 0 0 0 1 5\n", "line 2: expected 8 numbers");
  ExpectInputError(good + "\n# c\n2 0 0 0 0 0 0 1 5\n", "line 4: expected 8 numbers");
  ExpectInputError("1 0 0 zero 0 0 0 1\n", "line 1: tz: 'zero' is not a number");
  ExpectInputError("1 0 0 0,5 0 0 0 1\n", "line 1: tz: '0,5' is not a number");
  ExpectInputError("1 0 0 0 0 0 0 1x\n", "line 1: qw: '1x' is not a number");
  ExpectInputError("1 0 0 0 0 0 0 --1\n", "line 1: qw: '--1' is not a number");
  ExpectInputError("1 0 0 0 0 0 0 ++1\n", "line 1: qw: '++1' is not a number");
  ExpectInputError("1 0 0 0 0 0 0 0x1\n", "line 1: qw: '0x1' is not a number");
  ExpectInputError("nan 0 0 0 0 0 0 1\n", "line 1: timestamp: 'nan' is not finite");
  ExpectInputError("1 inf 0 0 0 0 0 1\n", "line 1: tx: 'inf' is not finite");
  ExpectInputError("1 0 1e999 0 0 0 0 1\n", "line 1: ty: '1e999' is out of range");
  ExpectInputError("1 0 0 0 0 0 0 0\n", "line 1: quaternion (qx qy qz qw) has norm 0");
  ExpectInputError("1 0 0 0 0 0 0 1.0011\n", "line 1: quaternion (qx qy qz qw) has norm 1.0011");
  ExpectInputError("1 0 0 0 0 0 0 0.998\n", "has norm 0.998");
  ExpectInputError(good + "1 0 0 0 0 0 0 1\n",
                   "line 2: timestamp 1 is not after the previous one (1 on line 1)");
  ExpectInputError(good + "# x\n0.5 0 0 0 0 0 0 1\n",
                   "line 3: timestamp 0.5 is not after the previous one (1 on line 1)");
  ExpectInputError(good + "2 0 0 0 0 0 0 1\x01\n", "line 2: qw: '1?' is not a number");
}

TEST(TrajectoryTest, QuaternionNormToleranceBoundary) {
  EXPECT_NO_THROW(ParseTumTrajectory("1 0 0 0 0 0 0 1.0009\n", "x"));
  EXPECT_NO_THROW(ParseTumTrajectory("1 0 0 0 0 0 0 0.9991\n", "x"));
  EXPECT_THROW(ParseTumTrajectory("1 0 0 0 0 0 0 1.0011\n", "x"), InputError);
}

TEST(TrajectoryTest, MissingFileIsInputError) {
  const fs::path dir = hw::test::TestFolder("missing");
  EXPECT_THROW(ReadTumTrajectory(dir / "nope.txt"), InputError);
  EXPECT_THROW(ReadTumTrajectory(dir), InputError);  // a folder
}

TEST(TrajectoryTest, WriteToUnwritablePlaceIsOutputError) {
  const fs::path dir = hw::test::TestFolder("unwritable");
  std::ofstream(dir / "file") << "x";
  Trajectory trajectory;
  trajectory.Add(1.0, Rigid3d::Identity());
  // A path whose parent is a regular file cannot be created.
  EXPECT_THROW(WriteTumTrajectory(dir / "file" / "groundtruth.txt", trajectory), OutputError);
}

TEST(TrajectoryTest, FuzzReturnsOrThrowsInputError) {
  std::mt19937 rng(1234);
  const Trajectory trajectory = RandomTrajectory(rng, 6);
  const fs::path dir = hw::test::TestFolder("fuzz");
  WriteTumTrajectory(dir / "t.txt", trajectory);
  const std::string valid = ReadFile(dir / "t.txt", kMaxMeshFileBytes);
  int parsed = 0, rejected = 0;
  auto run = [&](const std::string& text) {
    try {
      const Trajectory t = ParseTumTrajectory(text, "fuzz.txt");
      // Whatever parsed is a valid trajectory: increasing times, unit quaternions.
      for (size_t i = 0; i < t.size(); ++i) {
        ASSERT_NEAR(t.poses()[i].world_from_sensor.rotation.norm(), 1.0, 1e-12);
        if (i > 0) {
          ASSERT_GT(t.poses()[i].timestamp_s, t.poses()[i - 1].timestamp_s);
        }
      }
      ++parsed;
    } catch (const InputError& e) {
      ASSERT_THAT(e.what(), HasSubstr("fuzz.txt: line "));
      ++rejected;
    }
  };
  for (size_t n = 0; n <= valid.size(); ++n) run(valid.substr(0, n));
  static constexpr char kAlphabet[] = "0123456789 .-+eE#\n\r\tnaifx\0\xff";
  const std::string alphabet(kAlphabet, sizeof(kAlphabet) - 1);
  std::uniform_int_distribution<size_t> pick_char(0, alphabet.size() - 1);
  for (int trial = 0; trial < 3000; ++trial) {
    std::string text = valid;
    const int mutations = 1 + trial % 4;
    for (int m = 0; m < mutations; ++m) {
      const size_t pos = std::uniform_int_distribution<size_t>(0, text.size() - 1)(rng);
      switch (trial % 3) {
        case 0:
          text[pos] = alphabet[pick_char(rng)];
          break;
        case 1:
          text[pos] = static_cast<char>(rng() & 0xff);
          break;
        default:
          text.erase(pos, 1);
          break;
      }
    }
    run(text);
  }
  // Both outcomes occur: the fuzzing reaches past the first line.
  EXPECT_GT(parsed, 50);
  EXPECT_GT(rejected, 50);
  std::printf("fuzz: %d parsed, %d rejected\n", parsed, rejected);
}

}  // namespace
}  // namespace hw::core
