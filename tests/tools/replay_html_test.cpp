// The replay page: base64 encoding, and a page that embeds the trajectory and reaches for nothing outside.
#include "replay_html.hpp"
#include "report_html.hpp"

#include <gtest/gtest.h>

#include <string>

namespace hns::tools {
namespace {

// Standard base64 decoding, for the round trip.
std::string base64_decode(const std::string& text) {
  const std::string alphabet = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  uint32_t acc = 0;
  int bits = 0;
  for (char c : text) {
    if (c == '=') break;
    acc = acc << 6 | uint32_t(alphabet.find(c));
    bits += 6;
    if (bits >= 8) {
      bits -= 8;
      out += char((acc >> bits) & 0xFF);
    }
  }
  return out;
}

TEST(ReplayHtml, Base64MatchesRfc4648) {
  EXPECT_EQ(base64_encode(""), "");
  EXPECT_EQ(base64_encode("f"), "Zg==");
  EXPECT_EQ(base64_encode("fo"), "Zm8=");
  EXPECT_EQ(base64_encode("foo"), "Zm9v");
  EXPECT_EQ(base64_encode("foob"), "Zm9vYg==");
  EXPECT_EQ(base64_encode("fooba"), "Zm9vYmE=");
  EXPECT_EQ(base64_encode("foobar"), "Zm9vYmFy");
  std::string all;
  for (int i = 0; i < 256; ++i) all += char(i);
  for (size_t n = 0; n <= all.size(); n += 37)
    EXPECT_EQ(base64_decode(base64_encode(all.substr(0, n))), all.substr(0, n));
}

TEST(ReplayHtml, PageEmbedsTheTrajectoryAndNeedsNoNetwork) {
  const std::string data = std::string("HNSTRAJ\n") + std::string(100, '\x7f');
  const std::string page = render_replay_html(data, "runs/<a&b>.traj");
  const std::string b64 = base64_encode(data);
  const size_t at = page.find(b64);
  ASSERT_NE(at, std::string::npos);
  EXPECT_EQ(page.find(b64, at + 1), std::string::npos);
  EXPECT_NE(page.find("runs/&lt;a&amp;b&gt;.traj"), std::string::npos);
  EXPECT_EQ(page.find("<a&b>"), std::string::npos);
  EXPECT_EQ(page.find("@HNS_"), std::string::npos);
  EXPECT_NE(page.find("<canvas id=\"view\""), std::string::npos);
  EXPECT_NE(page.find("id=\"hns-status\""), std::string::npos);
  for (const char* remote : {"http://", "https://", "<script src", "<link", "@import", "url("}) {
    EXPECT_EQ(page.find(remote), std::string::npos) << remote;
  }
}

TEST(ReportHtml, DataCannotEndOrOpenAScriptElementAndTheReplayIsSandboxed) {
  ReportInputs in;
  in.title = "run";
  in.metrics_json = "[{\"iteration\": 1, \"note\": \"</script><script>alert(1)</script>\"}]";
  in.config_json = "{\"scene\": \"<!--<script>\"}";
  in.stages_json = "{}";
  in.replay_html = "<html><script>/* replay */</script></html>";
  const std::string page = render_report_html(in);
  // No "<" of the data survives as markup: it is the JSON escape \u003c, which JSON.parse reads back.
  EXPECT_EQ(page.find("<!--<script>"), std::string::npos);
  EXPECT_EQ(page.find("alert(1)</script>"), std::string::npos);
  EXPECT_NE(page.find("\\u003c!--\\u003cscript>"), std::string::npos);
  EXPECT_NE(page.find("<iframe title=\"replay\" sandbox=\"allow-scripts\" srcdoc="), std::string::npos);
}

// Found by fuzz_pages: text in a run's files that names a slot of the template stays text (the slots were
// filled one after another, so a metrics row holding "@HNS_REPLAY@" made hns report fail, or worse).
TEST(ReportHtml, DataThatNamesASlotStaysText) {
  ReportInputs in;
  in.title = "@HNS_METRICS_JSON@";
  in.metrics_json = "[{\"note\": \"@HNS_REPLAY@ @HNS_TITLE@ @HNS_CONFIG_JSON@\"}]";
  in.config_json = "{\"note\": \"@HNS_STAGES_JSON@\"}";
  in.stages_json = "{}";
  const std::string page = render_report_html(in);
  EXPECT_NE(page.find("[{\"note\": \"@HNS_REPLAY@ @HNS_TITLE@ @HNS_CONFIG_JSON@\"}]"), std::string::npos);
  EXPECT_NE(page.find("{\"note\": \"@HNS_STAGES_JSON@\"}"), std::string::npos);
  EXPECT_EQ(page.find("<iframe"), std::string::npos);
  const std::string replay = render_replay_html("HNSTRAJ\n", "@HNS_TRAJECTORY_BASE64@");
  EXPECT_NE(replay.find("@HNS_TRAJECTORY_BASE64@"), std::string::npos);
  EXPECT_NE(replay.find(base64_encode("HNSTRAJ\n")), std::string::npos);
}

}  // namespace
}  // namespace hns::tools
