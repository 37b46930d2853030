// `hns eval`: the paper's transfer protocol (docs/transfer.md). For every task of the suite, every condition
// (from scratch, and from each --pretrained checkpoint) and every seed: one training run of a fixed budget.
// Per task also the return of a uniformly random policy. Results go to DIR/eval.json (every curve, written
// after each run: a stopped evaluation continues with --resume), DIR/eval.md (one table) and DIR/eval.html
// (normalised-performance curves, mean and 90 % interval over seeds).
//
//   hns eval --out DIR [--tasks T1,T2,...] [--seeds N] [--iterations K] [--envs E] [--model M] [--threads T]
//            [--pretrained LABEL=CHECKPOINT ...] [--set KEY=VALUE ...] [--random-episodes N]
//            [--resume | --overwrite]
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "batch/scenes.hpp"
#include "cli.hpp"
#include "ppo/atomic_file.hpp"
#include "ppo/eval.hpp"
#include "ppo/trainer.hpp"
#include "replay/metrics.hpp"

namespace hns::tools {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

constexpr int kFinalIterations = 5;  // the final return: mean over a run's last iterations
constexpr int kSmooth = 5;           // curves: trailing mean over this many iterations

struct EvalOptions {
  std::string out;
  std::string tasks = "lock-and-return,sequential-lock,shelter,blueprint";
  int seeds = 3;
  int iterations = 40;
  int envs = 64;
  std::string model = "small";
  int threads = 0;
  std::vector<std::string> pretrained;  // LABEL=CHECKPOINT
  std::vector<std::string> sets;
  int random_episodes = 256;
  bool resume = false;
  bool overwrite = false;
};

std::vector<std::string> split_list(const std::string& text) {
  std::vector<std::string> out;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    if (!item.empty()) out.push_back(item);
  }
  return out;
}

// One finished run's curve.
struct RunRecord {
  std::string task, condition;
  int seed = 0;
  std::vector<double> returns;       // mean episode return per iteration
  std::vector<int64_t> agent_steps;  // cumulative, per iteration
  double seconds = 0;
};

json to_json(const RunRecord& r) {
  return json{{"task", r.task},       {"condition", r.condition},     {"seed", r.seed},
              {"returns", r.returns}, {"agent_steps", r.agent_steps}, {"seconds", r.seconds}};
}

RunRecord record_of(const json& j) {
  RunRecord r;
  r.task = j.at("task").get<std::string>();
  r.condition = j.at("condition").get<std::string>();
  r.seed = j.at("seed").get<int>();
  r.returns = j.at("returns").get<std::vector<double>>();
  r.agent_steps = j.at("agent_steps").get<std::vector<int64_t>>();
  r.seconds = j.value("seconds", 0.0);
  return r;
}

double final_return(const RunRecord& r) {
  const int n = std::min<int>(kFinalIterations, int(r.returns.size()));
  double s = 0;
  for (int i = int(r.returns.size()) - n; i < int(r.returns.size()); ++i) s += r.returns[size_t(i)];
  return n > 0 ? s / n : 0.0;
}

std::vector<double> smoothed(const std::vector<double>& v) {
  std::vector<double> out(v.size());
  double s = 0;
  for (size_t i = 0; i < v.size(); ++i) {
    s += v[i];
    if (i >= size_t(kSmooth)) s -= v[i - kSmooth];
    out[i] = s / double(std::min(i + 1, size_t(kSmooth)));
  }
  return out;
}

// Everything the table and the page show, from the records.
struct Summary {
  std::vector<std::string> tasks;
  std::vector<std::string> conditions;
  std::map<std::string, double> random;  // per task
  std::vector<RunRecord> runs;

  std::vector<const RunRecord*> of(const std::string& task, const std::string& cond) const {
    std::vector<const RunRecord*> out;
    for (const RunRecord& r : runs) {
      if (r.task == task && r.condition == cond) out.push_back(&r);
    }
    return out;
  }
  ppo::MeanInterval final_of(const std::string& task, const std::string& cond) const {
    std::vector<double> v;
    for (const RunRecord* r : of(task, cond)) v.push_back(final_return(*r));
    return ppo::mean_interval90(v);
  }
  // The normalisation's 1: the best condition's mean final return, or the random return where no condition
  // beats it (every normalised value is then 0).
  double best(const std::string& task) const {
    double b = random.at(task);
    for (const std::string& c : conditions) {
      const ppo::MeanInterval m = final_of(task, c);
      if (m.n > 0) b = std::max(b, m.mean);
    }
    return b;
  }
};

