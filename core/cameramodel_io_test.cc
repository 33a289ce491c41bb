#include "core/cameramodel_io.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "core/atomic_file.h"
#include "core/error.h"
#include "core/mrcal_c.h"
#include "core/splined_test_support.h"
#include "tests/support.h"

namespace hw::core {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using ::testing::StartsWith;

// libmrcal's parser reports every rejection on stderr; the fuzz test would print thousands
// of lines. Silences file descriptor 2 for the lifetime of the object.
class QuietStderr {
 public:
  QuietStderr() {
    std::fflush(stderr);
    saved_ = ::dup(2);
    const int null = ::open("/dev/null", O_WRONLY);
    ::dup2(null, 2);
    ::close(null);
  }
  ~QuietStderr() {
    std::fflush(stderr);
    ::dup2(saved_, 2);
    ::close(saved_);
  }
  QuietStderr(const QuietStderr&) = delete;
  QuietStderr& operator=(const QuietStderr&) = delete;

 private:
  int saved_ = -1;
};

CameraModel MakeCamera(CameraModelType type, int num_distortion) {
  CameraModel camera;
  camera.width = 1280;
  camera.height = 1024;
  camera.type = type;
  camera.fx = 1234.5678901234567;
  camera.fy = 1235.0 + 1.0 / 3.0;
  camera.cx = 639.5 + 0.1 + 0.2;
  camera.cy = 511.49999999999994;
  // 1e-17 and -3e-9 are what mrcal's own "%f" writer would turn into 0.
  const std::vector<double> coefficients = {-0.2 / 3.0, 0.11, 1e-17, -3e-9,
                                            0.02,       1e-3, -0.5,  2.0 / 7.0};
  camera.distortion.assign(coefficients.begin(), coefficients.begin() + num_distortion);
  return camera;
}

struct LensModel {
  CameraModelType type;
  int num_distortion;
  std::string mrcal_name;
};
const std::vector<LensModel> kLensModels = {
    {CameraModelType::kPinhole, 0, "LENSMODEL_PINHOLE"},
    {CameraModelType::kOpenCV, 4, "LENSMODEL_OPENCV4"},
    {CameraModelType::kOpenCV, 5, "LENSMODEL_OPENCV5"},
    {CameraModelType::kOpenCV, 8, "LENSMODEL_OPENCV8"},
};

// Angle (rad) between two rotations; 0 for q and -q.
double AngleBetween(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b) {
  return a.normalized().angularDistance(b.normalized());
}

std::string ParseError(const std::string& text) {
  QuietStderr quiet;
  try {
    ParseMrcalCameraModel(text, "cam.cameramodel");
  } catch (const InputError& e) {
    return e.what();
  }
  return "<no error>";
}

// ---------------------------------------------------------------------------------------
// Rodrigues <-> quaternion.

TEST(RodriguesTest, MatchesEigenAngleAxisAndRoundTrips) {
  std::mt19937 rng(3);
  std::normal_distribution<double> normal;
  std::uniform_real_distribution<double> uniform(0, M_PI);
  double max_error = 0;
  for (int i = 0; i < 1000; ++i) {
    const Eigen::Vector3d axis =
        Eigen::Vector3d(normal(rng), normal(rng), normal(rng)).normalized();
    const double angle = uniform(rng);
    const Eigen::Vector3d r = axis * angle;
    const Eigen::Quaterniond q = QuaternionFromRodrigues(r);
    // Against Eigen's rotation matrix of the same axis-angle.
    max_error = std::max(max_error,
                         (q.toRotationMatrix() - Eigen::AngleAxisd(angle, axis).toRotationMatrix())
                             .cwiseAbs()
                             .maxCoeff());
    max_error = std::max(max_error, (RodriguesFromQuaternion(q) - r).norm());
    // Either sign of the quaternion is the same rotation.
    max_error =
        std::max(max_error, (RodriguesFromQuaternion(Eigen::Quaterniond(-q.coeffs())) - r).norm());
  }
  // A few ulps of pi.
  EXPECT_LT(max_error, 4e-15);
  RecordProperty("max_error", (std::ostringstream() << max_error).str());
}

TEST(RodriguesTest, KeepsRelativePrecisionForTinyAngles) {
  for (const double angle : {1e-300, 1e-20, 1e-12, 1e-8, 1e-4}) {
    SCOPED_TRACE(angle);
    const Eigen::Vector3d r = Eigen::Vector3d(0.6, -0.8, 0) * angle;
    const Eigen::Quaterniond q = QuaternionFromRodrigues(r);
    // The vector part is sin(angle / 2) * axis, to an ulp or two.
    EXPECT_NEAR(q.x(), 0.6 * std::sin(angle / 2), 4e-16 * 0.3 * angle);
    EXPECT_NEAR(q.y(), -0.8 * std::sin(angle / 2), 4e-16 * 0.4 * angle);
    EXPECT_NEAR((RodriguesFromQuaternion(q) - r).norm(), 0, 1e-15 * angle);
  }
  EXPECT_EQ(RodriguesFromQuaternion(Eigen::Quaterniond::Identity()), Eigen::Vector3d::Zero());
  EXPECT_EQ(QuaternionFromRodrigues(Eigen::Vector3d::Zero()).coeffs(),
            Eigen::Quaterniond::Identity().coeffs());
  // An unnormalised quaternion gives the rotation it stands for.
  const Eigen::Quaterniond scaled(Eigen::Vector4d(0, 0, 2e-10, 2.0));  // (x y z w)
  EXPECT_NEAR(RodriguesFromQuaternion(scaled).z(), 2e-10, 1e-25);
}

TEST(RodriguesTest, IsExactNearPi) {
  const Eigen::Vector3d axis = Eigen::Vector3d(1, 2, -2) / 3.0;
  for (const double angle : {M_PI, M_PI - 1e-6, M_PI - 1e-12}) {
    SCOPED_TRACE(angle);
    const Eigen::Vector3d r = axis * angle;
    const Eigen::Quaterniond q = QuaternionFromRodrigues(r);
    EXPECT_LT(AngleBetween(q, Eigen::Quaterniond(Eigen::AngleAxisd(angle, axis))), 1e-15);
    EXPECT_LT((RodriguesFromQuaternion(q) - r).norm(), 2e-15);
  }
  // At exactly pi (w = 0, either sign), r and -r are the same rotation.
  const Eigen::Quaterniond half_turn(0, 0, 1, 0);  // w x y z: pi about y
  const Eigen::Vector3d r = RodriguesFromQuaternion(half_turn);
  EXPECT_NEAR(std::abs(r.y()), M_PI, 1e-15);
  EXPECT_EQ(r.x(), 0);
  EXPECT_EQ(r.z(), 0);
  // Beyond pi (mrcal may store any r): the same rotation as 2 pi - angle the other way.
  const Eigen::Vector3d r_long = axis * (1.5 * M_PI);
  EXPECT_LT(
      AngleBetween(QuaternionFromRodrigues(r_long), QuaternionFromRodrigues(-axis * (0.5 * M_PI))),
      1e-15);
}

TEST(RodriguesTest, AgreesWithTheSe3Logarithm) {
  // Rigid3d::Log's rotation part is the rotation vector, an independent implementation.
  std::mt19937 rng(4);
  std::normal_distribution<double> normal;
  for (int i = 0; i < 200; ++i) {
    const Rigid3d pose(Eigen::Quaterniond(normal(rng), normal(rng), normal(rng), normal(rng)),
                       Eigen::Vector3d::Zero());
    EXPECT_LT((RodriguesFromQuaternion(pose.rotation) - pose.Log().head<3>()).norm(), 1e-14);
  }
}

// ---------------------------------------------------------------------------------------
// Export / import.

TEST(CameraModelIoTest, NamesMrcalLensModels) {
  for (const LensModel& model : kLensModels) {
    EXPECT_EQ(MrcalLensModelName(MakeCamera(model.type, model.num_distortion)), model.mrcal_name);
  }
}

TEST(CameraModelIoTest, RoundTripsEveryLensModelWithAndWithoutExtrinsics) {
  const fs::path dir = hw::test::TestFolder();
  const std::vector<Rigid3d> extrinsics = {
      Rigid3d(),
      Rigid3d(Eigen::Quaterniond(0.9, -0.1, 0.3, 1e-9), Eigen::Vector3d(0.03, -1.0 / 3.0, 2e-9)),
      // Rotations near the two ends of the Rodrigues range.
      Rigid3d(Eigen::Quaterniond(1, 1e-13, 0, 0), Eigen::Vector3d(1, 2, 3)),
      Rigid3d(Eigen::Quaterniond(1e-13, 0, 0.6, 0.8), Eigen::Vector3d(-1, 0, 0.5))};
  double max_rotation_error = 0, max_translation_error = 0;
  for (const LensModel& model : kLensModels) {
    for (size_t e = 0; e < extrinsics.size(); ++e) {
      SCOPED_TRACE(model.mrcal_name + " extrinsics " + std::to_string(e));
      const CameraModel camera = MakeCamera(model.type, model.num_distortion);
      const fs::path path = dir / (model.mrcal_name + std::to_string(e) + ".cameramodel");
      WriteMrcalCameraModel(path, camera, extrinsics[e]);
      const MrcalCameraModel back = ReadMrcalCameraModel(path);
      // Intrinsics carry over as numbers: bit for bit.
      EXPECT_EQ(back.camera.type, camera.type);
      EXPECT_EQ(back.camera.width, camera.width);
      EXPECT_EQ(back.camera.height, camera.height);
      EXPECT_EQ(back.camera.Params(), camera.Params());
      // Extrinsics go through the Rodrigues vector: equal to rounding.
      const double rotation_error =
          AngleBetween(back.camera_from_ref.rotation, extrinsics[e].rotation);
      const double translation_error =
          (back.camera_from_ref.translation - extrinsics[e].translation).norm();
      EXPECT_LT(rotation_error, 1e-12);
      EXPECT_EQ(translation_error, 0);
      max_rotation_error = std::max(max_rotation_error, rotation_error);
      max_translation_error = std::max(max_translation_error, translation_error);
      // Identity extrinsics come back as exactly the identity.
      if (e == 0) {
        EXPECT_EQ(back.camera_from_ref.rotation.coeffs(), Eigen::Quaterniond::Identity().coeffs());
      }
    }
  }
  RecordProperty("max_rotation_error_rad", (std::ostringstream() << max_rotation_error).str());
  // Only the file: the temporary was renamed.
  for (const auto& entry : fs::directory_iterator(dir)) {
    EXPECT_EQ(entry.path().extension(), ".cameramodel");
    EXPECT_NE(entry.path().filename().string()[0], '.');
  }
}

TEST(CameraModelIoTest, WritesTheMrcalLayout) {
  const std::string text =
      FormatMrcalCameraModel(MakeCamera(CameraModelType::kOpenCV, 4),
                             Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(1, 2, 3)));
  EXPECT_THAT(text, HasSubstr("'lensmodel':  'LENSMODEL_OPENCV4',"));
  EXPECT_THAT(text, HasSubstr("'intrinsics': [ 1234.5678901234567, 1235.3333333333333, "
                              "639.8000000000001, 511.49999999999994, -0.06666666666666667, "
                              "0.11, 1e-17, -3e-09 ],"));
  EXPECT_THAT(text, HasSubstr("'extrinsics': [ 0, 0, 0, 1, 2, 3 ],"));
  EXPECT_THAT(text, HasSubstr("'imagersize': [ 1280, 1024 ]"));
}

