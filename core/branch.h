// Branch: which way the paper says an oscillatory SO moves, by the sign of its Omega (paper
// Sec. 3.2, eq. 8): Omega < 0 rises (U_z > 0), Omega > 0 sinks (U_z < 0), Omega = 0 is neither.
// The one home of that rule: fits, claims, figures, the report, the adaptive planner and the
// figure routes ask BranchOf rather than compare Omega's sign themselves.
//
// Thread safety: pure functions.
#ifndef SANDSWIM_CORE_BRANCH_H_
#define SANDSWIM_CORE_BRANCH_H_

#include <optional>
#include <string_view>

#include "core/point.h"

namespace sandswim {

enum class Branch { kNone, kRising, kSinking };

// rising: Omega < 0; sinking: Omega > 0; none: Omega = 0.
Branch BranchOfOmega(double omega);
inline Branch BranchOf(const Point& p) { return BranchOfOmega(p.Omega); }

// The sign of U_z the paper expects on a branch: +1 rising, -1 sinking, 0 none.
int ExpectedUzSign(Branch b);
// The sign of Omega on a branch: -1 rising, +1 sinking, 0 none.
int OmegaSign(Branch b);

// "rising" | "sinking" | "none" (the API's and the figures' word).
std::string_view BranchName(Branch b);
// The inverse of BranchName for "rising" and "sinking"; nullopt for any other text.
std::optional<Branch> ParseBranch(std::string_view name);
// "Ω < 0" | "Ω > 0" | "Ω = 0": the branch's side, as figures and the report label it.
std::string_view OmegaSide(Branch b);

}  // namespace sandswim

#endif  // SANDSWIM_CORE_BRANCH_H_
