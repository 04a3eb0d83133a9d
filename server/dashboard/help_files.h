// The documentation compiled into the daemon (server/CMakeLists.txt): every docs/**/*.md of the
// repository, by its path ("docs/how-to/sweeps.md"), so that the dashboard's help pages
// (/help/docs/...) show the docs of the daemon that serves them. Served as Markdown under
// /help-files/ by server/http/routes.cc; the page renders it (server/dashboard/app.js).
//
// Thread safety: immutable data.
#ifndef SANDSWIM_SERVER_DASHBOARD_HELP_FILES_H_
#define SANDSWIM_SERVER_DASHBOARD_HELP_FILES_H_

#include <optional>
#include <string_view>
#include <vector>

namespace sandswim {

// The bytes of a compiled-in docs page by its path relative to the repository ("docs/index.md").
std::optional<std::string_view> HelpFile(std::string_view name);

// Every compiled-in docs page's path, sorted.
const std::vector<std::string_view>& HelpFileNames();

}  // namespace sandswim

#endif  // SANDSWIM_SERVER_DASHBOARD_HELP_FILES_H_
