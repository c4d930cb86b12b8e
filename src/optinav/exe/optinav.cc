// The single optinav binary: `optinav <command> [options]`, one Run<Command> per subcommand.
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

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
    {"map", optinav::RunMap, "orthophoto map databases: build, info, locate frames"},
    {"sim", optinav::RunSim, "simulate stereo + IMU + GNSS sequences with weather (EuRoC, AirSim)"},
    {"mission", optinav::RunMission,
     "GNSS-denied missions to a target over an orthophoto map (30-run experiments)"},
    {"vio", optinav::RunVio, "stereo visual-inertial odometry on a EuRoC/ASL dataset"},
    {"bench", optinav::RunBench, "benchmarks: bench gnss (GNSS fusion table on simulated flights)"},
    {"demo", optinav::RunDemo, "run the end-to-end demo on generated data"},
};

void PrintUsage(std::FILE* out) {
  std::fprintf(out, "optinav %s: navigation when GNSS is jammed, spoofed or lost\n\n",
               OPTINAV_VERSION);
  std::fprintf(out,
               "usage: optinav <command> [options]   (optinav <command> --help)\n\ncommands:\n");
  for (const Command& c : kCommands) std::fprintf(out, "  %-10s %s\n", c.name, c.help);
  std::fprintf(out, "  %-10s %s\n", "version", "print the version");
}

}  // namespace

int main(int argc, char** argv) {
  optinav::InitLogging();
  if (argc < 2 || !std::strcmp(argv[1], "--help") || !std::strcmp(argv[1], "-h") ||
      !std::strcmp(argv[1], "help")) {
    PrintUsage(argc < 2 ? stderr : stdout);
    return argc < 2 ? EXIT_FAILURE : EXIT_SUCCESS;
  }
  const std::string name = argv[1];
  if (name == "version" || name == "--version") {
    std::printf("optinav %s\n", OPTINAV_VERSION);
    return EXIT_SUCCESS;
  }
  for (const Command& c : kCommands) {
    if (name == c.name) {
      // The subcommand sees "optinav <command>" as its program name.
      std::string program = std::string("optinav ") + c.name;
      argv[1] = program.data();
      return c.run(argc - 1, argv + 1);
    }
  }
  std::fprintf(stderr, "optinav: unknown command '%s'\n\n", name.c_str());
  PrintUsage(stderr);
  return 2;
}
