#include "ppo/train_config.hpp"

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <vector>

#include "batch/batch_sim.hpp"
#include "batch/host.hpp"
#include "batch/scenes.hpp"
#include "nn/actor_critic.hpp"
#include "nn/entity_net.hpp"
#include "physics/scene.hpp"
#include "ppo/batch_obs.hpp"

namespace hns::ppo {

namespace {

using physics::ConfigError;

bool is_count_key(std::string_view n) {
  return n == "hiders" || n == "seekers" || n == "boxes" || n == "ramps";
}

// Calls f(name, field, is_identity) for every field in declaration order. Identity fields change the results
// of a run; the others (iterations, threads, checkpoint cadence) do not.
template <class Config, class F>
void visit_fields(Config& c, F&& f) {
  f("scene", c.scene, true);
  f("model", c.model, true);
  f("horizon", c.horizon, true);
  f("hiders", c.hiders, true);
  f("seekers", c.seekers, true);
  f("boxes", c.boxes, true);
  f("ramps", c.ramps, true);
  f("spawn_quarter", c.spawn_quarter, true);
  f("envs", c.envs, true);
  f("episodes_per_iteration", c.episodes_per_iteration, true);
  f("iterations", c.iterations, false);
  f("seed", c.seed, true);
  f("threads", c.threads, false);
  f("epochs", c.epochs, true);
  f("minibatches", c.minibatches, true);
  f("minibatch_chunks", c.minibatch_chunks, true);
  f("bptt", c.bptt, true);
  f("grad_groups", c.grad_groups, true);
  f("chunk_sequences", c.chunk_sequences, true);
  f("precision", c.precision, true);
  f("lr", c.lr, true);
  f("clip", c.clip, true);
  f("entropy_coef", c.entropy_coef, true);
  f("value_coef", c.value_coef, true);
  f("grad_clip", c.grad_clip, true);
  f("weight_decay", c.weight_decay, true);
  f("intrinsic", c.intrinsic, true);
  f("count_state", c.count_state, true);
  f("count_scale", c.count_scale, true);
  f("extrinsic_coef", c.extrinsic_coef, true);
  f("rnd_scale", c.rnd_scale, true);
  f("gamma", c.gamma, true);
  f("lambda", c.lambda, true);
  f("init_from", c.init_from, true);
  f("init_value", c.init_value, true);
  f("init_normalizers", c.init_normalizers, true);
  f("init_optimizer", c.init_optimizer, true);
  f("init_heads", c.init_heads, true);
  f("checkpoint_every", c.checkpoint_every, false);
  f("inject_nan_at", c.inject_nan_at, true);
}

// A value as error messages show it: at most 80 characters (a long one cut, with its length).
std::string shown(std::string_view value) {
  constexpr size_t kMax = 80;
  if (value.size() <= kMax) return std::string(value);
  return std::string(value.substr(0, kMax)) + "... (" + std::to_string(value.size()) + " characters)";
}

std::string field_error(std::string_view key, std::string_view value, std::string_view allowed) {
  return "config: " + shown(key) + " = '" + shown(value) + "' is invalid: " + std::string(allowed);
}

void parse_into(std::string_view key, std::string_view text, std::string& out) {
  (void)key;
  out = std::string(text);
}
// Whether text is a number in JSON's form: an optional minus, 0 or digits without a leading zero, then (where
// fraction is allowed) an optional fraction and exponent. Not "010", "1.", ".5", "+1", "0x10".
bool json_number_form(std::string_view text, bool fraction) {
  size_t i = 0;
  auto digits = [&] {
    const size_t start = i;
    while (i < text.size() && text[i] >= '0' && text[i] <= '9') ++i;
    return i - start;
  };
  if (i < text.size() && text[i] == '-') ++i;
  if (i < text.size() && text[i] == '0') {
    ++i;
  } else if (digits() == 0) {
    return false;
  }
  if (fraction && i < text.size() && text[i] == '.') {
    ++i;
    if (digits() == 0) return false;
  }
  if (fraction && i < text.size() && (text[i] == 'e' || text[i] == 'E')) {
    ++i;
    if (i < text.size() && (text[i] == '+' || text[i] == '-')) ++i;
    if (digits() == 0) return false;
  }
  return i == text.size();
}

template <class Int>
void parse_integer(std::string_view key, std::string_view text, Int& out) {
  Int v{};
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  if (!json_number_form(text, false) || ec != std::errc() || end != text.data() + text.size()) {
    throw ConfigError(field_error(key, text, "must be an integer"));
  }
  out = v;
}
void parse_into(std::string_view key, std::string_view text, int& out) {
  parse_integer(key, text, out);
}
void parse_into(std::string_view key, std::string_view text, uint64_t& out) {
  parse_integer(key, text, out);
}
// A number as JSON writes it (decimal, optional minus, fraction and exponent): not hex ("0x1p-10"), not
// "+1", " 1", "inf" or "nan", which strtod would take.
void parse_into(std::string_view key, std::string_view text, double& out) {
  double v = 0;
  const auto [end, ec] =
      std::from_chars(text.data(), text.data() + text.size(), v, std::chars_format::general);
  if (!json_number_form(text, true) || ec != std::errc() || end != text.data() + text.size() ||
      !std::isfinite(v)) {
    throw ConfigError(field_error(key, text, "must be a finite number"));
  }
  out = v;
}

std::string text_of(const std::string& v) {
  return v;
}
std::string text_of(int v) {
  return std::to_string(v);
}
std::string text_of(uint64_t v) {
  return std::to_string(v);
}
// The shortest text that reads back as the same double (0.0003, not 0.00029999999999999997).
std::string text_of(double v) {
  char buf[32];
  const auto [end, ec] = std::to_chars(buf, buf + sizeof buf, v, std::chars_format::general);
  return std::string(buf, ec == std::errc() ? end : buf);
}

std::string json_string(const std::string& s) {
  std::string out = "\"";
  for (char ch : s) {
    if (ch == '"' || ch == '\\') out += '\\';
    if (static_cast<unsigned char>(ch) < 0x20) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\u%04x", ch);
      out += buf;
      continue;
    }
    out += ch;
  }
  return out + "\"";
}

// The offset of the first byte of `s` that does not start a well-formed UTF-8 sequence (none overlong, no
// surrogate, nothing above U+10FFFF), or npos.
size_t first_non_utf8(std::string_view s) {
  for (size_t k = 0; k < s.size();) {
    const auto c = static_cast<unsigned char>(s[k]);
    const size_t n = c < 0x80 ? 1 : (c >> 5) == 0x6 ? 2 : (c >> 4) == 0xE ? 3 : (c >> 3) == 0x1E ? 4 : 0;
    if (n == 0 || k + n > s.size()) return k;
    uint32_t cp = n == 1 ? c : n == 2 ? (c & 0x1Fu) : n == 3 ? (c & 0x0Fu) : (c & 0x07u);
    for (size_t j = 1; j < n; ++j) {
      const auto t = static_cast<unsigned char>(s[k + j]);
      if ((t >> 6) != 0x2) return k;
      cp = (cp << 6) | (t & 0x3Fu);
    }
    const uint32_t least = n == 1 ? 0 : n == 2 ? 0x80 : n == 3 ? 0x800 : 0x10000;
    if (cp < least || cp > 0x10FFFF || (cp >= 0xD800 && cp < 0xE000)) return k;
    k += n;
  }
  return std::string_view::npos;
}

// A minimal reader for one flat JSON object: {"key": "string" | number | true | false, ...}.
// What a value was in the JSON text.
enum class JsonKind { kString, kNumber, kBoolean };
struct JsonEntry {
  std::string key, value;
  JsonKind kind;
};

// The flat JSON objects of config files: string, number and boolean values only, each key once; strings with
// every JSON escape (\uXXXX, surrogate pairs included, decoded to UTF-8); numbers in JSON's grammar.
class FlatJsonReader {
 public:
  FlatJsonReader(std::string_view text, const std::string& origin) : s_(text), origin_(origin) {}

