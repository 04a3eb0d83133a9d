#include "core/branch.h"

#include <gtest/gtest.h>

namespace sandswim {
namespace {

TEST(BranchTest, RisingMeansOmegaBelowZero) {
  Point p;
  p.Omega = -10;
  EXPECT_EQ(BranchOf(p), Branch::kRising);
  EXPECT_EQ(ExpectedUzSign(BranchOf(p)), 1);
  EXPECT_EQ(OmegaSign(BranchOf(p)), -1);
  p.Omega = 10;
  EXPECT_EQ(BranchOf(p), Branch::kSinking);
  EXPECT_EQ(ExpectedUzSign(BranchOf(p)), -1);
  EXPECT_EQ(OmegaSign(BranchOf(p)), 1);
  p.Omega = 0;
  EXPECT_EQ(BranchOf(p), Branch::kNone);
  EXPECT_EQ(ExpectedUzSign(BranchOf(p)), 0);
}

TEST(BranchTest, NamesRoundTripAndOnlyBranchesParse) {
  for (Branch b : {Branch::kRising, Branch::kSinking}) EXPECT_EQ(ParseBranch(BranchName(b)), b);
  EXPECT_EQ(BranchName(Branch::kRising), "rising");
  EXPECT_EQ(OmegaSide(Branch::kSinking), "Ω > 0");
  EXPECT_FALSE(ParseBranch("none").has_value());
  EXPECT_FALSE(ParseBranch("Rising").has_value());
  EXPECT_FALSE(ParseBranch("").has_value());
}

}  // namespace
}  // namespace sandswim
