// sandswim-stand-in-engine: a STAND-IN for LIGGGHTS, for the orchestration benchmark of issue 4
// ONLY (runs per second through daemon + worker). It simulates nothing. It takes LIGGGHTS's
// command line (-in DECK -log LOG [-screen X]), writes a minimal valid log with the markers the
// worker reads, a short SO dump (drive decks) or a small bed.restart (bed decks), and exits 0 at
// once. Its version line says what it is, so no result it produces can pass for a real one.
// No real test uses it.
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
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

}  // namespace

int main(int argc, char** argv) {
  std::string deck_file, log_file = "log.lammps";
  for (int i = 1; i + 1 < argc; ++i) {
    std::string a = argv[i];
    if (a == "-in") deck_file = argv[++i];
    else if (a == "-log") log_file = argv[++i];
    else if (a == "-screen" || a == "-var") ++i;
  }
  std::ifstream in(deck_file);
  if (!in) {
    std::fprintf(stderr, "ERROR: Cannot open input script %s\n", deck_file.c_str());
    return 1;
  }
  std::stringstream ss;
  ss << in.rdbuf();
  const std::string deck = ss.str();
  std::ofstream log(log_file);
  log << "LIGGGHTS (Version sandswim-stand-in-engine 0, NOT LIGGGHTS: a benchmark stand-in)\n";
  if (deck.find("read_restart") == std::string::npos) {  // a bed deck
    std::ofstream("bed.restart") << "stand-in bed restart: no grains were simulated\n";
    log << "SANDSWIM bed equilibrated ke 0 ke_peak 1\n"
        << "SANDSWIM bed grains 1 so_z 0 grain_top 0.2 step 1\n"
        << "SANDSWIM bed done\n";
    return 0;
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
  std::ofstream dump("so.dump");
  for (int k = 0; k <= 10; ++k) {
    long long step = steps * k / 10;
    dump << "ITEM: TIMESTEP\n" << step << "\nITEM: NUMBER OF ATOMS\n1\nITEM: BOX BOUNDS pp pp ff\n"
         << "-0.1 0.1\n-0.1 0.1\n-0.25 0.5\nITEM: ATOMS id x y z vx vy vz omegax omegay omegaz\n"
         << "1 0 0 " << 0.001 * k << " 0 0 0 0 0 0\n";
  }
  log << "SANDSWIM drive start grains 1 so_z 0 surface 0.2\n"
      << "SANDSWIM drive stop duration step " << steps << " t " << steps * dt << " z 0.01\n";
  return 0;
}
