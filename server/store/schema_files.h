// Files of schema/ compiled into the daemon (templates/CMakeLists.txt): every database migration
// (schema/NNN_*.sql) and the OpenAPI document. The deck templates and campaigns, which core needs,
// are core/embedded.h's.
//
// Thread safety: immutable data.
#ifndef SANDSWIM_SERVER_SCHEMA_FILES_H_
#define SANDSWIM_SERVER_SCHEMA_FILES_H_

#include <optional>
#include <string_view>
#include <vector>

namespace sandswim {

// The bytes of a compiled-in file, by its path relative to the source root ("schema/openapi.json").
std::optional<std::string_view> SchemaFile(std::string_view name);

// Every compiled-in file's name, sorted (the migrations: "schema/001_init.sql", ...).
const std::vector<std::string_view>& SchemaFileNames();

}  // namespace sandswim

#endif  // SANDSWIM_SERVER_SCHEMA_FILES_H_
