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

std::string fill_template(std::string_view page, const std::vector<Slot>& slots) {
  std::string out;
  out.reserve(page.size());
  std::vector<int> seen(slots.size(), 0);
  size_t pos = 0;
  while (pos < page.size()) {
    // The nearest slot from here (slot names do not overlap one another).
    size_t best = std::string_view::npos, which = 0;
    for (size_t k = 0; k < slots.size(); ++k) {
      const size_t at = page.find(slots[k].name, pos);
      if (at < best) best = at, which = k;
    }
    if (best == std::string_view::npos) {
      out.append(page.substr(pos));
      break;
    }
    out.append(page.substr(pos, best - pos));
    out += slots[which].value;
    ++seen[which];
    pos = best + slots[which].name.size();
  }
  for (size_t k = 0; k < slots.size(); ++k) {
    if (slots[k].exactly_once && seen[k] != 1) {
      throw std::logic_error("page template must hold " + std::string(slots[k].name) +
                             " exactly once, holds it " + std::to_string(seen[k]) + " times");
    }
  }
  return out;
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
  return fill_template(kReplayViewerHtml, {{kDataSlot, base64_encode(trajectory_bytes)},
                                           {kTitleSlot, html_escape(title), false}});
}

}  // namespace hns::tools