std::string fmt(double v, int digits = 2) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", digits, v);
  return buf;
}

std::string interval_text(const ppo::MeanInterval& m, int digits = 2) {
  if (m.n == 0) return "";
  if (m.n == 1) return fmt(m.mean, digits) + " (1 seed)";
  return fmt(m.mean, digits) + " [" + fmt(m.lo, digits) + ", " + fmt(m.hi, digits) + "]";
}

std::string table_markdown(const Summary& s, const json& settings) {
  std::ostringstream o;
  o << "# hns eval\n\n";
  o << "Settings: " << settings.dump() << "\n\n";
  o << "Final return: the mean episode return of a run's last " << kFinalIterations
    << " iterations; mean over seeds and [90 % interval] (Student t). Normalised: (return - random) / (best "
       "- "
       "random), best = the best condition's mean.\n\n";
  o << "| task | random policy |";
  for (const std::string& c : s.conditions) o << " " << c << " | " << c << " normalised |";
  o << "\n|---|---|";
  for (size_t i = 0; i < s.conditions.size(); ++i) o << "---|---|";
  o << "\n";
  for (const std::string& t : s.tasks) {
    if (!s.random.count(t)) continue;
    const double rnd = s.random.at(t), best = s.best(t);
    o << "| " << t << " | " << fmt(rnd) << " |";
    for (const std::string& c : s.conditions) {
      const ppo::MeanInterval m = s.final_of(t, c);
      if (m.n == 0) {
        o << " not run | |";
        continue;
      }
      o << " " << interval_text(m) << (m.n > 1 ? " (" + std::to_string(m.n) + " seeds)" : "") << " | "
        << fmt(ppo::normalised(m.mean, rnd, best)) << " |";
    }
    o << "\n";
  }
  return o.str();
}

std::string html_escape(const std::string& text) {
  std::string out;
  for (char ch : text) {
    if (ch == '<')
      out += "&lt;";
    else if (ch == '>')
      out += "&gt;";
    else if (ch == '&')
      out += "&amp;";
    else
      out += ch;
  }
  return out;
}

// Round tick values over [lo, hi]: multiples of 1, 2 or 5 times a power of ten, about `count` of them.
std::vector<double> round_ticks(double lo, double hi, int count) {
  const double span = hi > lo ? hi - lo : 1.0;
  const double raw = span / count, mag = std::pow(10.0, std::floor(std::log10(raw)));
  double step = 10 * mag;
  for (double m : {1.0, 2.0, 5.0, 10.0}) {
    if (m * mag >= raw) {
      step = m * mag;
      break;
    }
  }
  std::vector<double> out;
  for (double v = std::ceil(lo / step) * step; v <= hi + 1e-9 * span; v += step) out.push_back(v);
  return out;
}

// An agent-step tick: 0, 250k, 1.5M.
std::string steps_label(double v) {
  if (v >= 1e6) return fmt(v / 1e6, v / 1e6 == std::floor(v / 1e6) ? 0 : 1) + "M";
  if (v >= 1e3) return fmt(v / 1e3, v / 1e3 == std::floor(v / 1e3) ? 0 : 1) + "k";
  return fmt(v, 0);
}