  std::vector<JsonEntry> read() {
    std::vector<JsonEntry> out;
    check_utf8();
    skip_space();
    expect('{');
    skip_space();
    if (peek() == '}') {
      ++i_;
    } else {
      for (;;) {
        skip_space();
        std::string key = read_string();
        for (const JsonEntry& e : out)
          if (e.key == key) fail("key '" + shown(key) + "' appears twice");
        skip_space();
        expect(':');
        skip_space();
        JsonEntry entry{std::move(key), {}, JsonKind::kString};
        if (peek() == '"') {
          entry.value = read_string();
        } else {
          entry.value = read_bare();
          entry.kind =
              entry.value == "true" || entry.value == "false" ? JsonKind::kBoolean : JsonKind::kNumber;
        }
        out.push_back(std::move(entry));
        skip_space();
        if (peek() == ',') {
          ++i_;
          continue;
        }
        expect('}');
        break;
      }
    }
    skip_space();
    if (i_ != s_.size()) fail("unexpected text after the closing '}'");
    return out;
  }

 private:
  [[noreturn]] void fail(const std::string& what) const {
    int line = 1;
    for (size_t k = 0; k < i_ && k < s_.size(); ++k) line += s_[k] == '\n';
    throw ConfigError(origin_ + ":" + std::to_string(line) + ": " + what +
                      " (expected a flat JSON object such as {\"epochs\": 4, \"scene\": \"quadrant\"})");
  }
  char peek() const { return i_ < s_.size() ? s_[i_] : '\0'; }
  void skip_space() {
    while (i_ < s_.size() && (s_[i_] == ' ' || s_[i_] == '\t' || s_[i_] == '\n' || s_[i_] == '\r')) ++i_;
  }
  void expect(char c) {
    if (peek() != c) fail(std::string("expected '") + c + "'");
    ++i_;
  }
  // The 4 hex digits after "\u" at i_ (i_ on the 'u'), leaving i_ on the last digit.
  unsigned read_hex4() {
    unsigned v = 0;
    for (int d = 0; d < 4; ++d) {
      ++i_;
      const char c = peek();
      v <<= 4;
      if (c >= '0' && c <= '9') {
        v |= unsigned(c - '0');
      } else if (c >= 'a' && c <= 'f') {
        v |= unsigned(c - 'a' + 10);
      } else if (c >= 'A' && c <= 'F') {
        v |= unsigned(c - 'A' + 10);
      } else {
        fail("a \\u escape needs 4 hex digits");
      }
    }
    return v;
  }
  static void append_utf8(unsigned cp, std::string& out) {
    if (cp < 0x80) {
      out += char(cp);
    } else if (cp < 0x800) {
      out += char(0xC0 | (cp >> 6));
      out += char(0x80 | (cp & 0x3F));
    } else if (cp < 0x10000) {
      out += char(0xE0 | (cp >> 12));
      out += char(0x80 | ((cp >> 6) & 0x3F));
      out += char(0x80 | (cp & 0x3F));
    } else {
      out += char(0xF0 | (cp >> 18));
      out += char(0x80 | ((cp >> 12) & 0x3F));
      out += char(0x80 | ((cp >> 6) & 0x3F));
      out += char(0x80 | (cp & 0x3F));
    }
  }
  std::string read_string() {
    expect('"');
    std::string out;
    while (i_ < s_.size() && s_[i_] != '"') {
      if (s_[i_] == '\\') {
        ++i_;
        if (i_ >= s_.size()) break;
        const char e = s_[i_];
        if (e == 'n') {
          out += '\n';
        } else if (e == 't') {
          out += '\t';
        } else if (e == 'r') {
          out += '\r';
        } else if (e == 'b') {
          out += '\b';
        } else if (e == 'f') {
          out += '\f';
        } else if (e == '"' || e == '\\' || e == '/') {
          out += e;
        } else if (e == 'u') {
          unsigned cp = read_hex4();
          if (cp >= 0xD800 && cp < 0xDC00) {  // a high surrogate: its low one must follow
            if (i_ + 2 >= s_.size() || s_[i_ + 1] != '\\' || s_[i_ + 2] != 'u')
              fail("a \\u escape of a high surrogate needs its low surrogate");
            i_ += 2;
            const unsigned lo = read_hex4();
            if (lo < 0xDC00 || lo >= 0xE000) fail("a \\u escape of a high surrogate needs its low surrogate");
            cp = 0x10000 + ((cp - 0xD800) << 10) + (lo - 0xDC00);
          } else if (cp >= 0xDC00 && cp < 0xE000) {
            fail("a \\u escape of a lone low surrogate");
          }
          append_utf8(cp, out);
        } else {
          fail("unsupported escape in a string");
        }
      } else if (static_cast<unsigned char>(s_[i_]) < 0x20) {
        char buf[96];
        std::snprintf(
            buf, sizeof buf, "a raw control character (byte 0x%02x) in a string: JSON writes it as \\u%04x",
            unsigned(static_cast<unsigned char>(s_[i_])), unsigned(static_cast<unsigned char>(s_[i_])));
        fail(buf);
      } else {
        out += s_[i_];
      }
      ++i_;
    }
    expect('"');
    return out;
  }
  // JSON text is UTF-8: a byte sequence that is not (a damaged or binary file) is refused before anything is
  // read, so no message quotes it.
  void check_utf8() const {
    const size_t bad = first_non_utf8(s_);
    if (bad != std::string_view::npos)
      throw ConfigError(origin_ + ": not UTF-8 text (byte " + std::to_string(bad) + ")");
  }
  // A number in JSON's grammar (-? (0 | [1-9][0-9]*) (. [0-9]+)? ([eE] [+-]? [0-9]+)?), true or false.
  static bool json_number_or_literal(std::string_view v) {
    if (v == "true" || v == "false") return true;
    size_t k = 0;
    auto digits = [&] {
      const size_t from = k;
      while (k < v.size() && v[k] >= '0' && v[k] <= '9') ++k;
      return k > from;
    };
    if (k < v.size() && v[k] == '-') ++k;
    if (k < v.size() && v[k] == '0') {
      ++k;
    } else if (!digits()) {
      return false;
    }
    if (k < v.size() && v[k] == '.') {
      ++k;
      if (!digits()) return false;
    }
    if (k < v.size() && (v[k] == 'e' || v[k] == 'E')) {
      ++k;
      if (k < v.size() && (v[k] == '+' || v[k] == '-')) ++k;
      if (!digits()) return false;
    }
    return k == v.size();
  }
  std::string read_bare() {
    const size_t start = i_;
    while (i_ < s_.size() && s_[i_] != ',' && s_[i_] != '}' && s_[i_] != ' ' && s_[i_] != '\n' &&
           s_[i_] != '\r' && s_[i_] != '\t') {
      ++i_;
    }
    if (i_ == start) fail("expected a value");
    const std::string v(s_.substr(start, i_ - start));
    if (v == "{" || v == "[" || v.front() == '{' || v.front() == '[')
      fail("nested objects and arrays are not allowed");
    if (!json_number_or_literal(v))
      fail("'" + shown(v) + "' is not a JSON number, true or false (strings need quotes)");
    return v;
  }

