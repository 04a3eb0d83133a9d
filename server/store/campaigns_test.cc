#include "server/store/campaigns.h"

#include <stdlib.h>

#include <filesystem>

#include <gtest/gtest.h>

namespace sandswim {
namespace {

class CampaignsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string pattern = (std::filesystem::temp_directory_path() / "sandswim-campaigns-XXXXXX").string();
    ASSERT_NE(mkdtemp(pattern.data()), nullptr);
    dir_ = pattern;
    auto s = Store::Open((dir_ / "sandswim.db").string());
    ASSERT_TRUE(s.ok()) << s.status().ToString();
    store_ = std::move(s).value();
  }
  void TearDown() override {
    store_.reset();
    std::filesystem::remove_all(dir_);
  }
  std::filesystem::path dir_;
  std::unique_ptr<Store> store_;
};

TEST_F(CampaignsTest, TheBuiltInOneWhenNoneIsStored) {
  auto found = FindCampaign(*store_, "paper-58");
  ASSERT_TRUE(found.ok()) << found.status().ToString();
  EXPECT_FALSE(found->stored);
  EXPECT_EQ(found->campaign.sweeps.size(), BuiltinCampaign("paper-58")->sweeps.size());
  EXPECT_EQ(found->definition, *BuiltinCampaignDefinition("paper-58"));
  EXPECT_EQ(found->schedule, found->campaign.schedule);
}

TEST_F(CampaignsTest, AStoredOneWinsWithItsOwnColumns) {
  nlohmann::json definition = *BuiltinCampaignDefinition("paper-58");
  definition["scale"] = "mini";
  StoredCampaign row;
  row.name = "paper-58";
  row.definition = definition;
  row.schedule = "0 3 * * *";
  row.drift_tolerance_mps = 0.25;
  ASSERT_TRUE(store_->PutCampaign(row).ok());
  auto found = FindCampaign(*store_, "paper-58");
  ASSERT_TRUE(found.ok()) << found.status().ToString();
  EXPECT_TRUE(found->stored);
  EXPECT_EQ(found->campaign.scale, "mini");
  EXPECT_EQ(found->schedule, "0 3 * * *");
  EXPECT_EQ(found->drift_tolerance_mps, 0.25);
}

TEST_F(CampaignsTest, AnUnknownNameIsNotFoundAndNamesTheBuiltInOnes) {
  auto found = FindCampaign(*store_, "no-such", "campaigns[0]");
  ASSERT_FALSE(found.ok());
  EXPECT_EQ(found.status().code(), StatusCode::kNotFound);
  EXPECT_EQ(found.status().field(), "campaigns[0]");
  EXPECT_NE(found.status().reason().find("paper-58"), std::string::npos) << found.status().reason();
}

TEST_F(CampaignsTest, AStoredDefinitionThatNoLongerParsesIsCorruption) {
  StoredCampaign row;
  row.name = "broken";
  row.definition = nlohmann::json{{"name", "broken"}, {"sweeps", 7}};
  ASSERT_TRUE(store_->PutCampaign(row).ok());
  auto found = FindCampaign(*store_, "broken");
  ASSERT_FALSE(found.ok());
  EXPECT_EQ(found.status().code(), StatusCode::kCorruption);
}

}  // namespace
}  // namespace sandswim