// One chart per task: the normalised, smoothed return against agent-steps, the mean over seeds as a line and
// its 90 % interval as a band, per condition; dashed lines at 0 (random) and 1 (best final); ticks on both
// axes; the legend below the plot, so no curve hides behind it (a condition above 1 included).
std::string chart_svg(const Summary& s, const std::string& task) {
  static const char* kColours[] = {"#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b"};
  const double W = 520, H = 330, L = 60, R = 14, T = 28, B = 70;
  const double rnd = s.random.at(task), best = s.best(task);
  struct Curve {
    std::vector<double> x, mean, lo, hi;
  };
  std::vector<Curve> curves;
  double x_max = 1, y_min = -0.1, y_max = 1.1;
  for (const std::string& c : s.conditions) {
    const std::vector<const RunRecord*> runs = s.of(task, c);
    Curve cv;
    if (!runs.empty()) {
      size_t n = runs.front()->returns.size();
      for (const RunRecord* r : runs) n = std::min(n, r->returns.size());
      std::vector<std::vector<double>> sm;
      for (const RunRecord* r : runs) sm.push_back(smoothed(r->returns));
      for (size_t i = 0; i < n; ++i) {
        std::vector<double> v;
        for (const auto& curve : sm) v.push_back(ppo::normalised(curve[i], rnd, best));
        const ppo::MeanInterval m = ppo::mean_interval90(v);
        cv.x.push_back(double(runs.front()->agent_steps[i]));
        cv.mean.push_back(m.mean), cv.lo.push_back(m.lo), cv.hi.push_back(m.hi);
        x_max = std::max(x_max, cv.x.back());
        y_min = std::min(y_min, m.lo), y_max = std::max(y_max, m.hi);
      }
    }
    curves.push_back(cv);
  }
  // Bands of a few seeds can be very wide: the view stops at -3 and 3 (a curve beyond runs along the edge).
  y_min = std::max(y_min, -3.0), y_max = std::min(y_max, 3.0);
  auto px = [&](double x) { return L + (W - L - R) * x / x_max; };
  auto py = [&](double y) {
    return T + (H - T - B) * (y_max - std::clamp(y, y_min, y_max)) / (y_max - y_min);
  };
  std::ostringstream o;
  o << "<svg xmlns='http://www.w3.org/2000/svg' width='" << W << "' height='" << H << "' class='chart'>";
  o << "<text x='" << L << "' y='18' class='title'>" << task << "</text>";
  o << "<rect x='" << L << "' y='" << T << "' width='" << W - L - R << "' height='" << H - T - B
    << "' fill='none' stroke='#999'/>";
  for (double v : round_ticks(y_min, y_max, 6)) {
    o << "<line x1='" << L << "' x2='" << W - R << "' y1='" << py(v) << "' y2='" << py(v)
      << "' stroke='#eee'/><text x='" << L - 6 << "' y='" << py(v) + 4 << "' text-anchor='end' class='ytick'>"
      << fmt(std::abs(v) < 1e-12 ? 0.0 : v, std::abs(v - std::round(v)) < 1e-9 ? 0 : 1) << "</text>";
  }
  for (double v : round_ticks(0, x_max, 5)) {
    o << "<line x1='" << px(v) << "' x2='" << px(v) << "' y1='" << T << "' y2='" << H - B
      << "' stroke='#eee'/><text x='" << px(v) << "' y='" << H - B + 15
      << "' text-anchor='middle' class='xtick'>" << steps_label(v) << "</text>";
  }
  for (double level : {0.0, 1.0}) {
    o << "<line x1='" << L << "' x2='" << W - R << "' y1='" << py(level) << "' y2='" << py(level)
      << "' stroke='#888' stroke-dasharray='4 3'/>";
  }
  o << "<text x='" << (L + W - R) / 2 << "' y='" << H - B + 32 << "' text-anchor='middle'>agent-steps</text>";
  o << "<text x='14' y='" << (T + H - B) / 2 << "' transform='rotate(-90 14 " << (T + H - B) / 2
    << ")' text-anchor='middle'>normalised return (0 random, 1 best)</text>";
  double legend_x = L;
  for (size_t c = 0; c < curves.size(); ++c) {
    const Curve& cv = curves[c];
    const char* colour = kColours[c % 6];
    if (!cv.x.empty()) {
      o << "<polygon fill='" << colour << "' fill-opacity='0.18' stroke='none' points='";
      for (size_t i = 0; i < cv.x.size(); ++i) o << px(cv.x[i]) << "," << py(cv.hi[i]) << " ";
      for (size_t i = cv.x.size(); i-- > 0;) o << px(cv.x[i]) << "," << py(cv.lo[i]) << " ";
      o << "'/><polyline fill='none' stroke='" << colour << "' stroke-width='2' points='";
      for (size_t i = 0; i < cv.x.size(); ++i) o << px(cv.x[i]) << "," << py(cv.mean[i]) << " ";
      o << "'/>";
    }
    o << "<text x='" << legend_x << "' y='" << H - 10 << "' fill='" << colour << "' class='legend'>"
      << html_escape(s.conditions[c]) << "</text>";
    legend_x += 14 + 7.0 * double(s.conditions[c].size());
  }
  o << "</svg>";
  return o.str();
}