TEST(CameraModelIoTest, ParsesAHandWrittenModel) {
  // As mrcal's Python tools write them: comments, any key order, trailing commas.
  const std::string text = R"(# generated on 2023-01-01 with   mrcal-calibrate-cameras
{
    'lensmodel':  'LENSMODEL_OPENCV5',

    # intrinsics are fx,fy,cx,cy,distortion0,distortion1,....
    'intrinsics': [ 520.5, 521.25, 319.75, 240.125, 0.25, -0.5, 0.001, -0.002, 0.125,],

    # extrinsics are rt_fromref
    'extrinsics': [ 0.0, 0.0, 1.5707963267948966, 0.1, -0.2, 0.3,],

    'imagersize': [ 640, 480,],
}
)";
  const MrcalCameraModel model = ParseMrcalCameraModel(text, "hand.cameramodel");
  EXPECT_EQ(model.camera.type, CameraModelType::kOpenCV);
  EXPECT_EQ(model.camera.width, 640);
  EXPECT_EQ(model.camera.height, 480);
  EXPECT_EQ(model.camera.fx, 520.5);
  EXPECT_EQ(model.camera.fy, 521.25);
  EXPECT_EQ(model.camera.cx, 319.75);
  EXPECT_EQ(model.camera.cy, 240.125);
  EXPECT_EQ(model.camera.distortion, (std::vector<double>{0.25, -0.5, 0.001, -0.002, 0.125}));
  // r = (0, 0, pi/2): a quarter turn about z maps the reference x axis onto camera y.
  const Eigen::Vector3d x_in_camera = model.camera_from_ref.rotation * Eigen::Vector3d::UnitX();
  EXPECT_LT((x_in_camera - Eigen::Vector3d::UnitY()).norm(), 1e-15);
  EXPECT_EQ(model.camera_from_ref.translation, Eigen::Vector3d(0.1, -0.2, 0.3));
  // And the point x_ref = (1, 0, 0) lands at R x + t.
  EXPECT_LT(
      (model.camera_from_ref * Eigen::Vector3d::UnitX() - Eigen::Vector3d(0.1, 0.8, 0.3)).norm(),
      1e-15);
}

