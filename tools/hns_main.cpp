// hns command-line front end. Thin: each command (tools/cmd_*.cpp) parses and validates its flags and calls
// the libraries. Exit status: 0 success, 2 bad usage or configuration, 1 runtime failure.
#include <CLI/CLI.hpp>

#include <filesystem>
#include <iostream>
#include <new>
#include <optional>
#include <regex>
#include <string>
#include <vector>

#include "cli.hpp"
#include "nn/kernels.hpp"
#include "physics/scene.hpp"

namespace {

// Every value is checked the same way in every command: an empty value is an error (not "the default"), and
// an integer is written in decimal digits with an optional minus sign, nothing else (CLI11 alone also takes
// " 2", "+2", "0x2" and "010" as 8).
void add_value_checks(CLI::App& app) {
  const CLI::Validator non_empty(
      [](std::string& value) {
        return value.empty() ? std::string("an empty value is not allowed") : std::string();
      },
      "");
  const CLI::Validator decimal_integer(
      [](std::string& value) {
        const std::string digits = !value.empty() && value[0] == '-' ? value.substr(1) : value;
        bool ok = !digits.empty() && !(digits.size() > 1 && digits[0] == '0');
        for (char c : digits) ok = ok && c >= '0' && c <= '9';
        if (!ok) return "'" + value + "' is not a whole number (decimal digits, an optional minus sign)";
        return std::string();
      },
      "");
  // A real number in JSON's decimal form (CLI11 alone also takes nan, inf and hex floats, which pass its
  // range checks: nan compares false).
  const CLI::Validator decimal_number(
      [](std::string& value) {
        static const std::regex form(R"(-?(0|[1-9][0-9]*)(\.[0-9]+)?([eE][+-]?[0-9]+)?)");
        if (!std::regex_match(value, form))
          return "'" + value + "' is not a decimal number (digits, an optional sign, fraction and exponent)";
        return std::string();
      },
      "");
  for (CLI::App* sub : app.get_subcommands([](CLI::App*) { return true; })) {
    for (CLI::Option* opt : sub->get_options([](CLI::Option*) { return true; })) {
      if (opt->get_type_size() == 0) continue;  // a flag without a value
      opt->check(non_empty);
      if (opt->get_type_name().rfind("INT", 0) == 0) opt->check(decimal_integer);
      if (opt->get_type_name().rfind("FLOAT", 0) == 0) opt->check(decimal_number);
    }
  }
}

// What hns answers before CLI11 parses: --version, `hns help [COMMAND]`, an unknown command or an option
// before any command. The exit status, or nothing to go on parsing.
std::optional<int> answer_before_parsing(int argc, char** argv, const CLI::App& app,
                                         const std::vector<hns::tools::Command>& commands) {
  if (argc == 2 && (std::string(argv[1]) == "--version" || std::string(argv[1]) == "version")) {
    std::cout << "hns " << hns::tools::kHnsVersion << " (commit " << hns::tools::kHnsCommit << ", "
              << hns::nn::kernels::isa_description() << ")\n";
    return {0};
  }
  // `hns help` and `hns help COMMAND` are --help spelled as a command.
  if (argc > 1 && std::string(argv[1]) == "help") {
    if (argc > 2) {
      for (const hns::tools::Command& c : commands) {
        if (c.app->get_name() == argv[2]) {
          std::cout << c.app->help();
          return {0};
        }
      }
    }
    std::cout << app.help();
    return {argc > 2 ? 2 : 0};
  }

  // An unknown command gets named (CLI11 would only say that a subcommand is required).
  if (argc > 1 && argv[1][0] != '-') {
    bool known = false;
    for (const hns::tools::Command& c : commands) known = known || c.app->get_name() == argv[1];
    if (!known) {
      std::cerr << "hns: unknown command '" << argv[1] << "': use one of";
      for (const hns::tools::Command& c : commands) std::cerr << " " << c.app->get_name();
      std::cerr << " (hns --help lists them)\n";
      return {2};
    }
  }
  // Likewise an option before any command (CLI11 would only say that a subcommand is required).
  if (argc > 1 && argv[1][0] == '-' && std::string(argv[1]) != "-h" && std::string(argv[1]) != "--help") {
    std::cerr << "hns: unknown option '" << argv[1] << "' before a command: hns [--help | --version] COMMAND "
              << "[OPTIONS] (hns --help lists the commands)\n";
    return {2};
  }
  return std::nullopt;
}

// The parsed command, run; a failure's message and exit status (2: bad usage or configuration, 1: a runtime
// failure).
int run_command(const std::vector<hns::tools::Command>& commands) {
  try {
    for (const hns::tools::Command& c : commands) {
      if (c.app->parsed()) return c.run();
    }
  } catch (const hns::physics::ConfigError& e) {
    std::cerr << "hns: bad configuration: " << e.what() << "\n";
    return 2;
  } catch (const std::filesystem::filesystem_error& e) {
    // A path that cannot resolve (a symlink loop) is bad input; any other file system failure is not.
    if (e.code() == std::errc::too_many_symbolic_link_levels) {
      std::cerr << "hns: bad path: " << e.path1().string()
                << ": too many levels of symbolic links (a symlink loop?)\n";
      return 2;
    }
    std::cerr << "hns: error: " << e.what() << "\n";
    return 1;
  } catch (const std::bad_alloc&) {
    std::cerr << "hns: error: out of memory (use fewer envs, a smaller model or a bigger machine)\n";
    return 1;
  } catch (const std::exception& e) {
    std::cerr << "hns: error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  // A binary built for AVX-512 on an AVX2 machine says so instead of dying of an illegal instruction. The
  // start-up check in nn/isa_check.cpp already did this before main (static initialisers included); this
  // call is what links that check into the binary, and a second line of defence.
  if (const std::string lack = hns::nn::kernels::isa_unsupported(); !lack.empty()) {
    std::cerr << "hns: " << lack << "\n";
    return 2;
  }
  CLI::App app{"hns: hide-and-seek simulator and trainer (physics on ODE)"};
  app.name("hns");
  app.require_subcommand(1);
  std::vector<hns::tools::Command> commands;
  hns::tools::add_bench_command(app, commands);
  hns::tools::add_play_command(app, commands);
  hns::tools::add_replay_command(app, commands);
  hns::tools::add_train_command(app, commands);
  hns::tools::add_report_command(app, commands);
  hns::tools::add_eval_command(app, commands);
  hns::tools::add_counting_command(app, commands);
  hns::tools::add_export_command(app, commands);

  add_value_checks(app);
  if (const std::optional<int> status = answer_before_parsing(argc, argv, app, commands)) return *status;
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? 0 : 2;
  }
  return run_command(commands);
}