  std::string_view s_;
  std::string origin_;
  size_t i_ = 0;
};

}  // namespace

void TrainConfig::set(std::string_view key, std::string_view value) {
  bool found = false;
  visit_fields(*this, [&](const char* name, auto& field, bool) {
    if (key != name) return;
    found = true;
    std::string text(value);
    // The 0/1 switches also take true and false; a number does not.
    const std::string_view n(name);
    if (n == "spawn_quarter" || (n.substr(0, 5) == "init_" && n != "init_from")) {
      if (text == "true") text = "1";
      if (text == "false") text = "0";
    }
    parse_into(key, text, field);
  });
  if (!found) {
    std::string names;
    visit_fields(*this, [&](const char* name, auto&, bool) {
      names += (names.empty() ? "" : ", ") + std::string(name);
    });
    throw ConfigError("config: unknown key '" + shown(key) + "' (known keys: " + names + ")");
  }
}

std::string TrainConfig::to_json() const {
  std::string out = "{\n";
  bool first = true;
  visit_fields(*this, [&](const char* name, const auto& field, bool) {
    // A run started from the seed writes no init_* keys: its files stay readable by versions without them.
    if (init_from.empty() && std::string_view(name).substr(0, 5) == "init_") return;
    // Likewise a run without an intrinsic reward writes none of its keys.
    const std::string_view n(name);
    const bool intrinsic_defaults = intrinsic == "none" && count_state == "box_pos" && count_scale == 0.1 &&
                                    extrinsic_coef == 1.0 && rnd_scale == 1.0;
    if (intrinsic_defaults && (n == "intrinsic" || n == "count_state" || n == "count_scale" ||
                               n == "extrinsic_coef" || n == "rnd_scale"))
      return;
    // And the count overrides only where set.
    if constexpr (std::is_same_v<std::decay_t<decltype(field)>, int>) {
      if (is_count_key(n) && field < 0) return;
      if (n == "spawn_quarter" && field == 0) return;
    }
    out += first ? "  " : ",\n  ";
    first = false;
    out += json_string(name) + ": ";
    if constexpr (std::is_same_v<std::decay_t<decltype(field)>, std::string>) {
      out += json_string(field);
    } else {
      out += text_of(field);
    }
  });
  return out + "\n}\n";
}

