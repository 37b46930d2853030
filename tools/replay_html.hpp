// The replay viewer page: tools/replay_viewer.html (embedded at build time) with a trajectory file inlined
// as base64. The page needs no network and no external library; it reads the trajectory format itself.
#pragma once

#include <string>
#include <string_view>

namespace hns::tools {

// Text with &, <, >, " and ' escaped for HTML text and attribute values.
std::string html_escape(const std::string& text);
// Replaces every occurrence of `slot` in `text` with `value`; returns how many there were.
int replace_all(std::string& text, std::string_view slot, const std::string& value);

// Standard base64 (RFC 4648, with padding).
std::string base64_encode(std::string_view bytes);

// The self-contained page for the (already checked) trajectory file `bytes`; `title` is shown in the page.
std::string render_replay_html(std::string_view trajectory_bytes, const std::string& title);

}  // namespace hns::tools
