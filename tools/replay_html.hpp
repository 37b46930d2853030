// The replay viewer page: tools/replay_viewer.html (embedded at build time) with a trajectory file inlined
// as base64. The page needs no network and no external library; it reads the trajectory format itself.
#pragma once

#include <string>
#include <string_view>
#include <vector>

namespace hns::tools {

// Text with &, <, >, " and ' escaped for HTML text and attribute values.
std::string html_escape(const std::string& text);
// A slot of a page template and the text that fills it. `exactly_once`: the template must hold it once
// (a data slot); otherwise any number of times (the title).
struct Slot {
  std::string_view name;
  std::string value;
  bool exactly_once = true;
};
// The template with every slot filled, in one pass over the template: text that a value brings in is never
// searched for slots (a metrics row holding "@HNS_REPLAY@" stays text). Throws std::logic_error when a data
// slot is not in the template exactly once.
std::string fill_template(std::string_view page, const std::vector<Slot>& slots);

// Standard base64 (RFC 4648, with padding).
std::string base64_encode(std::string_view bytes);

// The self-contained page for the (already checked) trajectory file `bytes`; `title` is shown in the page.
std::string render_replay_html(std::string_view trajectory_bytes, const std::string& title);

}  // namespace hns::tools