std::string page_html(const Summary& s, const json& settings) {
  std::ostringstream o;
  o << "<!DOCTYPE html><html><head><meta charset='utf-8'><title>hns eval</title><style>"
       "body{font-family:sans-serif;margin:20px;max-width:1100px}svg.chart{margin:6px;font-size:12px}"
       ".title{font-weight:bold;font-size:14px}table{border-collapse:collapse;margin:8px 0}td,th{border:1px "
       "solid "
       "#ccc;padding:3px 8px;text-align:right}td:first-child{text-align:left}table.settings "
       "th,table.settings td"
       "{text-align:left;vertical-align:top}table.settings td{max-width:900px}</style></head><body>";
  o << "<h1>hns eval: transfer suite</h1><table class='settings'>";
  for (const auto& [key, value] : settings.items()) {
    // An object (the training config) as "key value" pairs that wrap, not one long line of JSON.
    std::string text;
    if (value.is_object()) {
      for (const auto& [k, v] : value.items()) {
        text += (text.empty() ? "" : ", ") + k + " " + (v.is_string() ? v.get<std::string>() : v.dump());
      }
    } else {
      text = value.is_string() ? value.get<std::string>() : value.dump();
    }
    o << "<tr><th>" << html_escape(key) << "</th><td>" << html_escape(text) << "</td></tr>";
  }
  o << "</table>";
  o << "<p>Each line is the mean over seeds of a condition's return, smoothed over " << kSmooth
    << " iterations and normalised per task: 0 is the uniformly random policy's return, 1 the best "
       "condition's final return (the mean of its last "
    << kFinalIterations << " iterations). The band is the 90 % interval over seeds (Student t).</p>";
  o << "<table><tr><th>task</th><th>random</th>";
  for (const std::string& c : s.conditions) o << "<th>" << html_escape(c) << "</th><th>normalised</th>";
  o << "</tr>";
  for (const std::string& t : s.tasks) {
    if (!s.random.count(t)) continue;
    const double rnd = s.random.at(t), best = s.best(t);
    o << "<tr><td>" << t << "</td><td>" << fmt(rnd) << "</td>";
    for (const std::string& c : s.conditions) {
      const ppo::MeanInterval m = s.final_of(t, c);
      o << "<td>" << (m.n ? interval_text(m) : "not run") << "</td><td>"
        << (m.n ? fmt(ppo::normalised(m.mean, rnd, best)) : "") << "</td>";
    }
    o << "</tr>";
  }
  o << "</table><div>";
  for (const std::string& t : s.tasks) {
    if (s.random.count(t)) o << chart_svg(s, t);
  }
  o << "</div></body></html>\n";
  return o.str();
}

// --tasks: transfer tasks of the scene registry, each once.
std::vector<std::string> parse_tasks(const std::string& list) {
  std::vector<std::string> tasks = split_list(list);
  if (tasks.empty()) throw physics::ConfigError("--tasks '" + list + "': no task given");
  const std::string transfer = batch::scene_list(", ", batch::SceneFamily::kTransfer);
  for (const std::string& t : tasks) {
    const batch::SceneInfo* scene = batch::find_scene(t);
    if (scene == nullptr)
      throw physics::ConfigError("--tasks: '" + t + "' is not a scene of hns; the transfer tasks are " +
                                 transfer);
    if (scene->family == batch::SceneFamily::kProbe)
      throw physics::ConfigError("--tasks: '" + t +
                                 "' is a probe of a frozen policy, not a task to train: run hns counting");
    if (scene->family != batch::SceneFamily::kTransfer)
      throw physics::ConfigError("--tasks: '" + t + "' is not a transfer task (" + transfer + ")");
    if (std::count(tasks.begin(), tasks.end(), t) > 1)
      throw physics::ConfigError("--tasks: '" + t + "' is given twice");
  }
  return tasks;
}

