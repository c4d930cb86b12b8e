// The single optinav binary: `optinav [--log-level L] <command> [options]`, one Run<Command> per
// command. The top level goes through cli::RunCli like every command (same messages, exit 2 for
// a missing or unknown command); everything from the command name on is the command's.
#include <csignal>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include "optinav/exe/cli_runner.h"
#include "optinav/exe/commands.h"
#include "optinav/util/logging.h"

namespace {

struct Command {
  const char* name;
  int (*run)(int, char**);
  const char* help;
};

constexpr Command kCommands[] = {
    {"eval", optinav::RunEval, "evaluate trajectories: APE and RPE exactly as evo defines them"},
    {"map", optinav::RunMap, "orthophoto map databases: build, info, locate frames, render frames"},
    {"sim", optinav::RunSim, "simulate stereo + IMU + GNSS sequences with weather (EuRoC, AirSim)"},
    {"mission", optinav::RunMission,
     "GNSS-denied missions to a target over an orthophoto map (30-run experiments)"},
    {"vio", optinav::RunVio, "stereo visual-inertial odometry on a EuRoC/ASL dataset"},
    {"nav", optinav::RunNav,
     "map-aided inertial navigation: IMU + nadir camera + barometer + map fixes"},
    {"bench", optinav::RunBench,
     "benchmarks: bench gnss | weather | nav (GNSS fusion, weather, map-aided navigation tables)"},
    {"report", optinav::RunReport,
     "one self-contained HTML report (map, paths, fixes, errors) of a command's output"},
    {"demo", optinav::RunDemo, "run the end-to-end demo on generated data"},
};

std::string CommandList() {
  std::string s = "commands (optinav <command> --help):\n";
  for (const Command& c : kCommands) s += fmt::format("  {:<10} {}\n", c.name, c.help);
  return s + fmt::format("  {:<10} {}\n", "version", "print the version");
}

// Runs the command named first in `args` with the rest; a --log-level given before the command
// (`level`, empty when not given) is passed on to it.
int Dispatch(const CLI::App& app, std::vector<std::string> args, const std::string& level) {
  if (args.empty()) throw optinav::cli::UsageError("give a command (see the list in --help)", "");
  const std::string name = args.front();
  if (name == "help") {
    std::printf("%s", app.help().c_str());
    return 0;
  }
  if (name == "version") {
    std::printf("optinav %s\n", OPTINAV_VERSION);
    return 0;
  }
  for (const Command& c : kCommands) {
    if (name != c.name) continue;
    args.front() = std::string("optinav ") + c.name;  // the command's program name
    if (!level.empty()) args.insert(args.end(), {"--log-level", level});
    std::vector<char*> argv;
    for (std::string& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    return c.run(static_cast<int>(args.size()), argv.data());
  }
  throw optinav::cli::UsageError(fmt::format("unknown command '{}'", name), "");
}

}  // namespace

int main(int argc, char** argv) {
  // A file-size limit (ulimit -f) or a full quota makes write() fail with EFBIG instead of
  // killing the process: the writers then report it and leave the old file in place.
  std::signal(SIGXFSZ, SIG_IGN);
  optinav::InitLogging();
  CLI::App app{
      fmt::format("optinav {}: navigation when GNSS is jammed, spoofed or lost", OPTINAV_VERSION),
      "optinav"};
  app.prefix_command();  // the first positional (the command) and all after it are left over
  app.set_version_flag("--version", std::string("optinav ") + OPTINAV_VERSION);
  app.footer(CommandList());
  return optinav::cli::RunCli(app, argc, argv, [&] {
    const CLI::Option* level = app.get_option("--log-level");
    return Dispatch(app, app.remaining(), level->count() ? level->as<std::string>() : "");
  });
}