TEST(CameraModelIoTest, ReadsWhatLibmrcalItselfWrites) {
  // mrcal_write_cameramodel_file prints 6 decimals: values equal to 1e-6 only.
  const fs::path dir = hw::test::TestFolder();
  const CameraModel camera = MakeCamera(CameraModelType::kOpenCV, 8);
  const size_t size = sizeof(mrcal_cameramodel_t) + 12 * sizeof(double);
  mrcal_cameramodel_t* model = static_cast<mrcal_cameramodel_t*>(std::calloc(1, size));
  ASSERT_NE(model, nullptr);
  model->lensmodel.type = MRCAL_LENSMODEL_OPENCV8;
  model->imagersize[0] = 1280;
  model->imagersize[1] = 1024;
  const Eigen::VectorXd params = camera.Params();
  for (int i = 0; i < 12; ++i) model->intrinsics[i] = params[i];
  const double rt[6] = {0.1, -0.2, 0.3, 1.5, -2.5, 0.25};
  std::memcpy(model->rt_cam_ref, rt, sizeof(rt));
  const fs::path path = dir / "mrcal.cameramodel";
  const bool ok = mrcal_write_cameramodel_file(path.c_str(), model);
  std::free(model);
  ASSERT_TRUE(ok);
  const MrcalCameraModel back = ReadMrcalCameraModel(path);
  EXPECT_EQ(back.camera.width, 1280);
  EXPECT_LT((back.camera.Params() - params).cwiseAbs().maxCoeff(), 0.5e-6 + 1e-12);
  EXPECT_LT(
      (RodriguesFromQuaternion(back.camera_from_ref.rotation) - Eigen::Vector3d(0.1, -0.2, 0.3))
          .norm(),
      1e-12);
  EXPECT_EQ(back.camera_from_ref.translation, Eigen::Vector3d(1.5, -2.5, 0.25));
}