// The training config every run shares (its scene, seed and checkpoint are the run's own).
ppo::TrainConfig base_config(const EvalOptions& opt) {
  ppo::TrainConfig base;
  base.model = opt.model;
  base.envs = opt.envs;
  base.iterations = opt.iterations;
  base.threads = opt.threads;
  // Fine-tuning as the paper does it: both networks' weights and the observation normaliser are carried,
  // except each network's head (final layer norm and output layer), which starts from the seed (--set
  // init_heads=1 carries them, --set init_value=0 starts the whole value net from the seed).
  base.init_value = 1;
  base.init_heads = 0;
  for (const std::string& kv : opt.sets) {
    const auto eq = kv.find('=');
    if (eq == std::string::npos) throw physics::ConfigError("--set " + kv + ": expected KEY=VALUE");
    const std::string key = kv.substr(0, eq);
    if (key == "scene" || key == "seed" || key == "init_from" || key == "iterations" || key == "envs" ||
        key == "model" || key == "threads")
      throw physics::ConfigError("--set " + kv + ": " + key + " is set by hns eval itself (see --help)");
    base.set(key, kv.substr(eq + 1));
  }
  // The precision that runs here (auto resolved, so eval.json records it and a resume on a CPU that would
  // resolve it otherwise is refused); --set precision=bf16 on a CPU without it: refused now (exit 2).
  base.precision = std::string(nn::precision_name(base.resolve_precision()));
  // And the training chunk (0: the model's), so eval.json names the chunk its runs trained with.
  try {
    base.chunk_sequences = base.train_chunk();
  } catch (const std::invalid_argument& e) {
    throw physics::ConfigError(std::string("--model: ") + e.what());
  }
  return base;
}

// Whether the evaluation recorded in eval_json is from before the chunk_sequences key (its runs trained with
// chunks of 16 sequences). False for anything unreadable: read_evaluation reports that.
bool predates_chunk_key(const fs::path& eval_json) {
  try {
    const std::string text = ppo::read_regular_file(eval_json, ppo::kMaxMetricsBytes, "--resume:");
    if (!replay::json_nesting_within(text)) return false;
    const json tc = json::parse(text).at("settings").at("train_config");
    return tc.is_object() && !tc.contains("chunk_sequences");
  } catch (const std::exception&) {
    return false;
  }
}

// What a resumed evaluation must share with the one it continues: every run's training config but the
// scene, seed and checkpoint (the defaults of this version of hns eval included), and the random policy's
// episodes. Tasks, seeds and --pretrained conditions may be added; a resume that does not name a recorded
// task or condition runs it too.
json shared_settings(const EvalOptions& opt, const ppo::TrainConfig& base) {
  ppo::TrainConfig shared = base;
  shared.threads = 0;
  shared.init_from = "(per condition)";
  return {{"model", opt.model},
          {"envs", opt.envs},
          {"iterations", opt.iterations},
          {"random_episodes", opt.random_episodes},
          {"sets", opt.sets},
          {"train_config", json::parse(shared.to_json())}};
}

// --out may take the evaluation: a folder (or nothing yet) whose eval files hns may replace; eval.md and
// eval.html without eval.json are not an evaluation to resume, and not replaced unasked either.
void check_out_folder(const EvalOptions& opt, const fs::path& dir, const fs::path& eval_json) {
  std::error_code ec;
  if (fs::exists(dir, ec) && !fs::is_directory(dir, ec))
    throw physics::ConfigError("--out " + opt.out + ": exists and is not a folder");
  check_path_length("--out", opt.out);
  if (opt.resume && opt.overwrite)
    throw physics::ConfigError(
        "--resume and --overwrite: give one (--resume continues the evaluation in --out)");
  for (const char* name : {"eval.json", "eval.md", "eval.html"}) {
    if (std::string(name) != "eval.json" && !fs::exists(eval_json, ec) &&
        fs::exists(fs::symlink_status(dir / name, ec)) && !opt.overwrite) {
      throw physics::ConfigError("--out " + opt.out + " holds " + name +
                                 " but no eval.json: --overwrite replaces it, or give another folder");
    }
    try {
      ppo::check_replaceable((dir / name).string(), "--out:");
    } catch (const ppo::FileError& e) {
      throw physics::ConfigError(e.what());
    }
  }
}