void TrainConfig::merge_json(std::string_view text, const std::string& origin) {
  for (const JsonEntry& e : FlatJsonReader(text, origin).read()) {
    try {
      // In a file a key's JSON type must be its field's: a string for text, a number for numbers.
      bool text_field = false, known = false;
      visit_fields(*this, [&](const char* name, auto& field, bool) {
        if (e.key != name) return;
        known = true;
        text_field = std::is_same_v<std::decay_t<decltype(field)>, std::string>;
      });
      if (known && text_field && e.kind != JsonKind::kString)
        throw ConfigError(field_error(e.key, e.value, "must be a JSON string (in quotes)"));
      if (known && !text_field && e.kind != JsonKind::kNumber)
        throw ConfigError(field_error(e.key, e.value,
                                      e.kind == JsonKind::kString
                                          ? "must be a JSON number, not a string"
                                          : "must be a JSON number, not true or false"));
      set(e.key, e.value);
    } catch (const ConfigError& err) {
      throw ConfigError(origin + ": " + err.what());
    }
  }
}

void TrainConfig::merge_run_json(std::string_view text, const std::string& origin) {
  grad_groups = 16;      // before the key existed the update always used 16 gradient groups
  chunk_sequences = 16;  // and training chunks of 16 sequences
  precision = "fp32";    // and the networks' products were all float
  // Before these keys existed (and in a run that writes none of them, see to_json) there was no intrinsic
  // reward and fine-tuning carried the heads.
  intrinsic = "none";
  count_state = "box_pos";
  count_scale = 0.1;
  extrinsic_coef = 1.0;
  rnd_scale = 1.0;
  init_heads = 1;
  hiders = seekers = boxes = ramps = -1;  // the scene's counts
  spawn_quarter = 0;
  merge_json(text, origin);
}