TEST(CameraModelIoTest, RejectsOtherLensModelsByName) {
  const std::string cahvor =
      "{'lensmodel': 'LENSMODEL_CAHVOR', 'intrinsics': [500, 500, 320, 240, 0, 0, 0, 0, 0],"
      " 'imagersize': [640, 480], 'extrinsics': [0, 0, 0, 0, 0, 0]}";
  EXPECT_EQ(ParseError(cahvor),
            "cam.cameramodel: lensmodel: LENSMODEL_CAHVOR is not supported (heatwave reads "
            "LENSMODEL_PINHOLE, LENSMODEL_OPENCV4, 5 and 8 and LENSMODEL_SPLINED_STEREOGRAPHIC)");
  const std::string opencv12 =
      "{'lensmodel': 'LENSMODEL_OPENCV12', 'intrinsics': [500, 500, 320, 240, 0, 0, 0, 0, 0, 0,"
      " 0, 0, 0, 0, 0, 0], 'imagersize': [640, 480], 'extrinsics': [0, 0, 0, 0, 0, 0]}";
  EXPECT_THAT(ParseError(opencv12), HasSubstr("lensmodel: LENSMODEL_OPENCV12 is not supported"));
  const std::string stereographic =
      "{'lensmodel': 'LENSMODEL_STEREOGRAPHIC', 'intrinsics': [500, 500, 320, 240],"
      " 'imagersize': [640, 480], 'extrinsics': [0, 0, 0, 0, 0, 0]}";
  EXPECT_THAT(ParseError(stereographic),
              HasSubstr("lensmodel: LENSMODEL_STEREOGRAPHIC is not supported"));
}