// The conditions an evaluation recorded: each must be the checkpoint it was (added to `conditions` where
// this resume does not name it).
void check_recorded_conditions(const EvalOptions& opt, const json& recorded,
                               std::vector<Condition>& conditions) {
  for (const auto& item : recorded.items()) {
    const std::string label = item.key();
    const json& entry = item.value();
    auto given = std::find_if(conditions.begin(), conditions.end(),
                              [&](const Condition& c) { return c.label == label; });
    const std::string path = entry.at("path").get<std::string>();
    if (given == conditions.end()) {
      try {
        conditions.push_back(parse_conditions("", {label + "=" + path}, opt.model).back());
      } catch (const physics::ConfigError& e) {
        throw physics::ConfigError("--resume " + opt.out + ": recorded condition " + label + ": " + e.what());
      }
      given = conditions.end() - 1;
    } else if (given->checkpoint != path) {
      throw physics::ConfigError("--resume " + opt.out + ": --pretrained " + label + " was " + path +
                                 ", now " + given->checkpoint);
    }
    if (given->fingerprint != entry.at("fnv1a64").get<std::string>()) {
      throw physics::ConfigError("--resume " + opt.out + ": the checkpoint of condition " + label + " (" +
                                 path + ") changed since its first runs");
    }
  }
}

// --resume: the recorded evaluation in eval.json, which must have these settings; its random returns and
// runs go into `s`, its tasks and conditions are added.
void read_evaluation(const EvalOptions& opt, const fs::path& eval_json, const json& settings,
                     std::vector<Condition>& conditions, Summary& s) {
  try {
    const std::string text = ppo::read_regular_file(eval_json, ppo::kMaxMetricsBytes, "--resume:");
    if (!replay::json_nesting_within(text)) {
      throw physics::ConfigError("--resume " + opt.out + ": eval.json nests more than " +
                                 std::to_string(replay::kMaxJsonDepth) + " levels deep");
    }
    const json saved = json::parse(text);
    json old = saved.at("settings");
    const json recorded = old.value("pretrained", json::object());
    old.erase("pretrained");
    // An evaluation from before the precision key trained every run in fp32, and from before the chunk key
    // in chunks of 16 sequences (run_eval resumes such a one with 16).
    if (old.contains("train_config") && old["train_config"].is_object()) {
      json& tc = old["train_config"];
      if (!tc.contains("precision")) tc["precision"] = "fp32";
      if (!tc.contains("chunk_sequences")) tc["chunk_sequences"] = 16;
    }
    if (old != settings) {
      throw physics::ConfigError("--resume " + opt.out + ": its settings " + old.dump() +
                                 " differ from these " + settings.dump());
    }
    check_recorded_conditions(opt, recorded, conditions);
    for (auto& [task, value] : saved.at("random").items()) {
      s.random[task] = value.get<double>();
      if (std::find(s.tasks.begin(), s.tasks.end(), task) == s.tasks.end()) s.tasks.push_back(task);
    }
    for (const json& r : saved.at("runs")) {
      RunRecord run = record_of(r);
      // A finished run has one return and one agent-step count per iteration (the pages draw from both).
      if (run.returns.size() != size_t(opt.iterations) || run.agent_steps.size() != run.returns.size()) {
        throw physics::ConfigError(
            "--resume " + opt.out + ": eval.json's run of " + run.task + ", " + run.condition + ", seed " +
            std::to_string(run.seed) + " has " + std::to_string(run.returns.size()) + " returns and " +
            std::to_string(run.agent_steps.size()) + " agent-step counts; a finished run has " +
            std::to_string(opt.iterations) + " of each");
      }
      s.runs.push_back(std::move(run));
    }
  } catch (const json::exception& e) {
    throw physics::ConfigError("--resume " + opt.out + ": eval.json is not readable: " + e.what());
  } catch (const ppo::FileError& e) {
    throw physics::ConfigError(e.what());
  } catch (const std::system_error& e) {
    throw physics::ConfigError(e.what());
  }
}