std::string TrainConfig::identity_mismatch(const TrainConfig& other) const {
  std::vector<std::string> mine, theirs;
  // Without init_from the other init_* keys change nothing (and a run's files leave them out): not compared.
  const bool no_init = init_from.empty() && other.init_from.empty();
  auto compared = [no_init](const char* name, bool identity) {
    const std::string_view n(name);
    return identity && !(no_init && n.substr(0, 5) == "init_" && n != "init_from");
  };
  visit_fields(*this, [&](const char* name, const auto& field, bool identity) {
    if (compared(name, identity)) mine.push_back(text_of(field));
  });
  visit_fields(other, [&](const char* name, const auto& field, bool identity) {
    if (compared(name, identity)) theirs.push_back(text_of(field));
  });
  size_t k = 0;
  std::string result;
  visit_fields(*this, [&](const char* name, const auto&, bool identity) {
    if (!compared(name, identity)) return;
    if (result.empty() && mine[k] != theirs[k]) {
      result = std::string(name) + ": checkpoint has " + mine[k] + ", this run has " + theirs[k];
    }
    ++k;
  });
  return result;
}

nn::Precision TrainConfig::resolve_precision(const nn::CpuFeatures& cpu) const {
  if (precision != "fp32" && precision != "bf16" && precision != "auto")
    throw ConfigError(field_error("precision", precision, "must be one of fp32, bf16, auto"));
  try {
    return nn::resolve_precision(precision, cpu);
  } catch (const std::invalid_argument& e) {
    throw ConfigError(std::string("config: ") + e.what());
  }
}

int TrainConfig::update_blocks() const {
  // The chunks of real agents (a transfer task's spoofed agent slot is no agent and leaves the update).
  const int64_t chunks = int64_t(envs) * world().max_agents() * (rollout_steps() / bptt);
  const int64_t per_minibatch = chunks / std::max(1, minibatches_for(chunks));
  const int64_t fill = std::max<int64_t>(1, per_minibatch / train_chunk());
  return int(std::min({int64_t(grad_groups), int64_t(envs), fill}));
}

int TrainConfig::train_chunk() const {
  return chunk_sequences > 0 ? chunk_sequences : nn::default_train_chunk(nn::net_preset(model));
}

int TrainConfig::minibatches_for(int64_t chunks) const {
  if (chunks <= 0) return 0;
  const int64_t n = minibatch_chunks > 0 ? (chunks + minibatch_chunks - 1) / minibatch_chunks : minibatches;
  return int(std::min<int64_t>(n, chunks));
}