TEST(CameraModelIoTest, MalformedFilesThrowInputError) {
  const std::string good =
      "{'lensmodel': 'LENSMODEL_PINHOLE', 'intrinsics': [500, 501, 320, 240],"
      " 'imagersize': [640, 480], 'extrinsics': [0, 0, 0, 0, 0, 0]}";
  EXPECT_EQ(ParseError(good), "<no error>");
  auto replace = [&](const std::string& from, const std::string& to) {
    std::string text = good;
    const size_t at = text.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    return at == std::string::npos ? text : text.replace(at, from.size(), to);
  };
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"", "cam.cameramodel: empty file"},
      {"hello", "not a valid mrcal .cameramodel"},
      {"{", "not a valid mrcal .cameramodel"},
      {good.substr(0, good.size() - 1), "not a valid mrcal .cameramodel"},
      {replace("[500, 501, 320, 240]", "[500, 501, 320]"), "not a valid mrcal .cameramodel"},
      {replace(", 'extrinsics': [0, 0, 0, 0, 0, 0]", ""), "not a valid mrcal .cameramodel"},
      {replace("[640, 480]", "[0, 480]"), "not a valid mrcal .cameramodel"},
      {replace("[640, 480]", "[-640, 480]"), "not a valid mrcal .cameramodel"},
      {replace("LENSMODEL_PINHOLE", "LENSMODEL_FISHEYE"), "not a valid mrcal .cameramodel"},
      {replace("[500, 501, 320, 240]", "[nan, 501, 320, 240]"), "not a valid mrcal .cameramodel"},
      {good + " trailing", "not a valid mrcal .cameramodel"},
      {replace("[500, 501, 320, 240]", "[-500, 501, 320, 240]"),
       "cam.cameramodel: invalid camera: fx: must be in [1, 1e6] px, got -500"},
      {replace("[500, 501, 320, 240]", "[500, 0, 320, 240]"),
       "cam.cameramodel: invalid camera: fy: must be in [1, 1e6] px, got 0"},
      {replace("[500, 501, 320, 240]", "[500, 501, 1e999, 240]"), "cam.cameramodel: "},
      {replace("[0, 0, 0, 0, 0, 0]", "[1e999, 0, 0, 0, 0, 0]"), "cam.cameramodel: "},
      {replace("[640, 480]", "[4294967295, 480]"), "cam.cameramodel: "},
  };
  for (const auto& [text, expected] : cases) {
    SCOPED_TRACE(text);
    const std::string error = ParseError(text);
    EXPECT_THAT(error, HasSubstr(expected));
    EXPECT_EQ(error.find('\n'), std::string::npos);
  }
  const fs::path dir = hw::test::TestFolder();
  EXPECT_THROW(ReadMrcalCameraModel(dir / "missing.cameramodel"), InputError);
  std::string binary(300, '\0');
  for (size_t i = 0; i < binary.size(); ++i) binary[i] = static_cast<char>(i * 37);
  WriteFileAtomically(dir / "binary.cameramodel", binary);
  QuietStderr quiet;
  EXPECT_THROW(ReadMrcalCameraModel(dir / "binary.cameramodel"), InputError);
  EXPECT_EQ(ParseError(good + std::string(1, '\0')),
            "cam.cameramodel: NUL byte at line 1, column " + std::to_string(good.size() + 1));
}

