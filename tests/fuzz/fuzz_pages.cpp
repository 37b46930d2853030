// libFuzzer target: the data of the report and replay pages. Whatever text a run's files hold (config.json,
// metrics rows, a title, a recording's bytes), the page keeps the template's structure: every data slot is
// inside its own <script> element, which no data can end or open, so the page has exactly the template's
// script elements. A violation traps.
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "replay_html.hpp"
#include "report_html.hpp"

namespace {

size_t count(const std::string& text, std::string_view what) {
  size_t n = 0;
  for (size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string input(reinterpret_cast<const char*>(data), size);
  // Three pieces of text from one input: split at the first two NUL bytes.
  const size_t a = input.find('\0');
  const size_t b = a == std::string::npos ? std::string::npos : input.find('\0', a + 1);
  const std::string first = input.substr(0, a);
  const std::string second = a == std::string::npos ? "" : input.substr(a + 1, b - a - 1);
  const std::string third = b == std::string::npos ? "" : input.substr(b + 1);

  static const std::string empty_report = hns::tools::render_report_html({"t", "[]", "{}", "{}", ""});
  static const size_t scripts = count(empty_report, "<script");
  static const size_t closers = count(empty_report, "</script");
  static const size_t comments = count(empty_report, "<!--");
  // The data slots hold JSON text as the report passes it (any bytes here: the page must hold them inertly).
  hns::tools::ReportInputs in{third, first, second, "{}", ""};
  const std::string page = hns::tools::render_report_html(in);
  if (count(page, "<script") != scripts || count(page, "</script") != closers ||
      count(page, "<!--") != comments)
    __builtin_trap();

  static const std::string empty_replay = hns::tools::render_replay_html("", "t");
  static const size_t replay_scripts = count(empty_replay, "<script");
  const std::string replay = hns::tools::render_replay_html(input, third);
  if (count(replay, "<script") != replay_scripts) __builtin_trap();
  return 0;
}
