#include "core/image_io.h"

#include <sys/resource.h>
#include <sys/stat.h>

#include <chrono>
#include <csignal>
#include <filesystem>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "core/atomic_file.h"
#include "core/error.h"
#include "core/interrupt.h"
#include "core/png_test_support.h"
#include "tests/support.h"

namespace hw::core {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

cv::Mat RandomImage(int rows, int cols, int type, uint64_t seed) {
  cv::Mat image(rows, cols, type);
  cv::RNG rng(seed);
  rng.fill(image, cv::RNG::UNIFORM, 0, CV_MAT_DEPTH(type) == CV_16U ? 65535 : 255);
  return image;
}

bool Equal(const cv::Mat& a, const cv::Mat& b) {
  return a.size() == b.size() && a.type() == b.type() && cv::norm(a, b, cv::NORM_INF) == 0;
}

TEST(ImageIo, PngRoundTripsEveryLayoutInFileChannelOrder) {
  const cv::Mat depth = RandomImage(48, 64, CV_16UC1, 1);
  EXPECT_TRUE(Equal(DecodeImage(EncodeImage(depth, ".png", "d.png"), "d.png"), depth));
  const cv::Mat grey = RandomImage(48, 64, CV_8UC1, 2);
  EXPECT_TRUE(Equal(DecodeImage(EncodeImage(grey, ".png", "g.png"), "g.png"), grey));
  // OpenCV encodes BGR(A); the file holds RGB(A), which is what DecodeImage returns.
  const cv::Mat bgr = RandomImage(48, 64, CV_8UC3, 3);
  cv::Mat rgb;
  cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
  EXPECT_TRUE(Equal(DecodeImage(EncodeImage(bgr, ".png", "c.png"), "c.png"), rgb));
  const cv::Mat bgra = RandomImage(8, 8, CV_8UC4, 4);
  cv::Mat rgba;
  cv::cvtColor(bgra, rgba, cv::COLOR_BGRA2RGBA);
  EXPECT_TRUE(Equal(DecodeImage(EncodeImage(bgra, ".png", "a.png"), "a.png"), rgba));
  const cv::Mat rgb16 = RandomImage(8, 8, CV_16UC3, 5);
  const cv::Mat decoded16 = DecodeImage(EncodeImage(rgb16, ".png", "c16.png"), "c16.png");
  ASSERT_EQ(decoded16.type(), CV_16UC3);
  EXPECT_EQ(decoded16.at<cv::Vec3w>(3, 4)[0], rgb16.at<cv::Vec3w>(3, 4)[2]);
}

TEST(ImageIo, TiffAndJpegDecode) {
  cv::Mat apparent_c(24, 32, CV_32FC1);
  cv::randu(apparent_c, -40.0, 500.0);
  EXPECT_TRUE(Equal(DecodeImage(EncodeImage(apparent_c, ".tiff", "t.tiff"), "t.tiff"), apparent_c));
  const cv::Mat raw = RandomImage(24, 32, CV_16UC1, 6);
  EXPECT_TRUE(Equal(DecodeImage(EncodeImage(raw, ".tiff", "r.tiff"), "r.tiff"), raw));
  const cv::Mat flat(40, 48, CV_8UC3, cv::Scalar(30, 120, 200));  // BGR
  const cv::Mat jpeg = DecodeImage(EncodeImage(flat, ".jpg", "c.jpg"), "c.jpg");
  ASSERT_EQ(jpeg.type(), CV_8UC3);
  const cv::Vec3b pixel = jpeg.at<cv::Vec3b>(20, 20);
  EXPECT_NEAR(pixel[0], 200, 3);  // R
  EXPECT_NEAR(pixel[2], 30, 3);   // B
}

TEST(ImageIo, HeaderIsCheckedBeforeDecompression) {
  // 30000 x 30000 x 16 bit = 1.8 GB decoded; the header alone must decide.
  const std::string bomb = hw::test::PngClaiming(30000, 30000, 2);
  const ImageHeader header = DecodeImageHeader(bomb, "bomb.png");
  EXPECT_EQ(header.format, "PNG");
  EXPECT_EQ(header.width, 30000);
  EXPECT_EQ(header.height, 30000);
  EXPECT_EQ(header.type(), CV_16UC1);
  const auto start = std::chrono::steady_clock::now();
  bool check_ran = false;
  try {
    DecodeImage(bomb, "bomb.png", [&](const ImageHeader& h) {
      check_ran = true;
      if (h.width != 640) throw InputError("bomb.png", "image is not 640 wide");
    });
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(e.reason(), "image is not 640 wide");
  }
  EXPECT_TRUE(check_ran);
  // Without a caller's check the built-in cap still refuses it before allocating.
  try {
    DecodeImage(bomb, "bomb.png");
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_THAT(e.reason(), HasSubstr("30000x30000"));
    EXPECT_THAT(e.reason(), HasSubstr("not decoded"));
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_LT(seconds, 1.0);  // decoding would take ~20 s and 1.8 GB
}

TEST(ImageIo, CorruptFilesAreOneLineErrorsAndPrintNothing) {
  const std::string png = EncodeImage(RandomImage(48, 64, CV_16UC1, 7), ".png", "x.png");
  cv::Mat apparent_c(24, 32, CV_32FC1, cv::Scalar(21.5));
  const std::string tiff = EncodeImage(apparent_c, ".tiff", "x.tiff");
  const std::string jpeg = EncodeImage(RandomImage(48, 64, CV_8UC3, 8), ".jpg", "x.jpg");
  std::string bad_crc = png;
  bad_crc[40] = static_cast<char>(bad_crc[40] ^ 0x55);  // inside IDAT
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"empty", ""},
      {"garbage", "this is not an image at all"},
      {"png cut in the header", png.substr(0, 20)},
      {"png cut in the data", png.substr(0, png.size() / 2)},
      {"png without IEND", png.substr(0, png.size() - 12)},
      {"png bad crc", bad_crc},
      {"tiff cut", tiff.substr(0, 200)},
      {"tiff header only", tiff.substr(0, 8)},
      {"jpeg header only", jpeg.substr(0, 4)},
  };
  for (const auto& [name, bytes] : cases) {
    ::testing::internal::CaptureStderr();
    try {
      DecodeImage(bytes, "frame.img");
      ADD_FAILURE() << name << ": expected InputError";
    } catch (const InputError& e) {
      EXPECT_EQ(e.path(), fs::path("frame.img")) << name;
      EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << name << ": " << e.what();
    }
    // libpng's and libtiff's own handlers print to stderr; ours must not.
    EXPECT_EQ(::testing::internal::GetCapturedStderr(), "") << name;
  }
}