TEST(CameraModelIoTest, RefusesAbsurdValuesWithRigYamlsRanges) {
  const std::string good =
      "{'lensmodel': 'LENSMODEL_OPENCV4', 'intrinsics': [500, 501, 320, 240, -0.3, 0.1, 0, 0],"
      " 'imagersize': [640, 480], 'extrinsics': [0, 0, 0, 0.03, 0, 0]}";
  EXPECT_EQ(ParseError(good), "<no error>");
  const auto replace = [&](const std::string& from, const std::string& to) {
    std::string text = good;
    const size_t at = text.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    return at == std::string::npos ? text : text.replace(at, from.size(), to);
  };
  const std::vector<std::pair<std::string, std::string>> cases = {
      {replace("[500, 501,", "[1e-320, 501,"),
       "cam.cameramodel: invalid camera: fx: must be in [1, 1e6] px, got 1e-320"},
      {replace("[640, 480]", "[1000000000, 480]"),
       "cam.cameramodel: invalid camera: width: must be in [1, 16384] px, got 1000000000"},
      {replace("320, 240,", "320, 1e300,"),
       "cam.cameramodel: invalid camera: cy: must be in [-height, 2 height] = [-480, 960] px, got "
       "1e300"},
      {replace("-0.3, 0.1,", "-0.3, 1e5,"),
       "cam.cameramodel: invalid camera: distortion[1]: must be in [-10000, 10000], got 1e5"},
      {replace("0.03, 0, 0]", "1e300, 0, 0]"),
       "cam.cameramodel: extrinsics: the translation must be at most 10 m long, got [1e300, 0, 0]"},
      {replace("[0, 0, 0, 0.03", "[1e300, 0, 0, 0.03"),
       "cam.cameramodel: extrinsics: the rotation (Rodrigues vector, rad) must be finite and at "
       "most 4 pi long, got [1e300, 0, 0]"},
  };
  for (const auto& [text, expected] : cases) {
    SCOPED_TRACE(text);
    EXPECT_EQ(ParseError(text), expected);
  }
  // Edges: a turn and a half, 10 m.
  EXPECT_EQ(ParseError(replace("[0, 0, 0, 0.03", "[0, 0, 9.42, 10")), "<no error>");
}

