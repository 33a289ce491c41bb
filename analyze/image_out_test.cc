#include "analyze/image_out.h"

#include <cmath>
#include <limits>
#include <memory>

#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>

#include "core/atomic_file.h"
#include "core/error.h"
#include "tests/support.h"

namespace hw::analyze {
namespace {

namespace fs = std::filesystem;
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

struct ReadBack {
  OIIO::ImageSpec spec;
  std::vector<float> floats;
  std::vector<std::uint8_t> bytes;
};

ReadBack Read(const fs::path& path, bool as_float) {
  ReadBack r;
  std::unique_ptr<OIIO::ImageInput> in = OIIO::ImageInput::open(path.string());
  EXPECT_TRUE(in) << OIIO::geterror();
  if (!in) return r;
  r.spec = in->spec();
  const size_t n = static_cast<size_t>(r.spec.width * r.spec.height * r.spec.nchannels);
  if (as_float) {
    r.floats.resize(n);
    EXPECT_TRUE(in->read_image(0, 0, 0, r.spec.nchannels, OIIO::TypeDesc::FLOAT, r.floats.data()));
  } else {
    r.bytes.resize(n);
    EXPECT_TRUE(in->read_image(0, 0, 0, r.spec.nchannels, OIIO::TypeDesc::UINT8, r.bytes.data()));
  }
  in->close();
  return r;
}

TEST(ImageOutTest, PngRoundTrip) {
  ImageRgb8 image;
  image.width = 3;
  image.height = 2;
  for (int i = 0; i < 18; ++i) image.rgb.push_back(static_cast<std::uint8_t>(i * 14 + 3));
  const fs::path path = hw::test::TestFolder() / "view.png";
  WritePng(path, image);
  const ReadBack r = Read(path, false);
  EXPECT_EQ(r.spec.width, 3);
  EXPECT_EQ(r.spec.height, 2);
  EXPECT_EQ(r.spec.nchannels, 3);
  EXPECT_EQ(r.bytes, image.rgb);
}

TEST(ImageOutTest, FloatImagesKeepNaNAndUnits) {
  const std::vector<float> values = {21.25f, kNaN, -3.5f, 1e-3f, kNaN, 78.125f};
  for (const char* name : {"t.exr", "t.tif", "t.TIFF"}) {
    const fs::path path = hw::test::TestFolder() / name;
    WriteFloatImage(path, 3, 2, values, "°C");
    const ReadBack r = Read(path, true);
    ASSERT_EQ(r.floats.size(), values.size()) << name;
    EXPECT_EQ(r.spec.nchannels, 1);
    EXPECT_EQ(r.spec.format, OIIO::TypeDesc::FLOAT) << name;  // 32-bit, not half
    for (size_t i = 0; i < values.size(); ++i) {
      if (std::isnan(values[i])) {
        EXPECT_TRUE(std::isnan(r.floats[i])) << name << " " << i;
      } else {
        EXPECT_EQ(r.floats[i], values[i]) << name << " " << i;
      }
    }
    EXPECT_EQ(r.spec.get_string_attribute("ImageDescription"),
              "°C; NaN = no value (unobserved surface or background)")
        << name;
  }
}

TEST(ImageOutTest, FailureThrowsAndLeavesNoFile) {
  const fs::path folder = hw::test::TestFolder();
  // The parent "folder" is a regular file: the folder cannot be created.
  core::WriteFileAtomically(folder / "blocker", "x");
  const fs::path under_file = folder / "blocker" / "view.png";
  ImageRgb8 image;
  image.width = image.height = 1;
  image.rgb = {1, 2, 3};
  try {
    WritePng(under_file, image);
    FAIL() << "no error";
  } catch (const core::OutputError& e) {
    EXPECT_EQ(e.path(), under_file);
  }
  // The target is an existing folder: the rename fails, the temporary is removed.
  fs::create_directory(folder / "t.exr");
  EXPECT_THROW(WriteFloatImage(folder / "t.exr", 1, 1, {kNaN}, "K"), core::OutputError);
  int entries = 0;
  for ([[maybe_unused]] const auto& entry : fs::directory_iterator(folder)) ++entries;
  EXPECT_EQ(entries, 2);  // blocker and the folder t.exr, nothing else
  EXPECT_TRUE(fs::is_empty(folder / "t.exr"));
}

}  // namespace
}  // namespace hw::analyze
