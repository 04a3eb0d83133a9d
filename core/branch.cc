#include "core/branch.h"

namespace sandswim {

Branch BranchOfOmega(double omega) {
  if (omega < 0) return Branch::kRising;
  if (omega > 0) return Branch::kSinking;
  return Branch::kNone;
}

int ExpectedUzSign(Branch b) { return b == Branch::kRising ? 1 : b == Branch::kSinking ? -1 : 0; }

int OmegaSign(Branch b) { return -ExpectedUzSign(b); }

std::string_view BranchName(Branch b) {
  switch (b) {
    case Branch::kRising:
      return "rising";
    case Branch::kSinking:
      return "sinking";
    case Branch::kNone:
      break;
  }
  return "none";
}

std::optional<Branch> ParseBranch(std::string_view name) {
  if (name == "rising") return Branch::kRising;
  if (name == "sinking") return Branch::kSinking;
  return std::nullopt;
}

std::string_view OmegaSide(Branch b) {
  switch (b) {
    case Branch::kRising:
      return "Ω < 0";
    case Branch::kSinking:
      return "Ω > 0";
    case Branch::kNone:
      break;
  }
  return "Ω = 0";
}

}  // namespace sandswim
