// Small text helpers the parsers and messages share: one home, so that each reads alike.
#ifndef SANDSWIM_CORE_TEXT_H_
#define SANDSWIM_CORE_TEXT_H_

#include <string>
#include <string_view>

namespace sandswim {

// `s` without white space (std::isspace) at either end.
std::string_view Trim(std::string_view s);

bool StartsWith(std::string_view s, std::string_view prefix);

// `v` as printf's %.<digits>g: "80", "0.03", "1e-05" (6 digits: what %g prints).
std::string Num(double v, int digits = 6);

}  // namespace sandswim

#endif  // SANDSWIM_CORE_TEXT_H_
