#pragma once

// Hand-made PNG bytes for tests of the image readers (header-only; tests link zlib through
// libpng). Only what a test needs to build a file no encoder would write.

#include <zlib.h>

#include <cstdint>
#include <string>

namespace hw::test {

// One PNG chunk: big-endian length, type, data, CRC-32 of type + data.
inline std::string PngChunk(const std::string& type, const std::string& data) {
  std::string out;
  const auto be32 = [&out](uint32_t v) {
    for (int shift = 24; shift >= 0; shift -= 8) out += static_cast<char>((v >> shift) & 0xff);
  };
  be32(static_cast<uint32_t>(data.size()));
  out += type + data;
  const std::string crc_input = type + data;
  be32(static_cast<uint32_t>(crc32(0, reinterpret_cast<const Bytef*>(crc_input.data()),
                                   static_cast<uInt>(crc_input.size()))));
  return out;
}

// A PNG whose header claims width x height (16-bit grey) but whose data holds only `rows`
// zero rows: the header of a decompression bomb without its cost to the test.
inline std::string PngClaiming(uint32_t width, uint32_t height, int rows) {
  std::string ihdr;
  for (const uint32_t v : {width, height}) {
    for (int shift = 24; shift >= 0; shift -= 8) ihdr += static_cast<char>((v >> shift) & 0xff);
  }
  ihdr += std::string("\x10\x00\x00\x00\x00", 5);  // 16-bit, grey, deflate, filter 0, no interlace
  const std::string raw(static_cast<size_t>(rows) * (1 + 2 * width), '\0');
  uLongf size = compressBound(static_cast<uLong>(raw.size()));
  std::string compressed(size, '\0');
  compress(reinterpret_cast<Bytef*>(compressed.data()), &size,
           reinterpret_cast<const Bytef*>(raw.data()), static_cast<uLong>(raw.size()));
  compressed.resize(size);
  return std::string("\x89PNG\r\n\x1a\n", 8) + PngChunk("IHDR", ihdr) +
         PngChunk("IDAT", compressed) + PngChunk("IEND", "");
}

}  // namespace hw::test
