#include "calibrate/image_source.h"

#include <opencv2/imgcodecs.hpp>

#include <gtest/gtest.h>

#include "core/atomic_file.h"
#include "core/error.h"
#include "tests/support.h"

namespace hw::calibrate {
namespace {

namespace fs = std::filesystem;

std::string ErrorOf(const fs::path& path, core::Stream stream = core::Stream::kRgb) {
  try {
    LoadCalibrationImages(path, stream);
  } catch (const core::InputError& e) {
    return e.what();
  }
  return "";
}

TEST(ImageSourceTest, FolderOfMixedFormatsSortedAndOneChannel) {
  const fs::path folder = hw::test::TestFolder();
  cv::Mat colour(48, 64, CV_8UC3, cv::Scalar(10, 20, 200));  // BGR: red
  cv::imwrite((folder / "b.png").string(), colour);
  cv::imwrite((folder / "a.JPG").string(), colour);
  cv::imwrite((folder / "c.bmp").string(), colour);
  cv::Mat raw(48, 64, CV_16UC1, cv::Scalar(30000));
  cv::imwrite((folder / "d.tiff").string(), raw);
  core::WriteFileAtomically(folder / "notes.txt", "not an image");
  const std::vector<CalibrationImage> images = LoadCalibrationImages(folder, core::Stream::kRgb);
  ASSERT_EQ(images.size(), 4u);
  EXPECT_EQ(images[0].name, "a.JPG");
  EXPECT_EQ(images[3].name, "d.tiff");
  for (const CalibrationImage& im : images) EXPECT_EQ(im.image.channels(), 1) << im.name;
  // Luma of pure-ish red: 0.299 R + 0.587 G + 0.114 B = 0.299·200 + 0.587·20 + 0.114·10 ≈ 73.
  EXPECT_NEAR(images[1].image.at<uint8_t>(5, 5), 73, 1);  // PNG: exact
  EXPECT_NEAR(images[2].image.at<uint8_t>(5, 5), 73, 1);  // BMP, read in BGR order
  EXPECT_EQ(images[3].image.type(), CV_16UC1);
  EXPECT_EQ(images[3].image.at<uint16_t>(5, 5), 30000);
}

TEST(ImageSourceTest, BadFoldersAreOneLineNamingTheFile) {
  const fs::path folder = hw::test::TestFolder();
  EXPECT_NE(ErrorOf(folder).find("holds no image"), std::string::npos);
  cv::imwrite((folder / "a.png").string(), cv::Mat(48, 64, CV_8UC1, cv::Scalar(1)));
  cv::imwrite((folder / "b.png").string(), cv::Mat(24, 32, CV_8UC1, cv::Scalar(1)));
  EXPECT_EQ(ErrorOf(folder), (folder / "b.png").string() +
                                 ": is 32x24, a.png 64x48: images of one camera have one size");
  fs::remove(folder / "b.png");
  core::WriteFileAtomically(folder / "c.png", "not a png");
  EXPECT_NE(ErrorOf(folder).find((folder / "c.png").string()), std::string::npos);
  EXPECT_NE(ErrorOf(folder / "missing").find("not a folder"), std::string::npos);
}

}  // namespace
}  // namespace hw::calibrate