batch::BatchConfig TrainConfig::batch_config() const {
  batch::BatchConfig game = batch::scene_config(scene);
  physics::WorldConfig& w = game.world;
  if (horizon > 0) w.horizon = horizon;
  const bool had_others = w.max_agents() > 1, had_ramps = w.scene.ramps.max > 0;
  auto count = [](int v) { return v >= 0 ? std::optional<int>(v) : std::nullopt; };
  batch::apply_overrides(w, batch::CountOverrides{count(hiders), count(seekers), count(boxes), count(ramps)});
  // Keep the entity types of the scene in the observation: a lone agent still has an (empty) other-agent
  // slot and a scene without ramps an (empty) ramp slot, as the transfer tasks spoof them (docs/game.md §9).
  batch::GameRules& r = game.rules;
  if (had_others) r.obs_min_agents = std::max(r.obs_min_agents, 2);
  if (had_ramps) r.obs_min_ramps = std::max(r.obs_min_ramps, 1);
  if (spawn_quarter == 1) w.scene.spawn_quarter = true;
  return game;
}

int TrainConfig::envs_per_rank(int ranks) const {
  const int64_t k = update_blocks();
  const int r = std::max(1, std::min<int>(ranks, int(k)));
  int most = 0;
  for (int i = 0; i < r; ++i) {
    const int64_t b0 = k * i / r, b1 = k * (i + 1) / r;
    most = std::max(most, int(int64_t(envs) * b1 / k - int64_t(envs) * b0 / k));
  }
  return most;
}

size_t TrainConfig::estimated_bytes(int ranks) const {
  // The sum of what one rank allocates, from the sizes of its buffers, times a margin for the allocator,
  // the heap's fragmentation and the buffers too small to list; then the process's fixed part (code, shared
  // libraries, thread stacks). Checked against the measured peak resident memory of scenes, models, env
  // counts and horizon/bptt extremes (tests/tools/memory_estimate_test.sh; docs/training.md "Memory").
  constexpr double kMargin = 1.25;
  constexpr size_t kFixedBytes = size_t(48) << 20;
  const int rank_envs = envs_per_rank(ranks);
  batch::BatchConfig bc = batch_config();
  bc.num_envs = rank_envs;
  const batch::Layout L = batch::Layout::of(bc);
  nn::NetConfig net = nn::net_preset(model);
  net.obs = obs_shape(L);
  nn::ParamLayout layout;
  const nn::EntityNet policy(net, nn::NetHead::kPolicy, layout, "policy");
  const nn::EntityNet value(net, nn::NetHead::kValue, layout, "value");
  const nn::ParallelConfig par;
  const size_t params = layout.num_params();
  const size_t T = size_t(rollout_steps()), G = size_t(rank_envs) * size_t(L.max_agents), rows = T * G;
  const size_t threads_used = size_t(std::max(1, batch::usable_threads(threads)));
  const size_t heads = net.action_heads.size();

  size_t floats = 0;
  // Rollout: observations, actions, the per-row targets and flags, the LSTM states entering each chunk, and
  // the minibatch's gathered copies (at most the rollout again for the per-row targets).
  floats += rows * (nn::ObsStore::floats_per_row(net.obs) + heads + 7 + 1 + 8);
  const size_t state_width = 2 * size_t(net.lstm);
  floats += 2 * 2 * (T / size_t(bptt)) * G * state_width;
  // Networks: values, gradient, Adam's two moments, the gradient groups, and the packed weights (bf16 with
  // their transposes, or the LSTMs' packed recurrent weights: at most one float per parameter).
  floats += params * (4 + size_t(grad_groups) + 1);
  if (intrinsic == "rnd") floats += 8 * params;  // two more networks, and their optimiser
  // Per thread: the training chunk's activations of both networks (train_chunk() x bptt rows) with the bf16
  // operand scratch (a quarter of them at most), and the inference chunk's (infer_chunk_agents x 1). (Each
  // thread's training workspace is sized for a whole chunk of train_chunk() sequences.)
  const size_t train_ws =
      policy.workspace_floats(train_chunk(), bptt) + value.workspace_floats(train_chunk(), bptt);
  const size_t infer_ws =
      policy.workspace_floats(par.infer_chunk_agents, 1) + value.workspace_floats(par.infer_chunk_agents, 1);
  // Training workspaces: one per gradient group running at once (nn::ActorCritic keeps them in a pool), so
  // min(threads, update blocks). Every thread keeps its inference workspace and, for bf16, its operand
  // scratch (a quarter of a training workspace at most) once it has run a network: over a run, every thread
  // may.
  const size_t blocks = size_t(std::max(1, update_blocks()));
  floats += std::min(threads_used, blocks) * train_ws +
            threads_used * ((precision == "fp32" ? 0 : train_ws / 4) + infer_ws);
  // bf16: each training workspace's weight-gradient stages, both networks' (nn::GradStage: at most one block
  // per product matrix).
  if (precision != "fp32")
    floats += std::min(threads_used, blocks) * (nn::GradStage::max_bytes(layout) / sizeof(float));
  const double bytes = (double(floats) * sizeof(float) + double(bc.estimated_bytes())) * kMargin;
  return size_t(bytes) + kFixedBytes;
}

