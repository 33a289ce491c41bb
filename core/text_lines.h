#pragma once

#include <cstddef>
#include <string_view>

namespace hw::core {

// The one line splitter of heatwave's text readers (stream indexes, ffc.txt, TUM
// trajectories), so that every reader accepts what real tools write: a UTF-8 byte order mark
// at the start is skipped (Windows editors add it, and it is invisible in messages), and a
// line ends at LF, CRLF or a lone CR (classic Mac files; a CR-only file would otherwise be
// one long comment line). Line numbers count from 1 as an editor shows them.
inline constexpr std::string_view kUtf8Bom = "\xEF\xBB\xBF";

// Calls on_line(line_number, line) for every line, the terminator removed. A final line
// without a terminator is a line; text ending in a terminator has no empty last line.
template <typename OnLine>
void ForEachLine(std::string_view text, OnLine on_line) {
  if (text.substr(0, kUtf8Bom.size()) == kUtf8Bom) text.remove_prefix(kUtf8Bom.size());
  size_t line_number = 0;
  size_t begin = 0;
  while (begin < text.size()) {
    size_t end = text.find_first_of("\r\n", begin);
    if (end == std::string_view::npos) end = text.size();
    on_line(++line_number, text.substr(begin, end - begin));
    if (end < text.size() && text[end] == '\r' && end + 1 < text.size() && text[end + 1] == '\n') {
      ++end;  // CRLF is one terminator
    }
    begin = end + 1;
  }
}

}  // namespace hw::core
