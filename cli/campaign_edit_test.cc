#include "cli/campaign_edit.h"

#include <stdlib.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace sandswim::cli {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;
using ::testing::HasSubstr;

std::string ReadAll(const std::string& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

class CampaignEditTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string pattern = (fs::temp_directory_path() / "sandswim-campaign-edit-XXXXXX").string();
    ASSERT_NE(mkdtemp(pattern.data()), nullptr);
    dir_ = pattern;
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  std::string dir_;
};

TEST(EditorCommandTest, VisualThenEditorThenVi) {
  std::map<std::string, std::string> vars;
  auto getenv = [&vars](const char* name) -> const char* {
    auto it = vars.find(name);
    return it == vars.end() ? nullptr : it->second.c_str();
  };
  EXPECT_EQ(EditorCommand(getenv), "vi");
  vars["EDITOR"] = "nano";
  EXPECT_EQ(EditorCommand(getenv), "nano");
  vars["VISUAL"] = "";  // set but empty: not an editor
  EXPECT_EQ(EditorCommand(getenv), "nano");
  vars["VISUAL"] = "code --wait";
  EXPECT_EQ(EditorCommand(getenv), "code --wait");
}

// The real runner: the command's words are split by the shell, the path is one argument whatever
// it holds, and a failing or missing editor is an error that says what to do.
TEST_F(CampaignEditTest, OpenInEditorRunsTheCommandOnThePath) {
  const std::string path = dir_ + "/a file with 'quotes' and $dollars.json";
  std::ofstream(path) << "{\"replicates\": 1}";
  ASSERT_TRUE(OpenInEditor("sed -i s/1/3/", path).ok());
  EXPECT_EQ(ReadAll(path), "{\"replicates\": 3}");

  Status failed = OpenInEditor("false", path);
  EXPECT_EQ(failed.code(), StatusCode::kUnavailable);
  EXPECT_THAT(failed.reason(), HasSubstr("the editor \"false\" exited with status 1"));
  Status missing = OpenInEditor("/no/such/editor", path);
  EXPECT_THAT(missing.reason(), HasSubstr("the editor \"/no/such/editor\" was not found (set EDITOR or VISUAL"));
}

// The loop with fakes: a refusal, a re-open on the user's text, a save; the file is gone after.
TEST_F(CampaignEditTest, RefusedThenFixedThenSaved) {
  std::vector<std::string> texts = {R"({"replicates": 0})", R"({"replicates": 2})"};
  std::vector<std::string> seen;
  std::vector<json> saved;
  std::string file;
  EditEdges edges;
  edges.open = [&](const std::string& path) {
    file = path;
    seen.push_back(ReadAll(path));
    std::ofstream(path, std::ios::trunc) << texts.at(seen.size() - 1);
    return Status::Ok();
  };
  int asked = 0;
  edges.ask = [&](const std::string&) { return ++asked > 0; };
  edges.save = [&](const json& definition) -> Result<json> {
    saved.push_back(definition);
    if (definition["replicates"] == 0) return Status::InvalidArgument("replicates", "must be >= 1");
    return json{{"version", 2}};
  };
  std::ostringstream err;
  auto outcome = EditUntilSaved("{}\n", dir_, "mine", edges, err);
  ASSERT_TRUE(outcome.ok()) << outcome.status().ToString();
  EXPECT_EQ(outcome->kind, EditOutcome::Kind::kSaved);
  EXPECT_EQ(outcome->reply["version"], 2);
  EXPECT_EQ(seen, (std::vector<std::string>{"{}\n", R"({"replicates": 0})"}));
  EXPECT_EQ(saved.size(), 2u);
  EXPECT_EQ(asked, 1);
  EXPECT_EQ(err.str(), "sandswim: replicates: must be >= 1\n");
  EXPECT_FALSE(fs::exists(file));
}

// No daemon is not fixed in the editor: no question, the text is kept; an editor that fails keeps
// it too and says where.
TEST_F(CampaignEditTest, NoDaemonOrABrokenEditorKeepsTheText) {
  EditEdges edges;
  edges.open = [](const std::string& path) {
    std::ofstream(path, std::ios::trunc) << R"({"replicates": 2})";
    return Status::Ok();
  };
  edges.ask = [](const std::string&) -> bool {
    ADD_FAILURE() << "asked";
    return true;
  };
  edges.save = [](const json&) -> Result<json> { return Status::Unavailable("no daemon at http://127.0.0.1:1"); };
  std::ostringstream err;
  auto outcome = EditUntilSaved("{}", dir_, "mine", edges, err);
  ASSERT_TRUE(outcome.ok());
  EXPECT_EQ(outcome->kind, EditOutcome::Kind::kKept);
  EXPECT_EQ(ReadAll(outcome->kept_path), R"({"replicates": 2})");
  EXPECT_EQ(outcome->refusal.code(), StatusCode::kUnavailable);

  edges.open = [](const std::string&) { return Status::Unavailable("the editor \"false\" exited with status 1"); };
  auto broken = EditUntilSaved("{\"a\": 1}", dir_, "mine", edges, err);
  ASSERT_FALSE(broken.ok());
  EXPECT_THAT(broken.status().reason(),
              HasSubstr("exited with status 1; your text is kept in " + dir_ + "/sandswim-mine-"));
}

}  // namespace
}  // namespace sandswim::cli