TEST(CameraModelIoTest, TextRulesAreRigYamls) {
  const std::string good =
      "# mrcal model\n{'lensmodel': 'LENSMODEL_PINHOLE',\n 'intrinsics': [500, 501, 320, 240],\n"
      " 'imagersize': [640, 480],\n 'extrinsics': [0, 0, 0, 0, 0, 0]}\n";
  // libmrcal alone refuses a byte order mark and CR-only line ends.
  for (const std::string bom : {"", "\xEF\xBB\xBF"}) {
    for (const std::string line_end : {"\n", "\r\n", "\r"}) {
      std::string text = bom;
      for (const char c : good) text += c == '\n' ? line_end : std::string(1, c);
      SCOPED_TRACE(::testing::Message()
                   << "BOM " << !bom.empty() << " CR " << (line_end[0] == '\r'));
      EXPECT_EQ(ParseError(text), "<no error>");
    }
  }
  EXPECT_EQ(ParseError("# mrcal\r\n{'lensmodel':\x01 'LENSMODEL_PINHOLE'}"),
            "cam.cameramodel: control character 0x01 at line 2, column 14");
  EXPECT_EQ(ParseError("\xFE\xFF{"),
            "cam.cameramodel: starts with a UTF-16 or UTF-32 byte order mark: save the file as "
            "UTF-8");
}

TEST(CameraModelIoTest, OversizedFilesAndFifosAreRefusedAtOnce) {
  const fs::path dir = hw::test::TestFolder();
  WriteFileAtomically(dir / "big.cameramodel", std::string(2'000'000, '#'));
  try {
    ReadMrcalCameraModel(dir / "big.cameramodel");
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(e.reason(), "file is 2000000 bytes, more than the 1 MiB this kind of file may have");
  }
  const fs::path fifo = dir / "fifo.cameramodel";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0) << std::strerror(errno);
  const int exit_code = hw::test::RunInChild(
      [&] {
        try {
          ReadMrcalCameraModel(fifo);
        } catch (const InputError& e) {
          return std::string(e.what()) == fifo.string() + ": is a FIFO, expected a regular file"
                     ? 0
                     : 2;
        }
        return 1;
      },
      10);
  EXPECT_EQ(exit_code, 0) << "1: no error, 2: another message, -1: hung";
}

TEST(CameraModelIoTest, SurvivesLibmrcalOverreads) {
  // libmrcal 2.2 scans an unterminated comment or string past the end of its input
  // (ParseWithMrcal's padding stops it); under valgrind these crashed before the padding.
  const std::string good =
      "{'lensmodel': 'LENSMODEL_PINHOLE', 'intrinsics': [500, 501, 320, 240],"
      " 'imagersize': [640, 480], 'extrinsics': [0, 0, 0, 0, 0, 0]}";
  EXPECT_EQ(ParseError(good + "\n# a last comment without a newline"), "<no error>");
  for (const std::string& text :
       {std::string("#"), std::string("# comment"), std::string("'"), std::string("{'lensmodel"),
        std::string("{'lensmodel': \"LENS"), good.substr(0, 20), std::string("{#")}) {
    SCOPED_TRACE(text);
    EXPECT_THAT(ParseError(text), HasSubstr("not a valid mrcal .cameramodel"));
  }
}

TEST(CameraModelIoTest, FuzzTruncationsAndMutations) {
  const std::string valid = FormatMrcalCameraModel(
      MakeCamera(CameraModelType::kOpenCV, 5),
      Rigid3d(Eigen::Quaterniond(0.9, 0.1, -0.2, 0.3), Eigen::Vector3d(0.1, 0.2, 0.3)));
  std::mt19937 rng(2024);
  const std::string specials = "{}[]',:#.-+eE0123456789 \n";
  int cases = 0, accepted = 0;
  QuietStderr quiet;
  for (size_t n = 0; n <= valid.size() + 1500; ++n, ++cases) {
    std::string text = valid;
    if (n <= valid.size()) {
      text.resize(n);
    } else {
      const int edits = 1 + static_cast<int>(rng() % 3);
      for (int e = 0; e < edits; ++e) {
        const size_t at = rng() % text.size();
        const char c =
            rng() % 4 == 0 ? static_cast<char>(rng() % 256) : specials[rng() % specials.size()];
        if (rng() % 2 == 0) {
          text[at] = c;
        } else {
          text.erase(at, 1);
        }
      }
    }
    try {
      const MrcalCameraModel model = ParseMrcalCameraModel(text, "fuzz.cameramodel");
      ASSERT_EQ(model.camera.Check(), "");
      ASSERT_TRUE(model.camera_from_ref.rotation.coeffs().allFinite());
      ++accepted;
    } catch (const InputError& e) {
      // One line, whatever bytes the fuzz put in.
      const std::string what = e.what();
      ASSERT_TRUE(std::none_of(what.begin(), what.end(), [](char c) {
        return static_cast<unsigned char>(c) < 0x20;
      })) << what;
    }
  }
  EXPECT_GT(accepted, 10);
  EXPECT_LT(accepted, cases / 2);
}

