#include "platform/token.h"

#include <cstdlib>
#include <fstream>
#include <sstream>

#include "core/text.h"

namespace sandswim {

Result<std::string> LoadToken(const std::string& token_file, const std::function<const char*(const char*)>& getenv) {
  if (!token_file.empty()) {
    std::ifstream in(token_file);
    if (!in) return Status::InvalidArgument("--token-file", "cannot read " + token_file);
    std::stringstream text;
    text << in.rdbuf();
    std::string token(Trim(text.str()));
    if (token.empty()) return Status::InvalidArgument("--token-file", token_file + " is empty");
    return token;
  }
  const char* env = getenv("SANDSWIM_TOKEN");
  return std::string(Trim(env ? env : ""));
}

}  // namespace sandswim
