// Files compiled into the binary from templates/ (see templates/CMakeLists.txt): deck templates
// ("bed.in", "drive.in") and shipped campaigns ("campaigns/paper-58.json").
//
// Thread safety: immutable data.
#ifndef SANDSWIM_CORE_EMBEDDED_H_
#define SANDSWIM_CORE_EMBEDDED_H_

#include <optional>
#include <string_view>

namespace sandswim {

// The bytes of a file under templates/, by its path relative to templates/.
std::optional<std::string_view> EmbeddedFile(std::string_view name);

}  // namespace sandswim

#endif  // SANDSWIM_CORE_EMBEDDED_H_
