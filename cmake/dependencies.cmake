# Every external dependency of heatwave, found in one place. All come from Debian 12
# packages installed by scripts/install-deps.sh; README.md says why each is here.

find_package(Threads REQUIRED)
find_package(Eigen3 3.4 REQUIRED NO_MODULE)
find_package(yaml-cpp 0.7 REQUIRED)
find_package(CLI11 2 REQUIRED)
# aruco and ximgproc come from opencv_contrib (libopencv-contrib-dev).
find_package(OpenCV 4.6 REQUIRED COMPONENTS core imgproc imgcodecs calib3d aruco ximgproc)
find_package(Ceres 2.1 REQUIRED)
find_package(Mrcal REQUIRED)
find_package(embree 3.13 REQUIRED)
find_package(OpenImageIO 2.4 REQUIRED)
# nanoflann::nanoflann: header-only k-d trees (analyze/).
find_package(nanoflann 1.4 REQUIRED)
# libpng directly (core/image_io.cc): its error handlers are ours, so no decoder prints.
find_package(PNG 1.6 REQUIRED)
find_package(OpenNI2 REQUIRED)
# report/: nlohmann_json::nlohmann_json reads analyze.json and reconstruct.json;
# meshoptimizer::meshoptimizer decimates the model embedded in the HTML report.
find_package(nlohmann_json 3.11 REQUIRED)
find_package(meshoptimizer 0.18 REQUIRED)
# ZLIB::ZLIB deflates the model embedded in the HTML report (the page inflates it with
# the browser's DecompressionStream).
find_package(ZLIB REQUIRED)
find_package(GTest 1.12 REQUIRED)
# absl::flat_hash_map: the TSDF's block hash (reconstruct/tsdf_volume_impl.h).
find_package(absl REQUIRED)

find_package(PkgConfig REQUIRED)
pkg_check_modules(apriltag REQUIRED IMPORTED_TARGET apriltag>=3.3)
pkg_check_modules(libusb REQUIRED IMPORTED_TARGET libusb-1.0>=1.0.26)
# capture/: libuvc streams the thermal camera (USB video class, Y16 frames); Debian's
# libuvc-dev ships a pkg-config file.
pkg_check_modules(libuvc REQUIRED IMPORTED_TARGET libuvc>=0.0.6)
pkg_check_modules(cairo REQUIRED IMPORTED_TARGET cairo>=1.16 cairo-pdf)
pkg_check_modules(pangocairo REQUIRED IMPORTED_TARGET pangocairo>=1.50)
# CHOLMOD (SuiteSparse, a dependency of mrcal): calibrate/ reads the sparse Jacobian that
# mrcal_optimizer_callback returns as a cholmod_sparse. Debian ships no CMake or pkg-config
# file for it.
find_path(CHOLMOD_INCLUDE_DIR NAMES cholmod.h PATH_SUFFIXES suitesparse REQUIRED)
find_library(CHOLMOD_LIBRARY NAMES cholmod REQUIRED)
if(NOT TARGET SuiteSparse::CHOLMOD)
  add_library(SuiteSparse::CHOLMOD UNKNOWN IMPORTED)
  set_target_properties(SuiteSparse::CHOLMOD PROPERTIES
    IMPORTED_LOCATION "${CHOLMOD_LIBRARY}"
    INTERFACE_INCLUDE_DIRECTORIES "${CHOLMOD_INCLUDE_DIR}")
endif()
