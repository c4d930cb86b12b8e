// The subcommands of the single `optinav` binary: each parses its own options and returns a
// process exit code (0 success, 1 failure with a logged reason, 2 bad usage).
#pragma once

namespace optinav {

int RunEval(int argc, char** argv);  // optinav eval ape|rpe ...
int RunDemo(int argc, char** argv);  // optinav demo ...
int RunMap(int argc, char** argv);   // optinav map build|info|locate ...

}  // namespace optinav