// Each task's runs fit this machine's memory, and each checkpoint fits each task (model, entity types):
// tried on a one-env trainer now, not after hours of other runs.
void check_tasks_fit(const Summary& s, const ppo::TrainConfig& base,
                     const std::vector<Condition>& conditions) {
  for (const std::string& t : s.tasks) {
    ppo::TrainConfig c = base;
    c.scene = t;
    c.validate();
    check_memory("hns eval --tasks " + t + " --envs " + std::to_string(c.envs), c.estimated_bytes());
    c.envs = 1;
    for (const Condition& cond : conditions) {
      if (cond.checkpoint.empty()) continue;
      ppo::Trainer probe(c);
      try {
        probe.initialize_from(cond.checkpoint);
      } catch (const std::runtime_error& e) {
        throw physics::ConfigError("--pretrained " + cond.label + "=" + cond.checkpoint + " cannot start " +
                                   t + ": " + e.what());
      }
    }
  }
}

// One training run of the evaluation: `iterations` iterations of task t from the condition's checkpoint (or
// from scratch), with its returns per iteration.
RunRecord train_run(const ppo::TrainConfig& base, const std::string& t, const Condition& cond, int seed) {
  ppo::TrainConfig c = base;
  c.scene = t;
  c.seed = uint64_t(seed);
  c.init_from = cond.checkpoint;
  ppo::Trainer trainer(c);
  if (!cond.checkpoint.empty()) trainer.initialize_from(cond.checkpoint);
  RunRecord rec{t, cond.label, seed, {}, {}, 0};
  for (int i = 1; i <= c.iterations; ++i) {
    const ppo::IterationMetrics m = trainer.iterate();
    rec.returns.push_back(m.hider_reward);
    rec.agent_steps.push_back(m.agent_steps);
    rec.seconds += m.seconds;
    if (i % 10 == 0 || i == c.iterations) {
      std::printf("  %s / %s / seed %d: iteration %d/%d, return %.3f, %.0f agent-steps/s\n", t.c_str(),
                  cond.label.c_str(), seed, i, c.iterations, m.hider_reward, m.steps_per_s);
      std::fflush(stdout);
    }
  }
  return rec;
}

int run_eval(const EvalOptions& opt) {
  // Everything is checked before any work starts.
  if (opt.out.empty())
    throw physics::ConfigError("--out DIR is required (where eval.json, eval.md, eval.html go)");
  if (opt.resume && opt.overwrite) throw physics::ConfigError("--resume and --overwrite: give one");
  Summary s;
  s.tasks = parse_tasks(opt.tasks);
  std::vector<Condition> conditions = parse_conditions("scratch", opt.pretrained, opt.model);
  ppo::TrainConfig base = base_config(opt);
  const fs::path dir(opt.out);
  const fs::path eval_json = dir / "eval.json";
  // An evaluation from before chunk_sequences continues with the 16 its runs used (unless --set gives one,
  // which its recorded settings then refuse).
  const bool chunk_set = std::any_of(opt.sets.begin(), opt.sets.end(), [](const std::string& kv) {
    return kv.rfind("chunk_sequences=", 0) == 0;
  });
  if (opt.resume && !chunk_set && predates_chunk_key(eval_json)) base.chunk_sequences = 16;
  if (opt.seeds < 1 || opt.seeds > 100) {
    throw physics::ConfigError("--seeds " + std::to_string(opt.seeds) + " is invalid: must be in [1, 100]");
  }
  json settings = shared_settings(opt, base);

  check_out_folder(opt, dir, eval_json);
  std::error_code ec;
  if (fs::exists(eval_json, ec)) {
    if (!opt.resume && !opt.overwrite) {
      throw physics::ConfigError(
          "--out " + opt.out +
          " holds an evaluation (eval.json): --resume continues it, --overwrite starts over");
    }
    if (opt.resume) read_evaluation(opt, eval_json, settings, conditions, s);
  } else if (opt.resume) {
    throw physics::ConfigError("--resume " + opt.out + ": no eval.json there");
  }
  for (const Condition& c : conditions) s.conditions.push_back(c.label);
  json pretrained = json::object();
  for (const Condition& c : conditions) {
    if (!c.checkpoint.empty()) pretrained[c.label] = {{"path", c.checkpoint}, {"fnv1a64", c.fingerprint}};
  }
  settings["pretrained"] = pretrained;
  check_tasks_fit(s, base, conditions);
  fs::create_directories(dir, ec);
  if (ec) throw physics::ConfigError("--out " + opt.out + ": cannot create the folder: " + ec.message());

  auto write_all = [&]() {
    json j = {
        {"kind", "hns-eval"}, {"settings", settings}, {"random", json::object()}, {"runs", json::array()}};
    for (const auto& [task, value] : s.random) j["random"][task] = value;
    for (const RunRecord& r : s.runs) j["runs"].push_back(to_json(r));
    write_atomically(eval_json.string(), j.dump(1) + "\n");
    write_atomically((dir / "eval.md").string(), table_markdown(s, settings));
    write_atomically((dir / "eval.html").string(), page_html(s, settings));
  };

  std::printf("hns eval: %s x %s x %s, %s of %s each (model %s, %s)\n",
              count_text(static_cast<long long>(s.tasks.size()), "task").c_str(),
              count_text(static_cast<long long>(s.conditions.size()), "condition").c_str(),
              count_text(opt.seeds, "seed").c_str(), count_text(opt.iterations, "iteration").c_str(),
              count_text(opt.envs, "env").c_str(), opt.model.c_str(), threads_text(opt.threads).c_str());
  for (const std::string& t : s.tasks) {
    if (s.random.count(t)) continue;
    ppo::TrainConfig c = base;
    c.scene = t;
    s.random[t] = ppo::random_policy_return(c, opt.random_episodes);
    std::printf("  %s: random policy return %.3f (%s)\n", t.c_str(), s.random[t],
                count_text(opt.random_episodes, "episode").c_str());
    std::fflush(stdout);
    write_all();
  }
  for (const std::string& t : s.tasks) {
    for (const Condition& cond : conditions) {
      for (int seed = 1; seed <= opt.seeds; ++seed) {
        const bool done = std::any_of(s.runs.begin(), s.runs.end(), [&](const RunRecord& r) {
          return r.task == t && r.condition == cond.label && r.seed == seed;
        });
        if (done) continue;
        s.runs.push_back(train_run(base, t, cond, seed));
        write_all();
      }
    }
  }
  write_all();
  std::printf("\n%s\nhns eval: wrote %s, %s and %s\n", table_markdown(s, settings).c_str(), eval_json.c_str(),
              (dir / "eval.md").c_str(), (dir / "eval.html").c_str());
  return 0;
}

}  // namespace

