#pragma once

#include <string>
#include <string_view>

namespace hw::core {

// `s` as a JSON string literal, quotes included, that a strict RFC 8259 parser accepts.
// Every string a command puts into JSON goes through here, because much of it is paths and
// Linux paths are bytes, not text:
// - valid UTF-8 passes through unchanged (°C, µm, any language);
// - '"' and '\' are backslash-escaped; control characters (U+0000-U+001F, and DEL) become
//   \u00XX;
// - every byte that is not part of a valid UTF-8 sequence (a stray continuation byte, an
//   overlong form, an encoded surrogate, a code point past U+10FFFF, a truncated sequence)
//   becomes U+FFFD, one per byte. The name is then not byte-exact, but the report parses;
//   the text reports print paths as they are.
std::string JsonString(std::string_view s);

}  // namespace hw::core
