// Fuzz target: engine dump text -- the SO's trajectory as the worker follows it while the engine
// writes it, and a full-bed snapshot as the daemon checks an upload (core/dump_reader.h,
// core/trajectory.h, core/snapshot.h). The first byte splits the rest into two chunks, so frames
// torn across reads are tried too. tests/fuzz/run.sh builds and runs it.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "core/dump_reader.h"
#include "core/snapshot.h"
#include "core/trajectory.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  const std::string_view text(reinterpret_cast<const char*>(data) + 1, size - 1);
  const size_t cut = text.empty() ? 0 : data[0] % (text.size() + 1);
  sandswim::DumpReader reader;
  sandswim::SoSampleSink sink(1e-5);
  if (reader.Feed(text.substr(0, cut), sink).ok() && reader.Feed(text.substr(cut), sink).ok()) (void)reader.Finish();
  (void)sink.Take();
  auto snapshot = sandswim::ParseBedSnapshot(text);
  if (snapshot.ok()) {
    (void)sandswim::SliceThroughSo(*snapshot);
    (void)sandswim::BedSnapshotVtk(*snapshot, "fuzz");
  }
  return 0;
}