void add_eval_command(CLI::App& app, std::vector<Command>& commands) {
  auto opt = std::make_shared<EvalOptions>();
  CLI::App* cmd = app.add_subcommand(
      "eval",
      "Transfer suite: train each task from scratch and from checkpoints over seeds (docs/transfer.md)");
  cmd->add_option("--out", opt->out, "Folder for eval.json, eval.md and eval.html")->required();
  cmd->add_option(
         "--tasks", opt->tasks,
         "Comma-separated transfer tasks, of " + batch::scene_list(", ", batch::SceneFamily::kTransfer))
      ->capture_default_str();
  cmd->add_option("--seeds", opt->seeds, "Seeds per task and condition (1 .. N)")->capture_default_str();
  cmd->add_option("--iterations", opt->iterations, "Training iterations per run (the fixed budget)")
      ->check(CLI::Range(1, 1000000))
      ->capture_default_str();
  cmd->add_option("--envs", opt->envs, "Envs per run")->check(CLI::Range(1, 1 << 20))->capture_default_str();
  cmd->add_option("--model", opt->model, "small | paper (a --pretrained checkpoint's model)")
      ->capture_default_str();
  cmd->add_option("--threads", opt->threads, "TBB threads (0 = all); results do not depend on it");
  cmd->add_option("--pretrained", opt->pretrained,
                  "LABEL=CHECKPOINT: a condition starting from that checkpoint's policy (repeatable)");
  cmd->add_option("--set", opt->sets, "A training config key for every run, KEY=VALUE (repeatable)");
  cmd->add_option("--random-episodes", opt->random_episodes, "Episodes of the random policy per task")
      ->check(CLI::Range(1, 1000000))
      ->capture_default_str();
  cmd->add_flag("--resume", opt->resume,
                "Continue the evaluation in --out: runs already in eval.json are kept");
  cmd->add_flag("--overwrite", opt->overwrite, "Start over when --out holds an evaluation");
  commands.push_back({cmd, [opt] { return run_eval(*opt); }});
}

}  // namespace hns::tools
