// Files compiled into core (the list is in templates/CMakeLists.txt): deck templates
// ("templates/bed.in", "templates/drive.in") and shipped campaigns
// ("templates/campaigns/paper-58.json"), and the claims' calibration tables
// ("templates/calibration/paper-58.smoke.K1.json", core/claim_rates.h). The migrations and the API document are the daemon's
// (server/store/schema_files.h).
//
// Thread safety: immutable data.
#ifndef SANDSWIM_CORE_EMBEDDED_H_
#define SANDSWIM_CORE_EMBEDDED_H_

#include <optional>
#include <string_view>
#include <vector>

namespace sandswim {

// The bytes of a compiled-in file, by its path relative to the source root.
std::optional<std::string_view> EmbeddedFile(std::string_view name);

// Every compiled-in file's name, sorted.
const std::vector<std::string_view>& EmbeddedFileNames();

}  // namespace sandswim

#endif  // SANDSWIM_CORE_EMBEDDED_H_
