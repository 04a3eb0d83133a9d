#include "platform/token.h"

#include <cstdlib>
#include <fstream>
#include <sstream>

namespace sandswim {
namespace {

std::string Trim(std::string s) {
  const char* space = " \t\r\n";
  s.erase(0, s.find_first_not_of(space));
  s.erase(s.find_last_not_of(space) + 1);
  return s;
}

}  // namespace

Result<std::string> LoadToken(const std::string& token_file, const std::function<const char*(const char*)>& getenv) {
  if (!token_file.empty()) {
    std::ifstream in(token_file);
    if (!in) return Status::InvalidArgument("--token-file", "cannot read " + token_file);
    std::stringstream text;
    text << in.rdbuf();
    std::string token = Trim(text.str());
    if (token.empty()) return Status::InvalidArgument("--token-file", token_file + " is empty");
    return token;
  }
  const char* env = getenv("SANDSWIM_TOKEN");
  return Trim(env ? env : "");
}

}  // namespace sandswim
