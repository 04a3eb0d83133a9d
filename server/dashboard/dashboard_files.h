// The web dashboard's files compiled into the daemon (server/CMakeLists.txt): server/dashboard/'s
// index.html, app.js and app.css, and uPlot's script and style sheet from its pinned npm package.
// Served by server/http/routes.cc: the page at /, /campaign-runs/ID, /sweeps/ID, /runs/ID, /beds[/ID],
// /submit, /campaigns[/NAME[/edit]] and /new-campaign; the rest under /ui/NAME.
//
// Thread safety: immutable data.
#ifndef SANDSWIM_SERVER_DASHBOARD_FILES_H_
#define SANDSWIM_SERVER_DASHBOARD_FILES_H_

#include <optional>
#include <string_view>
#include <vector>

namespace sandswim {

// The bytes of a compiled-in dashboard file by its bare name ("app.js", "uPlot.iife.min.js").
std::optional<std::string_view> DashboardFile(std::string_view name);

// Every compiled-in dashboard file's name, sorted.
const std::vector<std::string_view>& DashboardFileNames();

}  // namespace sandswim

#endif  // SANDSWIM_SERVER_DASHBOARD_FILES_H_