TEST(CameraModelIoTest, RoundTripsASplinedCamera) {
  const fs::path dir = hw::test::TestFolder();
  CameraModel camera = test::SplinedTestCamera();
  camera.distortion[3] = 1.0 / 3.0 * 1e-2;  // all 17 digits
  EXPECT_EQ(MrcalLensModelName(camera),
            "LENSMODEL_SPLINED_STEREOGRAPHIC_order=3_Nx=16_Ny=13_fov_x_deg=80");
  const Rigid3d extrinsics(Eigen::Quaterniond(0.9, -0.1, 0.3, 1e-9).normalized(),
                           Eigen::Vector3d(0.03, -0.25, 0.001));
  WriteMrcalCameraModel(dir / "splined.cameramodel", camera, extrinsics);
  const MrcalCameraModel back = ReadMrcalCameraModel(dir / "splined.cameramodel");
  EXPECT_TRUE(back.camera == camera);  // type, config, every control bit for bit
  EXPECT_EQ(back.camera.splined, camera.splined);
  EXPECT_EQ(back.camera.Params(), camera.Params());
}

TEST(CameraModelIoTest, ReadsSplinedModelsAndRefusesBadConfigsByField) {
  const auto text = [](const std::string& config, int num_controls) {
    std::string intrinsics = "[500, 500, 320, 240";
    for (int i = 0; i < num_controls; ++i) intrinsics += i % 3 == 0 ? ", 1e-3" : ", 0";
    return "{'lensmodel': 'LENSMODEL_SPLINED_STEREOGRAPHIC_" + config + "', 'intrinsics': " +
           intrinsics + "], 'imagersize': [640, 480], 'extrinsics': [0, 0, 0, 0, 0, 0]}";
  };
  const MrcalCameraModel model = ParseMrcalCameraModel(
      text("order=2_Nx=5_Ny=4_fov_x_deg=90", 40), "cam.cameramodel");
  EXPECT_EQ(model.camera.type, CameraModelType::kSplined);
  EXPECT_EQ(model.camera.splined, (SplinedConfig{2, 5, 4, 90}));
  EXPECT_EQ(model.camera.distortion.size(), 40u);
  EXPECT_EQ(model.camera.distortion[3], 1e-3);
  EXPECT_THAT(ParseError(text("order=3_Nx=3_Ny=4_fov_x_deg=90", 24)),
              HasSubstr("invalid camera: splined.nx: must be in [4, 64], got 3"));
  EXPECT_THAT(ParseError(text("order=3_Nx=5_Ny=100_fov_x_deg=90", 1000)),
              HasSubstr("invalid camera: splined.ny: must be in [4, 64], got 100"));
  EXPECT_THAT(ParseError(text("order=1_Nx=5_Ny=4_fov_x_deg=90", 40)),
              HasSubstr("invalid camera: splined.order: must be 2 or 3, got 1"));
  EXPECT_THAT(ParseError(text("order=3_Nx=5_Ny=4_fov_x_deg=200", 40)),
              HasSubstr("invalid camera: splined.fov_x_deg: must be in [1, 179] degrees, got 200"));
}

}  // namespace
}  // namespace hw::core
