// bench_engine_rate: the engine's rate on a real prepared smoke bed, in particle-steps per second,
// and what the drive deck's chunk loop costs.
//
//   bench_engine_rate [--steps N] [--repeat R] [--json FILE]
//
// On smoke's prepared bed (tests/engine_fixture.h PrepareBed), the baseline drive (A = 0.03 m,
// f = 3 Hz, Omega = -80) for N steps (3000 by default) in these forms:
//   rendered    the drive deck as the daemon renders it: every chunk of kOmegaUpdateSteps steps sets
//               omega, runs `run 100 pre no post no`, checks both clearances and includes the
//               control file;
//   omega only  the same loop without the clearance checks and the control file;
//   chunks only the same loop without the omega update either (a bare `run 100 pre no post no`);
//   plain       the same physics in one `run N` at constant omega(0);
// on 1 rank and (rendered, plain) on 2, and two rendered runs side by side on 1 rank each.
// Wall time is the engine process's, from mpirun's start to its exit; a 100-step run of the same
// form on the same ranks is subtracted, so reading the restart and starting MPI do not count.
// Each form runs R times (1 by default); the fastest counts (the machine's other work only slows).
// The cost of a part is the ratio of the rates (rendered vs omega only: the checks and the control
// file; omega only vs chunks only: the omega update; chunks only vs plain: cutting the run).
// A program to run on demand, not a test: it asserts nothing. It says what else the machine ran
// (load average) -- a shared machine makes every figure noisy.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <regex>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/deck.h"
#include "core/engine_log.h"
#include "tests/engine_fixture.h"

namespace sandswim {
namespace {

using testing::EngineRun;

// Removes every line of `deck` that starts with `prefix`.
std::string DropLines(const std::string& deck, const std::string& prefix) {
  std::string out;
  size_t at = 0;
  while (at < deck.size()) {
    size_t end = deck.find('\n', at);
    end = end == std::string::npos ? deck.size() : end + 1;
    if (deck.compare(at, prefix.size(), prefix) != 0) out.append(deck, at, end - at);
    at = end;
  }
  return out;
}

std::string OmegaOnlyDeck(const std::string& deck) {
  std::string d = DropLines(deck, "  if ");
  return DropLines(d, "  include ");
}
std::string ChunksOnlyDeck(const std::string& deck) { return DropLines(OmegaOnlyDeck(deck), "  set group so"); }
// One `run` at constant omega(0) in place of the loop.
std::string PlainDeck(const std::string& deck, long long steps) {
  size_t cut = deck.find("run 0\nlabel chunk");
  return deck.substr(0, cut) + "run " + std::to_string(steps) + "\n";
}

double LoadAverage() {
  double one = 0;
  std::ifstream("/proc/loadavg") >> one;
  return one;
}

struct Timed {
  double wall_s = 0;
  bool ok = false;
};

Timed Run(const std::string& name, const std::string& deck, const std::string& bed, int ranks) {
  std::string dir = testing::CacheDir() + "/bench-rate/" + name;
  std::filesystem::remove_all(dir);
  auto t0 = std::chrono::steady_clock::now();
  EngineRun r = testing::RunDeck(dir, deck, bed, ranks);
  Timed t;
  t.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  t.ok = r.exit_code == 0 && r.log.find("Loop time") != std::string::npos;
  if (!t.ok) std::fprintf(stderr, "%s failed: see %s/log.liggghts\n", name.c_str(), dir.c_str());
  return t;
}

template <typename F>
Timed Best(int repeat, F run) {
  Timed best = run();
  for (int k = 1; k < repeat; ++k) {
    Timed t = run();
    if (t.ok && (!best.ok || t.wall_s < best.wall_s)) best = t;
  }
  return best;
}

struct Form {
  std::string name;
  std::string deck;       // N steps
  std::string deck_short;  // 100 steps
};

}  // namespace
}  // namespace sandswim

