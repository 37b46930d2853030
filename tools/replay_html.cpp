#include "replay_html.hpp"

#include <stdexcept>

namespace hns::tools {

// Generated from tools/replay_viewer.html by cmake/HnsEmbedText.cmake.
extern const char kReplayViewerHtml[];

namespace {

constexpr std::string_view kTitleSlot = "@HNS_TITLE@";
constexpr std::string_view kDataSlot = "@HNS_TRAJECTORY_BASE64@";

}  // namespace

std::string html_escape(const std::string& text) {
  std::string out;
  for (char c : text) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      case '\'':
        out += "&#39;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

int replace_all(std::string& text, std::string_view slot, const std::string& value) {
  int count = 0;
  for (size_t pos = text.find(slot); pos != std::string::npos; pos = text.find(slot, pos + value.size())) {
    text.replace(pos, slot.size(), value);
    ++count;
  }
  return count;
}

std::string base64_encode(std::string_view bytes) {
  static constexpr char kAlphabet[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((bytes.size() + 2) / 3 * 4);
  size_t i = 0;
  for (; i + 3 <= bytes.size(); i += 3) {
    const uint32_t v =
        uint32_t(uint8_t(bytes[i])) << 16 | uint32_t(uint8_t(bytes[i + 1])) << 8 | uint8_t(bytes[i + 2]);
    out += kAlphabet[v >> 18];
    out += kAlphabet[(v >> 12) & 63];
    out += kAlphabet[(v >> 6) & 63];
    out += kAlphabet[v & 63];
  }
  if (i < bytes.size()) {
    const bool two = i + 1 < bytes.size();
    const uint32_t v = uint32_t(uint8_t(bytes[i])) << 16 | (two ? uint32_t(uint8_t(bytes[i + 1])) << 8 : 0);
    out += kAlphabet[v >> 18];
    out += kAlphabet[(v >> 12) & 63];
    out += two ? kAlphabet[(v >> 6) & 63] : '=';
    out += '=';
  }
  return out;
}

std::string render_replay_html(std::string_view trajectory_bytes, const std::string& title) {
  std::string page(kReplayViewerHtml);
  // The data slot goes first: base64 cannot contain the title slot, a title could contain the data slot.
  if (replace_all(page, kDataSlot, base64_encode(trajectory_bytes)) != 1) {
    throw std::logic_error("replay_viewer.html must hold exactly one " + std::string(kDataSlot));
  }
  replace_all(page, kTitleSlot, html_escape(title));
  return page;
}

}  // namespace hns::tools
