#pragma once

// The one way to include mrcal's C API from C++. Debian's libmrcal-dev 2.2 headers have no
// extern "C" (newer mrcal adds one; nesting it is harmless) and use C constructs that
// -Wpedantic reports in C++ (empty structs, anonymous structs, a flexible array member in
// mrcal_cameramodel_t). Their layout is the same in C and C++ (checked: sizeof
// mrcal_cameramodel_t is 72 with the intrinsics at offset 72 in both), so the C ABI holds.

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wpedantic"
extern "C" {
#include <mrcal/mrcal.h>
}
#pragma GCC diagnostic pop
