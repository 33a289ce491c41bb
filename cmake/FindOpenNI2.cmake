# Finds OpenNI2 (Debian's libopenni2-dev ships no CMake file; its pkg-config file
# is not always installed). Defines the imported target OpenNI2::OpenNI2.
find_path(OpenNI2_INCLUDE_DIR NAMES OpenNI.h PATH_SUFFIXES openni2)
find_library(OpenNI2_LIBRARY NAMES OpenNI2)
include(FindPackageHandleStandardArgs)
find_package_handle_standard_args(OpenNI2 REQUIRED_VARS OpenNI2_LIBRARY OpenNI2_INCLUDE_DIR)
if(OpenNI2_FOUND AND NOT TARGET OpenNI2::OpenNI2)
  add_library(OpenNI2::OpenNI2 UNKNOWN IMPORTED)
  set_target_properties(OpenNI2::OpenNI2 PROPERTIES
    IMPORTED_LOCATION "${OpenNI2_LIBRARY}"
    INTERFACE_INCLUDE_DIRECTORIES "${OpenNI2_INCLUDE_DIR}")
endif()
mark_as_advanced(OpenNI2_INCLUDE_DIR OpenNI2_LIBRARY)
