#pragma once

#include <string>
#include <string_view>

namespace hw::core {

// printf into a std::string (summaries, tables, messages).
std::string StringPrintf(const char* format, ...) __attribute__((format(printf, 1, 2)));

// `text` made one printable line for a message: '\n', '\r' and '\t' become spaces, other
// control characters '?'. Error messages are read one line per error (scripts, logs); a
// path or a library's reason holding a newline must not split one.
std::string OneLineMessage(std::string_view text);

// Standard base64 (RFC 4648, alphabet A–Z a–z 0–9 + /, '=' padding) of `bytes`: images and
// data inlined in the HTML report.
std::string Base64(std::string_view bytes);

}  // namespace hw::core
