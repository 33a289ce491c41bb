#include "core/cameramodel_io.h"

#include <array>
#include <cassert>
#include <charconv>
#include <climits>
#include <cmath>
#include <cstdlib>
#include <memory>
#include <numbers>
#include <string>
#include <system_error>
#include <vector>

#include "core/atomic_file.h"
#include "core/error.h"
#include "core/camera_mrcal.h"
#include "core/mrcal_c.h"
#include "core/rig.h"
#include "core/yaml_reader.h"

namespace hw::core {
namespace {

namespace fs = std::filesystem;

// Shortest text that reads back (strtod, as mrcal's parser does) to the same double.
std::string FormatNumber(double value) {
  assert(std::isfinite(value));
  std::array<char, 64> buffer{};
  const auto [end, ec] = std::to_chars(buffer.data(), buffer.data() + buffer.size(), value);
  assert(ec == std::errc());
  return std::string(buffer.data(), end);
}

std::string FormatList(const double* values, int count) {
  std::string text = "[ ";
  for (int i = 0; i < count; ++i) {
    if (i > 0) text += ", ";
    text += FormatNumber(values[i]);
  }
  return text + " ]";
}

struct MrcalModelFree {
  void operator()(mrcal_cameramodel_t* model) const { mrcal_free_cameramodel(&model); }
};
using MrcalModelPtr = std::unique_ptr<mrcal_cameramodel_t, MrcalModelFree>;

mrcal_lensmodel_type_t MrcalLensModelType(const CameraModel& camera) {
  const mrcal_lensmodel_t lensmodel = MrcalLensModel(camera);
  assert(lensmodel.type != MRCAL_LENSMODEL_INVALID &&
         "camera has no mrcal lens model; CameraModel::Check() should have said so");
  return lensmodel.type;
}

// The configured name of any mrcal lens model, for messages.
std::string LensModelName(const mrcal_lensmodel_t& lensmodel) {
  std::array<char, 256> name{};
  if (mrcal_lensmodel_name(name.data(), static_cast<int>(name.size()), &lensmodel)) {
    return name.data();
  }
  const char* unconfigured = mrcal_lensmodel_name_unconfigured(&lensmodel);
  return unconfigured != nullptr ? unconfigured : "unknown";
}

// libmrcal 2.2's parser does not stop at the terminating 0 in two of its patterns: a
// '#' comment runs to the next '\n' and a quoted string to the next quote, wherever in
// memory they are (mrcal_read_cameramodel_string("#", 1) segfaults; valgrind shows the
// over-reads; newer mrcal excludes \x00 there). Elsewhere it may read one byte past the 0
// before failing. So mrcal gets the text with a '\n' appended (ends a
// final comment; harmless otherwise), the 0, a quote of each kind (ends a runaway string,
// after which the parser fails on the quote that follows) and zeros for the one-byte
// over-reads. Length 0 tells mrcal to read up to the first 0.
constexpr char kMrcalTerminator[] = "\n\0'\"\0\0\0\0\0\0\0";

// mrcal's parser on `text`; nullptr when it rejects it (it then prints why to stderr).
// `text` must hold no 0 byte.
MrcalModelPtr ParseWithMrcal(const std::string& text) {
  assert(!text.empty() && text.find('\0') == std::string::npos);
  std::string padded = text;
  padded.append(kMrcalTerminator, sizeof(kMrcalTerminator));
  return MrcalModelPtr(mrcal_read_cameramodel_string(padded.c_str(), 0));
}

// "" when mrcal's extrinsics are plausible, else a message: r finite with |r| <= 4 pi
// (mrcal's solver leaves r within a turn or so of 0; at 1e300 rad the rotation is
// arbitrary, every bit of the angle lost to cos/sin's argument reduction) and t as rig.yaml's
// extrinsic translations (CheckExtrinsicTranslation, rig.h: at most 10 m).
std::string CheckMrcalExtrinsics(const Eigen::Vector3d& r, const Eigen::Vector3d& t) {
  constexpr double kMaxRotationRad = 4 * std::numbers::pi;
  if (!(r.norm() <= kMaxRotationRad)) {
    return "extrinsics: the rotation (Rodrigues vector, rad) must be finite and at most 4 pi "
           "long, got [" +
           MessageNumber(r.x()) + ", " + MessageNumber(r.y()) + ", " + MessageNumber(r.z()) + "]";
  }
  if (const std::string problem = CheckExtrinsicTranslation(t); !problem.empty()) {
    return "extrinsics: the translation " + problem;
  }
  return "";
}

}  // namespace

Eigen::Vector3d RodriguesFromQuaternion(const Eigen::Quaterniond& q_in) {
  assert(q_in.norm() > 0);
  // q and -q are the same rotation: pick w >= 0 so that the angle is in [0, pi].
  const Eigen::Quaterniond q = q_in.w() < 0 ? Eigen::Quaterniond(-q_in.coeffs()) : q_in;
  const double sin_half = q.vec().stableNorm();  // |q| sin(angle / 2)
  // angle = 2 atan2(|v|, w) is accurate everywhere (acos(w) is not near 0 and asin(|v|) is
  // not near pi). r = v / |v| * angle; for |v| -> 0, angle / |v| -> 2 / w with no
  // cancellation, so tiny rotations keep full relative precision.
  const double scale = sin_half > 0 ? 2.0 * std::atan2(sin_half, q.w()) / sin_half : 2.0 / q.w();
  return q.vec() * scale;
}

Eigen::Quaterniond QuaternionFromRodrigues(const Eigen::Vector3d& r) {
  // stableNorm: squaring a 1e-200 rad vector would underflow to a zero angle.
  const double angle = r.stableNorm();
  if (angle == 0) return Eigen::Quaterniond::Identity();
  // Eigen's AngleAxis -> quaternion: (cos(angle / 2), sin(angle / 2) * axis). r / angle is
  // an exact-enough unit axis even for tiny angles (a ratio, not a difference).
  return Eigen::Quaterniond(Eigen::AngleAxisd(angle, r / angle));
}

std::string MrcalLensModelName(const CameraModel& camera) {
  assert(camera.Check().empty());
  const mrcal_lensmodel_t lensmodel = MrcalLensModel(camera);
  assert(lensmodel.type != MRCAL_LENSMODEL_INVALID);
  // "LENSMODEL_SPLINED_STEREOGRAPHIC_order=3_Nx=64_Ny=64_fov_x_deg=179" is 66 characters.
  std::array<char, 128> name{};
  const bool ok = mrcal_lensmodel_name(name.data(), static_cast<int>(name.size()), &lensmodel);
  assert(ok);
  (void)ok;
  return name.data();
}

std::string FormatMrcalCameraModel(const CameraModel& camera, const Rigid3d& camera_from_ref) {
  assert(camera.Check().empty());
  assert(CheckExtrinsicTranslation(camera_from_ref.translation).empty());
  const Eigen::VectorXd intrinsics = camera.Params();
  std::array<double, 6> rt{};
  const Eigen::Vector3d r = RodriguesFromQuaternion(camera_from_ref.rotation);
  for (int i = 0; i < 3; ++i) {
    rt[i] = r[i];
    rt[3 + i] = camera_from_ref.translation[i];
  }
  std::string text;
  text += "# mrcal camera model, written by heatwave\n";
  text += "{\n";
  text += "    'lensmodel':  '" + MrcalLensModelName(camera) + "',\n";
  text += "    # intrinsics are fx,fy,cx,cy,distortion0,distortion1,....\n";
  text +=
      "    'intrinsics': " + FormatList(intrinsics.data(), static_cast<int>(intrinsics.size())) +
      ",\n";
  text += "    # extrinsics are rt_cam_ref: Rodrigues rotation (rad), then translation (m)\n";
  text += "    'extrinsics': " + FormatList(rt.data(), 6) + ",\n";
  text += "    'imagersize': [ " + std::to_string(camera.width) + ", " +
          std::to_string(camera.height) + " ]\n";
  text += "}\n";

  // Whatever we write, libmrcal must read back exactly; anything else is a bug here.
  const MrcalModelPtr check = ParseWithMrcal(text);
  assert(check != nullptr);
  assert(check->lensmodel.type == MrcalLensModelType(camera));
  assert(LensModelName(check->lensmodel) == MrcalLensModelName(camera));
  assert(check->imagersize[0] == static_cast<unsigned>(camera.width));
  for (int i = 0; i < intrinsics.size(); ++i) assert(check->intrinsics[i] == intrinsics[i]);
  for (int i = 0; i < 6; ++i) assert(check->rt_cam_ref[i] == rt[i]);
  (void)check;
  return text;
}

void WriteMrcalCameraModel(const fs::path& path, const CameraModel& camera,
                           const Rigid3d& camera_from_ref) {
  WriteFileAtomically(path, FormatMrcalCameraModel(camera, camera_from_ref));
}

MrcalCameraModel ParseMrcalCameraModel(const std::string& raw_text,
                                       const fs::path& path_for_errors) {
  const fs::path& path = path_for_errors;
  // The same text rules as rig.yaml: BOM dropped, line ends made LF (libmrcal takes neither
  // a BOM nor CR-only lines), NUL and control characters refused with their position.
  const std::string text = PrepareConfigText(raw_text, path);
  if (text.empty()) ThrowInputError(path, "empty file, expected an mrcal .cameramodel");
  const MrcalModelPtr model = ParseWithMrcal(text);
  if (model == nullptr) {
    ThrowInputError(path,
                    "not a valid mrcal .cameramodel (libmrcal's parser rejected it; its "
                    "reason is on stderr)");
  }

  MrcalCameraModel result;
  CameraModel& camera = result.camera;
  int num_distortion = 0;
  switch (model->lensmodel.type) {
    case MRCAL_LENSMODEL_PINHOLE:
      camera.type = CameraModelType::kPinhole;
      break;
    case MRCAL_LENSMODEL_OPENCV4:
      camera.type = CameraModelType::kOpenCV;
      num_distortion = 4;
      break;
    case MRCAL_LENSMODEL_OPENCV5:
      camera.type = CameraModelType::kOpenCV;
      num_distortion = 5;
      break;
    case MRCAL_LENSMODEL_OPENCV8:
      camera.type = CameraModelType::kOpenCV;
      num_distortion = 8;
      break;
    case MRCAL_LENSMODEL_SPLINED_STEREOGRAPHIC: {
      const auto& config = model->lensmodel.LENSMODEL_SPLINED_STEREOGRAPHIC__config;
      camera.type = CameraModelType::kSplined;
      camera.splined = {config.order, config.Nx, config.Ny, config.fov_x_deg};
      // Before the parameter count is trusted: the config's ranges (Nx = 0 would make no
      // parameters at all).
      if (const std::string problem = camera.splined.Check(); !problem.empty()) {
        ThrowInputError(path, "invalid camera: " + problem + " (lensmodel " +
                                  LensModelName(model->lensmodel) + ")");
      }
      num_distortion = camera.splined.NumControls();
      break;
    }
    default:
      ThrowInputError(path, "lensmodel: " + LensModelName(model->lensmodel) +
                                " is not supported (heatwave reads LENSMODEL_PINHOLE, "
                                "LENSMODEL_OPENCV4, 5 and 8 and "
                                "LENSMODEL_SPLINED_STEREOGRAPHIC)");
  }
  // mrcal sized intrinsics[] for its model; ours has the same count.
  assert(mrcal_lensmodel_num_params(&model->lensmodel) == 4 + num_distortion);

  // CameraModel::Check bounds the size far lower; this keeps the conversion to int exact.
  for (int i = 0; i < 2; ++i) {
    if (model->imagersize[i] > static_cast<unsigned>(INT_MAX)) {
      ThrowInputError(path,
                      "imagersize: " + std::to_string(model->imagersize[i]) + " is too large");
    }
  }
  camera.width = static_cast<int>(model->imagersize[0]);
  camera.height = static_cast<int>(model->imagersize[1]);
  Eigen::VectorXd params(4 + num_distortion);
  for (int i = 0; i < params.size(); ++i) params[i] = model->intrinsics[i];
  camera.distortion.resize(num_distortion);
  camera.SetParams(params);
  // The ranges of rig.yaml's cameras (camera.h): a calibration heatwave imports must be one
  // it could write into a rig.
  if (const std::string problem = camera.Check(); !problem.empty()) {
    ThrowInputError(path, "invalid camera: " + problem);
  }

  Eigen::Vector3d r, t;
  for (int i = 0; i < 3; ++i) {
    r[i] = model->rt_cam_ref[i];
    t[i] = model->rt_cam_ref[3 + i];
  }
  if (const std::string problem = CheckMrcalExtrinsics(r, t); !problem.empty()) {
    ThrowInputError(path, problem);
  }
  result.camera_from_ref.rotation = QuaternionFromRodrigues(r);
  result.camera_from_ref.translation = t;
  return result;
}

MrcalCameraModel ReadMrcalCameraModel(const fs::path& path) {
  return ParseMrcalCameraModel(ReadFile(path, kMaxConfigFileBytes), path);
}

}  // namespace hw::core
