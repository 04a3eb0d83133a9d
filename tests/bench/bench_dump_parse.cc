// bench_dump_parse: how fast the streaming DumpReader (core/dump_reader.h) reads a LIGGGHTS dump,
// next to `wc -l` on the same file (the goal: at least half of wc -l's speed). The figure
// compared is the worker's path: the file in 1 MB chunks fed to DumpReader::Feed(chunk, sink) with
// the SoSampleSink that makes the run's samples (core/trajectory.h); a DumpFrameCollector (every
// frame copied into a DumpFrame, what tools and tests use) is timed too.
//
// Usage: bench_dump_parse [FILE] [MB]
//   With no FILE, generates a dump of about MB megabytes (default 200) of 10-column granular
//   frames in /tmp, reads it once to warm the page cache, then times both.
#include <sys/resource.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "core/dump_reader.h"
#include "core/trajectory.h"

namespace {

using Clock = std::chrono::steady_clock;

void Generate(const std::string& path, double megabytes) {
  std::ofstream out(path, std::ios::binary);
  std::mt19937_64 rng(42);
  std::uniform_real_distribution<double> u(-1, 1);
  const int atoms = 10000;
  char line[512];
  size_t bytes = 0;
  for (long step = 0; bytes < megabytes * 1e6; step += 100) {
    std::string frame = "ITEM: TIMESTEP\n" + std::to_string(step) + "\nITEM: NUMBER OF ATOMS\n" +
                        std::to_string(atoms) +
                        "\nITEM: BOX BOUNDS pp pp ff\n-0.1 0.1\n-0.19 0.19\n-0.25 0.65\n"
                        "ITEM: ATOMS id x y z vx vy vz omegax omegay omegaz \n";
    for (int i = 1; i <= atoms; ++i) {
      // LIGGGHTS writes %g: 6 significant digits.
      int n =
          std::snprintf(line, sizeof(line), "%d %g %g %g %g %g %g %g %g %g \n", i, 0.1 * u(rng), 0.19 * u(rng),
                        0.3 * u(rng), 1e-3 * u(rng), 0.5 * u(rng), 1e-2 * u(rng), 80 * u(rng), 5 * u(rng), 5 * u(rng));
      frame.append(line, static_cast<size_t>(n));
    }
    out << frame;
    bytes += frame.size();
  }
}

// CPU seconds (user + system) of this process, or of its reaped children.
double CpuSeconds(int who) {
  rusage ru{};
  getrusage(who, &ru);
  return ru.ru_utime.tv_sec + ru.ru_utime.tv_usec * 1e-6 + ru.ru_stime.tv_sec + ru.ru_stime.tv_usec * 1e-6;
}

double FileMegabytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  return static_cast<double>(in.tellg()) / 1e6;
}

}  // namespace

int main(int argc, char** argv) {
  std::string path = argc > 1 ? argv[1] : "";
  const double want_mb = argc > 2 ? std::atof(argv[2]) : 200;
  if (path.empty()) {
    path = "/tmp/sandswim_bench_dump_parse.dump";
    std::printf("generating %.0f MB dump at %s ...\n", want_mb, path.c_str());
    Generate(path, want_mb);
  }
  const double mb = FileMegabytes(path);
  // Warm the page cache so both measure parsing, not the disk.
  if (std::system(("cat '" + path + "' > /dev/null").c_str()) != 0) return 1;

  // The path the worker uses (workers/worker.cc): frames lent to a sink, SoSampleSink making the
  // SO's samples (SamplesFromDump); a DumpFrameCollector's copies next to it.
  struct Timing {
    double cpu = 0, wall = 0;
    long frames = 0, atoms = 0;
  };
  auto time_path = [&](bool sink_path, Timing* t) -> bool {
    auto t0 = Clock::now();
    const double cpu0 = CpuSeconds(RUSAGE_SELF);
    sandswim::DumpReader reader;
    // A file made of several dumps back to back (steps start again): one SoSampleSink per dump.
    struct Samples final : sandswim::DumpFrameSink {
      sandswim::SoSampleSink sink{1e-5};
      int64_t last_step = -1;
      long samples = 0;
      bool ok = true;
      void Restart() {
        auto got = sink.Take();
        ok = ok && got.ok();
        if (!got.ok()) std::fprintf(stderr, "%s\n", got.status().ToString().c_str());
        samples += got.ok() ? static_cast<long>(got->size()) : 0;
        sink = sandswim::SoSampleSink(1e-5);
      }
      void OnFrame(const sandswim::DumpFrameView& f) override {
        if (f.step <= last_step) Restart();
        last_step = f.step;
        sink.OnFrame(f);
      }
    } samples;
    sandswim::DumpFrameCollector copies;
    std::ifstream in(path, std::ios::binary);
    std::vector<char> buf(1 << 20);
    while (in) {
      in.read(buf.data(), static_cast<std::streamsize>(buf.size()));
      if (in.gcount() <= 0) break;
      const std::string_view chunk(buf.data(), static_cast<size_t>(in.gcount()));
      sandswim::Status s = sink_path ? reader.Feed(chunk, samples) : reader.Feed(chunk, copies);
      if (!s.ok()) {
        std::fprintf(stderr, "%s\n", s.ToString().c_str());
        return false;
      }
      if (!sink_path) {
        for (const auto& f : copies.Take()) {
          ++t->frames;
          t->atoms += f.atoms;
        }
      }
    }
    if (sink_path) {
      samples.Restart();
      if (!samples.ok) return false;
      t->frames = samples.samples;
    }
    t->wall = std::chrono::duration<double>(Clock::now() - t0).count();
    t->cpu = CpuSeconds(RUSAGE_SELF) - cpu0;
    return true;
  };
  Timing sink, queue;
  if (!time_path(true, &sink) || !time_path(false, &queue)) return 1;
  const double parse_cpu = sink.cpu, parse_s = sink.wall;
  const long frames = queue.frames, atoms = queue.atoms;

  const double child0 = CpuSeconds(RUSAGE_CHILDREN);
  const auto t0 = Clock::now();
  if (std::system(("exec wc -l '" + path + "' > /dev/null").c_str()) != 0) return 1;
  const double wc_s = std::chrono::duration<double>(Clock::now() - t0).count();
  const double wc_cpu = CpuSeconds(RUSAGE_CHILDREN) - child0;

  std::printf("file: %s, %.1f MB, %ld frames, %ld atom lines\n", path.c_str(), mb, frames, atoms);
  // CPU time is the fair figure on a shared machine; wall time is printed too.
  std::printf("DumpReader, worker path (1 MB chunks -> Feed(chunk, SoSampleSink), %ld samples):\n", sink.frames);
  std::printf("DumpReader: %.3f s CPU = %.0f MB/s (wall %.3f s = %.0f MB/s)\n", parse_cpu, mb / parse_cpu, parse_s,
              mb / parse_s);
  std::printf("DumpFrameCollector (DumpFrame copies): %.3f s CPU = %.0f MB/s\n", queue.cpu, mb / queue.cpu);
  std::printf("wc -l:      %.3f s CPU = %.0f MB/s (wall %.3f s = %.0f MB/s, includes sh)\n", wc_cpu, mb / wc_cpu, wc_s,
              mb / wc_s);
  std::printf("ratio DumpReader / wc -l = %.2f by CPU time, %.2f by wall time (goal >= 0.5)\n", wc_cpu / parse_cpu,
              wc_s / parse_s);
  return 0;
}