void TrainConfig::validate() const {
  auto check = [](bool ok, const char* key, const auto& value, std::string_view allowed) {
    if (!ok) throw ConfigError(field_error(key, text_of(value), allowed));
  };
  // config.json is JSON, which holds UTF-8 text only: a string the run could write but not read back (a path
  // in another encoding) is refused before the run starts.
  visit_fields(*this, [&](const char* name, const auto& field, bool) {
    if constexpr (std::is_same_v<std::decay_t<decltype(field)>, std::string>) {
      const size_t bad = first_non_utf8(field);
      if (bad != std::string_view::npos) {
        throw ConfigError(std::string(name) + ": byte " + std::to_string(bad) +
                          " is not UTF-8 (config.json holds UTF-8 text only; rename the path)");
      }
    }
  });
  const batch::BatchConfig game = batch_config();  // throws for an unknown scene
  const physics::WorldConfig& w = game.world;
  try {
    (void)nn::net_preset(model);
  } catch (const std::invalid_argument&) {
    check(false, "model", model, "must be one of small, paper");
  }
  check(horizon >= 0 && horizon <= 100000, "horizon", horizon, "must be in [0, 100000] (0 = the scene's)");
  const bool counts_set = hiders >= 0 || seekers >= 0 || boxes >= 0 || ramps >= 0 || spawn_quarter != 0;
  const batch::SceneFamily family = batch::find_scene(scene)->family;
  const bool hide_and_seek =
      family == batch::SceneFamily::kHideAndSeek || family == batch::SceneFamily::kFood;
  check(!counts_set || hide_and_seek, "scene", scene,
        "sets its own agent and object counts and spawns: the keys hiders, seekers, boxes, ramps and "
        "spawn_quarter are for the hide-and-seek scenes (quadrant, full, empty, food, dynamic-food)");
  check(spawn_quarter == 0 || spawn_quarter == 1, "spawn_quarter", spawn_quarter,
        "must be 0 or 1 (false or true)");
  check(hiders >= -1 && hiders <= 32, "hiders", hiders, "must be in [0, 32] (-1 = the scene's)");
  check(seekers >= -1 && seekers <= 32, "seekers", seekers, "must be in [0, 32] (-1 = the scene's)");
  check(boxes >= -1 && boxes <= 32, "boxes", boxes, "must be in [0, 32] (-1 = the scene's)");
  check(ramps >= -1 && ramps <= 16, "ramps", ramps, "must be in [0, 16] (-1 = the scene's)");
  check(boxes != 0 || batch::scene_config(scene).world.scene.boxes.max == 0, "boxes", boxes,
        "must be at least 1 in a scene with boxes (0 would drop the network's box type)");
  check(w.max_agents() >= 1, "hiders", hiders,
        "with seekers = " + std::to_string(seekers) + ": at least one agent is required");
  game.validate();  // the world's, the rules' and whether the counts can be placed (the batch's are defaults)
  check(envs >= 1 && envs <= 65536, "envs", envs, "must be in [1, 65536]");
  check(episodes_per_iteration >= 1 && episodes_per_iteration <= 1000, "episodes_per_iteration",
        episodes_per_iteration, "must be in [1, 1000]");
  check(iterations >= 1 && iterations <= 100000000, "iterations", iterations, "must be in [1, 100000000]");
  check(threads >= 0 && threads <= 4096, "threads", threads, "must be in [0, 4096] (0 = all)");
  check(epochs >= 1 && epochs <= 100, "epochs", epochs, "must be in [1, 100]");
  check(bptt >= 1 && bptt <= 1000, "bptt", bptt, "must be in [1, 1000]");
  check(grad_groups >= 1 && grad_groups <= 1024, "grad_groups", grad_groups, "must be in [1, 1024]");
  check(chunk_sequences >= 0 && chunk_sequences <= 1024, "chunk_sequences", chunk_sequences,
        "must be in [0, 1024] (0 = the model's)");
  check(precision == "fp32" || precision == "bf16" || precision == "auto", "precision", precision,
        "must be one of fp32, bf16, auto");
  check(rollout_steps() % bptt == 0, "bptt", bptt,
        "must divide the rollout length (horizon x episodes_per_iteration)");
  // The rollout buffer holds every agent slot of every env for every step of an iteration (several KiB of
  // observations per row); the cap keeps its row indices in 32 bits and its size within a server's memory.
  const int64_t rows = int64_t(rollout_steps()) * envs * game.agent_slots();
  if (rows > kMaxRolloutRows) {
    throw ConfigError("envs " + std::to_string(envs) + " x rollout steps " + std::to_string(rollout_steps()) +
                      " (horizon x episodes_per_iteration) x agent slots " +
                      std::to_string(game.agent_slots()) + " = " + std::to_string(rows) +
                      " agent-step rows in the rollout buffer: must be at most " +
                      std::to_string(kMaxRolloutRows) + "; lower envs, episodes_per_iteration or horizon");
  }
  const int64_t chunks = int64_t(envs) * (rollout_steps() / bptt);
  check(minibatches >= 1 && minibatches <= chunks, "minibatches", minibatches,
        "must be in [1, envs x rollout steps / bptt]");
  check(
      minibatch_chunks >= 0 && minibatch_chunks <= buffer_chunks(), "minibatch_chunks", minibatch_chunks,
      "must be in [0, " + std::to_string(buffer_chunks()) +
          "] (0 = use minibatches; at most the buffer's chunks: envs x agent slots x rollout steps / bptt)");
  check(lr > 0 && lr <= 1, "lr", lr, "must be in (0, 1]");
  check(clip > 0 && clip < 1, "clip", clip, "must be in (0, 1)");
  check(entropy_coef >= 0 && entropy_coef <= 10, "entropy_coef", entropy_coef, "must be in [0, 10]");
  check(value_coef >= 0 && value_coef <= 100, "value_coef", value_coef, "must be in [0, 100]");
  check(grad_clip >= 0 && grad_clip <= 1e6, "grad_clip", grad_clip, "must be in [0, 1e6] (0 = off)");
  check(weight_decay >= 0 && weight_decay <= 1, "weight_decay", weight_decay, "must be in [0, 1]");
  check(gamma > 0 && gamma <= 1, "gamma", gamma, "must be in (0, 1]");
  check(lambda >= 0 && lambda <= 1, "lambda", lambda, "must be in [0, 1]");
  check(checkpoint_every >= 1 && checkpoint_every <= 100000000, "checkpoint_every", checkpoint_every,
        "must be in [1, 100000000]");
  check(inject_nan_at >= 0, "inject_nan_at", inject_nan_at, "must be >= 0 (0 = never)");
  check(init_value == 0 || init_value == 1, "init_value", init_value, "must be 0 or 1 (false or true)");
  check(init_normalizers == 0 || init_normalizers == 1, "init_normalizers", init_normalizers,
        "must be 0 or 1 (false or true)");
  check(init_optimizer == 0 || init_optimizer == 1, "init_optimizer", init_optimizer,
        "must be 0 or 1 (false or true)");
  check(
      init_optimizer == 0 || init_value == 1, "init_optimizer", init_optimizer,
      "must be 0 when init_value is 0 (Adam's state covers both networks; a fresh value net starts it over)");
  check(intrinsic == "none" || intrinsic == "count" || intrinsic == "rnd", "intrinsic", intrinsic,
        "must be none, count or rnd");
  check(rnd_scale >= 0 && rnd_scale <= 100, "rnd_scale", rnd_scale, "must be in [0, 100]");
  check(count_state == "box_pos" || count_state == "box_full" || count_state == "full", "count_state",
        count_state, "must be one of box_pos, box_full, full");
  check(count_scale >= 0 && count_scale <= 100, "count_scale", count_scale, "must be in [0, 100]");
  check(extrinsic_coef >= 0 && extrinsic_coef <= 100, "extrinsic_coef", extrinsic_coef,
        "must be in [0, 100]");
  check(init_heads == 0 || init_heads == 1, "init_heads", init_heads, "must be 0 or 1 (false or true)");
  check(init_optimizer == 0 || init_heads == 1, "init_optimizer", init_optimizer,
        "must be 0 when init_heads is 0 (Adam's state belongs to the heads it was carried with)");
}

}  // namespace hns::ppo