int main(int argc, char** argv) {
  using namespace sandswim;
  long long steps = 3000;
  int repeat = 1;
  std::string json_path;
  for (int i = 1; i < argc; ++i) {
    if (!std::strcmp(argv[i], "--steps") && i + 1 < argc) steps = std::atoll(argv[++i]);
    else if (!std::strcmp(argv[i], "--repeat") && i + 1 < argc) repeat = std::max(1, std::atoi(argv[++i]));
    else if (!std::strcmp(argv[i], "--json") && i + 1 < argc) json_path = argv[++i];
    else {
      std::fprintf(stderr, "usage: bench_engine_rate [--steps N] [--repeat R] [--json FILE]\n");
      return 2;
    }
  }
  std::setvbuf(stdout, nullptr, _IOLBF, 0);  // each line as it is measured
  const Scale& smoke = *FindScale("smoke");
  std::printf("engine: %s\n", testing::EngineVersion().c_str());
  std::string bed = testing::PrepareBed(smoke);
  EngineLog bed_log = ParseEngineLog(testing::ReadFile(std::filesystem::path(bed).parent_path() / kLogFile));
  const long long particles = (bed_log.bed_grains ? bed_log.bed_grains->grains : 0) + 1;  // grains + the SO
  const long long short_steps = kOmegaUpdateSteps;
  const double dt = kMaterials.dt;
  auto deck_for = [&](long long n) {
    return RenderDriveDeck(OscillatoryPoint(0.03, 3, -80, static_cast<double>(n) * dt), smoke, std::nullopt);
  };
  const std::string rendered = deck_for(steps), rendered_short = deck_for(short_steps);
  std::vector<Form> forms = {
      {"rendered", rendered, rendered_short},
      {"omega-only", OmegaOnlyDeck(rendered), OmegaOnlyDeck(rendered_short)},
      {"chunks-only", ChunksOnlyDeck(rendered), ChunksOnlyDeck(rendered_short)},
      {"plain", PlainDeck(rendered, steps), PlainDeck(rendered_short, short_steps)},
  };
  std::printf("smoke bed: %lld particles; %lld steps (%.3f s) of the baseline drive a run; load average %.2f at start\n",
              particles, steps, steps * dt, LoadAverage());

  nlohmann::json out = {{"particles", particles}, {"steps", steps}, {"forms", nlohmann::json::array()}};
  auto rate = [&](const Timed& long_run, const Timed& short_run) {
    double w = long_run.wall_s - short_run.wall_s;
    return long_run.ok && short_run.ok && w > 0 ? particles * static_cast<double>(steps - short_steps) / w : 0.0;
  };
  std::printf("\n%-22s %6s %14s %12s %10s\n", "form", "ranks", "p-steps/s", "s/p-step", "load");
  double rates[4][3] = {};
  for (int ranks : {1, 2}) {
    for (size_t i = 0; i < forms.size(); ++i) {
      if (ranks == 2 && (forms[i].name == "omega-only" || forms[i].name == "chunks-only")) continue;
      const std::string tag = forms[i].name + "-" + std::to_string(ranks);
      Timed s = Best(repeat, [&] { return Run(tag + "-short", forms[i].deck_short, bed, ranks); });
      Timed l = Best(repeat, [&] { return Run(tag, forms[i].deck, bed, ranks); });
      double r = rate(l, s);
      rates[i][ranks] = r;
      double load = LoadAverage();
      std::printf("%-22s %6d %14.4g %12.4g %10.2f\n", forms[i].name.c_str(), ranks, r, r > 0 ? 1 / r : 0.0, load);
      out["forms"].push_back({{"form", forms[i].name}, {"ranks", ranks}, {"particle_steps_per_s", r},
                              {"wall_s", l.wall_s}, {"startup_wall_s", s.wall_s}, {"load_after", load}});
    }
  }
  // Two rendered runs side by side, one rank each.
  Timed s = Best(repeat, [&] { return Run("side-short", rendered_short, bed, 1); });
  Timed a, b;
  for (int k = 0; k < repeat; ++k) {
    Timed x, y;
    std::thread ta([&] { x = Run("side-a", rendered, bed, 1); });
    std::thread tb([&] { y = Run("side-b", rendered, bed, 1); });
    ta.join();
    tb.join();
    if (k == 0 || x.wall_s + y.wall_s < a.wall_s + b.wall_s) a = x, b = y;
  }
  double ra = rate(a, s), rb = rate(b, s);
  std::printf("%-22s %6d %14.4g %12.4g %10.2f  (each: %.4g and %.4g)\n", "rendered, 2 side by side", 1, ra + rb,
              ra + rb > 0 ? 2 / (ra + rb) : 0.0, LoadAverage(), ra, rb);
  out["side_by_side"] = {{"particle_steps_per_s", {ra, rb}}, {"wall_s", {a.wall_s, b.wall_s}}};

  auto cost = [](double slow, double fast) { return slow > 0 && fast > 0 ? (fast / slow - 1) * 100 : 0.0; };
  std::printf("\ncost, 1 rank (time added over the faster form):\n");
  std::printf("  checks + control file (rendered vs omega only)      %+.1f %%\n", cost(rates[0][1], rates[1][1]));
  std::printf("  omega update (omega only vs chunks only)            %+.1f %%\n", cost(rates[1][1], rates[2][1]));
  std::printf("  cutting the run in chunks (chunks only vs plain)    %+.1f %%\n", cost(rates[2][1], rates[3][1]));
  std::printf("  the whole chunk loop (rendered vs plain)            %+.1f %%\n", cost(rates[0][1], rates[3][1]));
  std::printf("  on 2 ranks, the whole chunk loop                    %+.1f %%\n", cost(rates[0][2], rates[3][2]));
  std::printf("2 ranks vs 1, rendered: %.2fx; two runs side by side vs one alone: %.2fx the throughput\n",
              rates[0][1] > 0 ? rates[0][2] / rates[0][1] : 0.0, rates[0][1] > 0 ? (ra + rb) / rates[0][1] : 0.0);
  out["load_average_end"] = LoadAverage();
  if (!json_path.empty()) std::ofstream(json_path) << out.dump(2) << "\n";
  return 0;
}
