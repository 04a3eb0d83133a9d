// Files compiled into the binary (the list is in templates/CMakeLists.txt): deck templates
// ("templates/bed.in", "templates/drive.in"), shipped campaigns
// ("templates/campaigns/paper-58.json"), and whatever else that list names (SQL migrations).
//
// Thread safety: immutable data.
#ifndef SANDSWIM_CORE_EMBEDDED_H_
#define SANDSWIM_CORE_EMBEDDED_H_

#include <optional>
#include <string_view>

namespace sandswim {

// The bytes of a compiled-in file, by its path relative to the source root.
std::optional<std::string_view> EmbeddedFile(std::string_view name);

}  // namespace sandswim

#endif  // SANDSWIM_CORE_EMBEDDED_H_
