// prt: bake precomputed radiance transfer, relight it, inspect it.
// Thin on purpose: parse the command line, call the libraries, report. Each subcommand is one
// file (X_command.{h,cpp}: an XArgs struct, addX, runX) and one row of the table below, as the
// commands of pbrt-v4's cmd/imgtool.cpp. Errors are caught once, here: bad input prints one line
// and exits 1; usage errors (CLI11's checks, UsageError) print one line with a hint and exit 2.
#include <chrono>
#include <csignal>
#include <cstdio>
#include <functional>
#include <new>
#include <string>
#include <thread>
#include <vector>

#include <CLI/CLI.hpp>

#include "bake_command.h"
#include "cli_checks.h"
#include "info_command.h"
#include "light_command.h"
#include "merge_command.h"
#include "probe_command.h"
#include "prt/bake/checkpoint.h"
#include "prt/bake/ranks.h"
#include "prt/error.h"
#include "prt/huge_pages.h"
#include "prt/version.h"
#include "relight_command.h"
#include "render_command.h"

namespace {

using namespace prt;
using namespace prt::tools;

constexpr int kUsageExit = 2;

// One line for a usage error, with where to look.
std::string usageLine(const std::string& what) { return cat("prt: ", what, " (see --help)\n"); }

// Prints an error's line once for all ranks of an MPI bake (ranks.h) and ends them all: rank 0
// prints at once and stops every rank; another rank first leaves rank 0 a moment, so that an
// error every rank meets (a missing scene) is printed by rank 0 alone and one a rank meets on
// its own still is. One process: prints. Returns `code`.
int report(const std::string& line, int code, int waitMs = 2000) {
  if (bake::launcherRank() > 0) std::this_thread::sleep_for(std::chrono::milliseconds(waitMs));
  std::fprintf(stderr, "%s", line.c_str());
  std::fflush(stderr);
  bake::stopAllRanks(code);
  return code;
}

// One subcommand: its name and summary, how it adds its options, how it runs.
struct Command {
  const char* name;
  const char* summary;
  std::function<void(CLI::App&)> add;
  std::function<int()> run;
  CLI::App* app = nullptr;
};

}  // namespace

int main(int argc, char** argv) {
  tuneHeap();  // page faults cost ~12 µs each on VMs (prt/huge_pages.h)
  CLI::App app{"prt: precomputed radiance transfer. Bake once, relight with a dot product."};
  app.require_subcommand(1);
  app.set_version_flag("--version", cat("prt ", kVersion));
  app.get_formatter()->column_width(34);
  // Usage errors in one line (CLI11's default adds a second).
  app.failure_message([](const CLI::App*, const CLI::Error& e) { return usageLine(e.what()); });

  BakeArgs bake;
  RelightArgs relight;
  LightArgs light;
  ProbeArgs probe;
  RenderArgs render;
  InfoArgs info;
  MergeArgs merge;
  std::vector<Command> commands = {
      {"bake", "Bake per-vertex SH transfer of a glTF scene into a .glb", [&](CLI::App& c) { addBake(c, bake); },
       [&] { return runBake(bake); }},
      {"relight",
       "Relight a baked scene: per-vertex exitant radiance (diffuse, view-independent) as _RADIANCE (COLOR_0: "
       "clamped for viewers)",
       [&](CLI::App& c) { addRelight(c, relight); }, [&] { return runRelight(relight); }},
      {"light", "Project lighting to SH and write it as JSON", [&](CLI::App& c) { addLight(c, light); },
       [&] { return runLight(light); }},
      {"probe", "Query a probe grid: incident radiance SH and irradiance at points",
       [&](CLI::App& c) { addProbe(c, probe); }, [&] { return runProbe(probe); }},
      {"render", "Render relit frames of a baked scene headlessly (EXR, PNG, MP4)",
       [&](CLI::App& c) { addRender(c, render); }, [&] { return runRender(render); }},
      {"info", "Describe baked or input files", [&](CLI::App& c) { addInfo(c, info); }, [&] { return runInfo(info); }},
      {"merge", "Join the shards of a bake stage (prt bake --shard I/N) into its checkpoint",
       [&](CLI::App& c) { addMerge(c, merge); }, [&] { return runMerge(merge); }},
  };
  for (Command& c : commands) {
    c.app = app.add_subcommand(c.name, c.summary);
    c.add(*c.app);
  }

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    if (e.get_exit_code() != 0 && bake::launcherRank() > 0) {  // every rank has the same arguments
      std::this_thread::sleep_for(std::chrono::milliseconds(2000));
      return kUsageExit;
    }
    return app.exit(e) == 0 ? 0 : kUsageExit;
  }
  try {
    for (const Command& c : commands)
      if (c.app->parsed()) return c.run();
  } catch (const UsageError& e) {
    return report(usageLine(e.what()), kUsageExit);
  } catch (const Interrupted& e) {
    // Every rank saves before it stops: rank 0's may take a while.
    return report(cat("prt: ", e.what(), "\n"), 128 + (bake::interruptSignal() ? bake::interruptSignal() : SIGINT),
                  3000);
  } catch (const Error& e) {
    return report(cat("prt: ", e.what(), "\n"), 1);
  } catch (const std::bad_alloc&) {
    return report("prt: out of memory\n", 1);
  } catch (const std::exception& e) {
    return report(cat("prt: unexpected error: ", e.what(), "\n"), 1);
  }
  return 0;
}