TEST(ImageIo, ReadImageRefusesSpecialFilesAndOversizedFiles) {
  const fs::path dir = hw::test::TestFolder();
  ASSERT_EQ(::mkfifo((dir / "fifo.png").c_str(), 0644), 0);
  const int code = hw::test::RunInChild([&] {
    try {
      ReadImage(dir / "fifo.png");
    } catch (const InputError& e) {
      return std::string(e.reason()).find("FIFO") != std::string::npos ? 0 : 1;
    }
    return 2;
  });
  EXPECT_EQ(code, 0) << (code == hw::test::kTimedOut ? "hung on a FIFO" : "wrong outcome");
}

// A file size limit makes writes fail exactly as a full disk does (EFBIG instead of
// ENOSPC), at a byte position we choose: past the stdio buffer, so that only the final
// flush at close fails — the case cv::imwrite reports as success.
TEST(ImageIo, FullDiskLeavesNoFileUnderTheFinalName) {
  const fs::path dir = hw::test::TestFolder();
  const cv::Mat image = RandomImage(480, 640, CV_16UC1, 9);
  const size_t encoded = EncodeImage(image, ".png", "x.png").size();
  ASSERT_GT(encoded, 20000u);
  const int code = hw::test::RunInChild([&] {
    InstallInterruptHandlers();  // ignores SIGXFSZ
    rlimit limit{};
    limit.rlim_cur = encoded - 100;
    limit.rlim_max = RLIM_INFINITY;
    if (::setrlimit(RLIMIT_FSIZE, &limit) != 0) return 10;
    try {
      WriteImageAtomically(dir / "depth.png", image);
      return 11;  // reported success
    } catch (const OutputError& e) {
      return std::string(e.what()).find("depth.png") != std::string::npos ? 0 : 12;
    }
  });
  EXPECT_EQ(code, 0);
  EXPECT_FALSE(fs::exists(dir / "depth.png"));
  EXPECT_TRUE(fs::is_empty(dir)) << "a temporary was left behind";
}

}  // namespace
}  // namespace hw::core
