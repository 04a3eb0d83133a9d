// sandswim-stand-in-engine: a STAND-IN for LIGGGHTS, for measuring and breaking the orchestration
// ONLY: the runs-per-second benchmark, the daemon crash trials
// (tests/crash_trials_test.cc) and the dashboard's browser tests (tests/browser/). It simulates nothing. It takes LIGGGHTS's command line (-in DECK
// -log LOG [-screen X]), writes a minimal valid log with the markers the worker reads, a short SO
// dump (drive decks) or a small bed.restart (bed decks), and exits 0. Its version line says what
// it is, so no result it produces can pass for a real one. No physics test uses it.
//
// Two environment variables, for the crash trials:
//   SANDSWIM_STAND_IN_SECONDS  how long it lasts (default 0: at once): a bed deck waits, then writes;
//                              a drive deck writes its dump's 11 frames over that time;
//   SANDSWIM_STAND_IN_STARTS   a file it appends its working directory to when it starts, so a
//                              test can count the engine starts of every run (one line each,
//                              written with one O_APPEND write: lines never interleave).
//
// It is written with plain POSIX calls and snprintf, not iostreams, so that it costs as little
// as a static program can: what the benchmark measures is sandswim's orchestration, not this.
#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

namespace {

// The number after `key` on the first line that starts (after blanks) with it, or `fallback`.
double After(const std::string& deck, const std::string& key, double fallback) {
  size_t pos = 0;
  while ((pos = deck.find(key, pos)) != std::string::npos) {
    size_t bol = deck.rfind('\n', pos);
    bol = bol == std::string::npos ? 0 : bol + 1;
    if (deck.find_first_not_of(" \t", bol) == pos) return std::strtod(deck.c_str() + pos + key.size(), nullptr);
    pos += key.size();
  }
  return fallback;
}

bool ReadAll(const char* path, std::string* out) {
  int fd = open(path, O_RDONLY | O_CLOEXEC);
  if (fd < 0) return false;
  char buf[16384];
  ssize_t n;
  while ((n = read(fd, buf, sizeof buf)) > 0) out->append(buf, static_cast<size_t>(n));
  close(fd);
  return n == 0;
}

bool WriteAll(const char* path, const std::string& text) {
  int fd = open(path, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) return false;
  const char* p = text.data();
  size_t left = text.size();
  while (left > 0) {
    ssize_t n = write(fd, p, left);
    if (n <= 0) break;
    p += n;
    left -= static_cast<size_t>(n);
  }
  close(fd);
  return left == 0;
}

}  // namespace

int main(int argc, char** argv) {
  const char* deck_file = nullptr;
  const char* log_file = "log.lammps";
  for (int i = 1; i + 1 < argc; ++i) {
    if (std::strcmp(argv[i], "-in") == 0)
      deck_file = argv[++i];
    else if (std::strcmp(argv[i], "-log") == 0)
      log_file = argv[++i];
    else if (std::strcmp(argv[i], "-screen") == 0 || std::strcmp(argv[i], "-var") == 0)
      ++i;
  }
  if (const char* starts = std::getenv("SANDSWIM_STAND_IN_STARTS")) {
    char cwd[4096];
    if (getcwd(cwd, sizeof cwd) != nullptr) {
      std::string line = std::string(cwd) + "\n";
      int fd = open(starts, O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
      if (fd >= 0) {
        (void)!write(fd, line.data(), line.size());
        close(fd);
      }
    }
  }
  double seconds = 0;
  if (const char* text = std::getenv("SANDSWIM_STAND_IN_SECONDS")) seconds = std::max(0.0, std::strtod(text, nullptr));
  std::string deck;
  if (deck_file == nullptr || !ReadAll(deck_file, &deck)) {
    std::fprintf(stderr, "ERROR: Cannot open input script %s\n", deck_file ? deck_file : "(none)");
    return 1;
  }
  std::string log = "LIGGGHTS (Version sandswim-stand-in-engine 0, NOT LIGGGHTS: a benchmark stand-in)\n";
  if (deck.find("read_restart") == std::string::npos) {  // a bed deck
    usleep(static_cast<useconds_t>(seconds * 1e6));
    WriteAll("bed.restart", "stand-in bed restart: no grains were simulated\n");
    log +=
        "SANDSWIM bed equilibrated ke 0 ke_peak 1\n"
        "SANDSWIM bed grains 1 so_z 0 grain_top 0.2 step 1\n"
        "SANDSWIM bed done\n";
    return WriteAll(log_file, log) ? 0 : 1;
  }
  // Steps the worker expects: chunks x steps per chunk, as the drive deck loops.
  const long long chunks = static_cast<long long>(After(deck, "variable c loop ", 1));
  // The chunk's run line is the one with "pre no post no".
  long long per_chunk = 1;
  size_t at = deck.find(" pre no post no");
  if (at != std::string::npos) {
    size_t run = deck.rfind("run ", at);
    if (run != std::string::npos) per_chunk = std::atoll(deck.c_str() + run + 4);
  }
  const long long steps = chunks * per_chunk;
  const double dt = After(deck, "timestep", 1e-5);
  // The SO's dump, a frame each tenth of the run; with SANDSWIM_STAND_IN_SECONDS the frames come
  // one by one over that time (each with one write), as a real engine's dump grows.
  const int dump_fd = open("so.dump", O_WRONLY | O_CREAT | O_TRUNC | O_APPEND | O_CLOEXEC, 0644);
  if (dump_fd < 0) return 1;
  char line[256];
  bool wrote = true;
  for (int k = 0; k <= 10; ++k) {
    if (k > 0) usleep(static_cast<useconds_t>(seconds * 1e5));
    int n = std::snprintf(line, sizeof line,
                          "ITEM: TIMESTEP\n%lld\nITEM: NUMBER OF ATOMS\n1\nITEM: BOX BOUNDS pp pp ff\n"
                          "-0.1 0.1\n-0.1 0.1\n-0.25 0.5\nITEM: ATOMS id x y z vx vy vz omegax omegay omegaz\n"
                          "1 0 0 %g 0 0 0 0 0 0\n",
                          steps * k / 10, 0.001 * k);
    wrote = wrote && write(dump_fd, line, static_cast<size_t>(n)) == n;
  }
  close(dump_fd);
  int n = std::snprintf(line, sizeof line,
                        "SANDSWIM drive start grains 1 so_z 0 surface 0.2\n"
                        "SANDSWIM drive stop duration step %lld t %g z 0.01\n",
                        steps, steps * dt);
  log.append(line, static_cast<size_t>(n));
  return wrote && WriteAll(log_file, log) ? 0 : 1;
}
