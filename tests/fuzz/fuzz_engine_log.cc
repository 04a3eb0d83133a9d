// Fuzz target: the engine's log, complete or still growing, as the worker reads it to judge a job
// (core/engine_log.h). tests/fuzz/run.sh builds and runs it.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "core/engine_log.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  (void)sandswim::ParseEngineLog(std::string_view(reinterpret_cast<const char*>(data), size));
  return 0;
}
