# Finds mrcal's C library. Debian's libmrcal-dev ships neither a CMake nor a
# pkg-config file. Defines the imported target Mrcal::mrcal.
# mrcal's headers lack extern "C": include them through core/mrcal_c.h only.
find_path(Mrcal_INCLUDE_DIR NAMES mrcal/mrcal.h)
find_library(Mrcal_LIBRARY NAMES mrcal)
include(FindPackageHandleStandardArgs)
find_package_handle_standard_args(Mrcal REQUIRED_VARS Mrcal_LIBRARY Mrcal_INCLUDE_DIR)
if(Mrcal_FOUND AND NOT TARGET Mrcal::mrcal)
  add_library(Mrcal::mrcal UNKNOWN IMPORTED)
  set_target_properties(Mrcal::mrcal PROPERTIES
    IMPORTED_LOCATION "${Mrcal_LIBRARY}"
    INTERFACE_INCLUDE_DIRECTORIES "${Mrcal_INCLUDE_DIR}")
endif()
mark_as_advanced(Mrcal_INCLUDE_DIR Mrcal_LIBRARY)
