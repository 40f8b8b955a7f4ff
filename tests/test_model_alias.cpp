// Model aliases (core/nn/model_alias.h): `-m best` and the like resolve to a model's variant and run it with the
// alias's settings, in core, the CLI and the cards; malformed alias files are refused naming the file.
#include <algorithm>
#include <cstdlib>
#include <fstream>

#include <OpenImageIO/imagebuf.h>
#include <gtest/gtest.h>

#include "core/nn/model_alias.h"
#include "core/nn/model_card.h"
#include "core/nn/model_registry.h"
#include "core/util/error.h"
#include "support/test_support.h"

namespace residue {
namespace {

using testing::TempDir;

// RESIDUE_MODEL_PATH pointed at a folder for one test, restored after.
class ModelPathFor {
 public:
  explicit ModelPathFor(const std::filesystem::path& dir) {
    if (const char* old = std::getenv("RESIDUE_MODEL_PATH")) old_ = old;
    setenv("RESIDUE_MODEL_PATH", dir.c_str(), 1);
  }
  ~ModelPathFor() { old_.empty() ? unsetenv("RESIDUE_MODEL_PATH") : setenv("RESIDUE_MODEL_PATH", old_.c_str(), 1); }

 private:
  std::string old_;
};

// A family "fam" with a full and a colour-only variant, and `aliases` as the folder's aliases.json.
void write_models(const TempDir& tmp, const std::string& aliases) {
  nn::write_safetensors(tmp / "fam.safetensors",
                        nn::to_safetensors(nn::random_network({1, 4, FeatureSet::Full}, 1),
                                           {{"name", "fam"}, {"validation", R"({"relmse": 0.75, "ssim": 0.5, "scenes": 3})"},
                                            {"benchmark", R"({"fp32_s_per_mp": 1.5, "machine": "m"})"}}),
                        false);
  nn::write_safetensors(tmp / "fam-color.safetensors",
                        nn::to_safetensors(nn::random_network({1, 4, FeatureSet::ColorOnly}, 2), {{"name", "fam-color"}}),
                        false);
  std::ofstream(tmp / "aliases.json") << aliases;
}

TEST(ModelAlias, ResolvesToTheModelsVariantWithTheAliasSettings) {
  TempDir tmp;
  write_models(tmp, R"({"top": {"model": "fam", "ensemble": 4, "description": "fam four times",
                                "validation": {"relmse": 0.5, "ssim": 0.25, "scenes": 3},
                                "benchmark": {"fp32_s_per_mp": 6.5, "machine": "m"}},
                        "twice": {"model": "fam", "ensemble": 2}, "same": {"model": "fam"},
                        "best": {"model": "fam", "ensemble": 2}})");
  ModelPathFor path(tmp.path());
  EXPECT_EQ(nn::find_model_for("top", FeatureSet::Full), tmp / "fam.safetensors");
  EXPECT_EQ(nn::find_model_for("top", FeatureSet::ColorOnly), tmp / "fam-color.safetensors")
      << "an alias picks its model's variant for the AOVs present, as the model's own name does";
  EXPECT_EQ(nn::load_model_for("top", FeatureSet::Full).ensemble, 4);
  EXPECT_EQ(nn::load_model_for("top", FeatureSet::ColorOnly).ensemble, 4);
  EXPECT_EQ(nn::load_model_for("fam", FeatureSet::Full).ensemble, 1) << "the model itself runs as its file says";
  EXPECT_FALSE(nn::find_model_alias("fam"));
  // $RESIDUE_MODEL_PATH comes before the shipped models: its "best" wins over resources/models/aliases.json's.
  EXPECT_EQ(nn::find_model_for("best", FeatureSet::Full), tmp / "fam.safetensors");
  EXPECT_EQ(nn::load_model_for("best", FeatureSet::Full).ensemble, 2);

  // The card: the model's cost times the alias's ensemble, the alias's own description and numbers.
  const auto cards = nn::list_model_cards();
  const auto card = [&](const std::string& family) {
    const auto it = std::find_if(cards.begin(), cards.end(), [&](const nn::ModelCard& c) { return c.family == family; });
    EXPECT_NE(it, cards.end()) << family;
    return it == cards.end() ? nn::ModelCard{} : *it;
  };
  const nn::ModelCard top = card("top"), fam = card("fam");
  EXPECT_EQ(top.alias_of, "fam");
  EXPECT_TRUE(fam.alias_of.empty());
  EXPECT_NEAR(top.gflop_per_mp, 4 * fam.gflop_per_mp, 1e-9 * fam.gflop_per_mp);
  EXPECT_GT(fam.gflop_per_mp, 0);
  EXPECT_EQ(top.description, "fam four times");
  ASSERT_TRUE(top.validation);
  EXPECT_EQ(top.validation->relmse, 0.5);
  EXPECT_EQ(top.validation->scenes, 3);
  EXPECT_EQ(top.seconds_per_mp(nn::Precision::FP32), 6.5);
  EXPECT_EQ(top.ensemble, 4);
  EXPECT_EQ(top.variants, fam.variants);
  EXPECT_NE(top.architecture.find("x4"), std::string::npos) << top.architecture;
  // The model's own numbers were measured x1: an alias running it otherwise shows none of them, one running it
  // as is shows them.
  const nn::ModelCard twice = card("twice"), same = card("same");
  EXPECT_FALSE(twice.validation);
  EXPECT_FALSE(twice.benchmark);
  ASSERT_TRUE(same.validation && fam.validation);
  EXPECT_EQ(same.validation->relmse, 0.75);
  EXPECT_EQ(same.seconds_per_mp(nn::Precision::FP32), 1.5);
}

// The registry (core/nn/model_registry.h): one resolution says which file runs and with which settings; a loaded
// model is read once per name and file and shared; a family with no variant for the AOVs present gets the cheapest
// family that has one, never an alias.
TEST(ModelRegistry, ResolvesLoadsOnceAndSubstitutes) {
  TempDir tmp;
  write_models(tmp, R"({"top": {"model": "fam", "ensemble": 4}})");
  nn::write_safetensors(tmp / "rich.safetensors",
                        nn::to_safetensors(nn::random_network({1, 4, FeatureSet::Full}, 3), {{"name", "rich"}}), false);
  ModelPathFor path(tmp.path());
  const nn::ModelChoice top = nn::resolve_model("top", FeatureSet::ColorOnly);
  EXPECT_EQ(top.file, tmp / "fam-color.safetensors");
  EXPECT_EQ(top.ensemble, 4);
  ASSERT_TRUE(top.alias);
  EXPECT_EQ(top.alias->model, "fam");
  const nn::ModelChoice fam = nn::resolve_model("fam", FeatureSet::Full);
  EXPECT_EQ(fam.file, tmp / "fam.safetensors");
  EXPECT_EQ(fam.ensemble, 0);
  EXPECT_FALSE(fam.alias);
  EXPECT_EQ(nn::resolve_model((tmp / "fam.safetensors").string(), FeatureSet::ColorOnly).file, tmp / "fam.safetensors")
      << "a path runs as named, whatever the AOVs";

  nn::ModelRegistry registry;
  const auto a = registry.load("top", FeatureSet::Full), b = registry.load("top", FeatureSet::Full);
  const auto c = registry.load("fam", FeatureSet::Full);
  EXPECT_EQ(a.get(), b.get()) << "loaded once";
  EXPECT_NE(a.get(), c.get()) << "an alias and its model share a file, not their settings";
  EXPECT_EQ(a->ensemble, 4);
  EXPECT_EQ(c->ensemble, 1);

  const std::vector<std::string> families = {"top", "rich", "fam", "bilateral"};  // in order of cost
  EXPECT_FALSE(nn::ModelRegistry::substitute("rich", FeatureSet::Full, families)) << "it fits as it is";
  EXPECT_EQ(nn::ModelRegistry::substitute("rich", FeatureSet::ColorOnly, families), std::optional<std::string>("fam"))
      << "rich has no colour-only variant: the cheapest family that has one, skipping the alias top";
  EXPECT_FALSE(nn::ModelRegistry::substitute("unknown", FeatureSet::ColorOnly, families));
  EXPECT_THROW(nn::resolve_model("rich", FeatureSet::ColorOnly), Error);
}

TEST(ModelAlias, MalformedAliasesAreRefusedNamingTheFile) {
  struct Case {
    std::string json, expect;
  };
  for (const Case& c : {Case{R"({"top": {"model": "fam", "ensemble": 3}})", "\"ensemble\" must be 1, 2, 4 or 8"},
                        Case{R"({"top": {"ensemble": 2}})", "needs \"model\""},
                        Case{R"({"top": {"model": "mid"}, "mid": {"model": "fam"}})", "itself an alias"},
                        Case{R"(["top"])", "not a JSON object"}, Case{"{not json", "not a JSON object"}}) {
    TempDir tmp;
    write_models(tmp, c.json);
    ModelPathFor path(tmp.path());
    const std::string e = testing::error_message([] { nn::find_model_for("top", FeatureSet::Full); }, ErrorKind::Input);
    EXPECT_NE(e.find((tmp / "aliases.json").string()), std::string::npos) << c.json << ": " << e;
    EXPECT_NE(e.find(c.expect), std::string::npos) << c.json << ": " << e;
    // A broken aliases.json costs the listing only its own cards, with a note.
    std::vector<std::string> problems;
    const auto cards = nn::list_model_cards(&problems);
    EXPECT_TRUE(std::any_of(cards.begin(), cards.end(), [](const nn::ModelCard& m) { return m.family == "fam"; }));
    EXPECT_FALSE(std::any_of(cards.begin(), cards.end(), [](const nn::ModelCard& m) { return m.family == "top"; }));
    EXPECT_FALSE(problems.empty()) << c.json;
  }
}

// The shipped alias: `best` is multiscale as a self-ensemble x8, what docs/MODELS.md measured most accurate.
TEST(ModelAlias, ShippedBestIsAnEnsemble) {
  const auto alias = nn::find_model_alias("best");
  ASSERT_TRUE(alias);
  EXPECT_EQ(nn::find_model_for("best", FeatureSet::Full), nn::find_model_for(alias->model, FeatureSet::Full));
  EXPECT_EQ(nn::load_model_for("best", FeatureSet::Full).ensemble, alias->ensemble);
  EXPECT_GT(alias->ensemble, 1);
}

// End to end: `-m top` writes the very pixels of `-m fam --ensemble 4`, and the header says x4.
TEST(ModelAlias, CliDenoiseWithAnAliasRunsItsModelAsTheAliasSays) {
  TempDir tmp;
  write_models(tmp, R"({"top": {"model": "fam", "ensemble": 4}})");
  ModelPathFor path(tmp.path());
  const std::string room = (std::filesystem::path(RESIDUE_SOURCE_RESOURCES) / "examples/room/noisy.exr").string();
  std::string text;
  ASSERT_EQ(testing::run_cli({"denoise", room, "-o", (tmp / "alias.exr").string(), "-m", "top", "--backend", "eigen"}, &text), 0)
      << text;
  ASSERT_EQ(testing::run_cli({"denoise", room, "-o", (tmp / "x4.exr").string(), "-m", "fam", "--ensemble", "4",
                              "--backend", "eigen"}, &text), 0)
      << text;
  ASSERT_EQ(testing::run_cli({"denoise", room, "-o", (tmp / "x1.exr").string(), "-m", "fam", "--backend", "eigen"}, &text), 0)
      << text;
  const Image alias = testing::read_exr_float(tmp / "alias.exr"), x4 = testing::read_exr_float(tmp / "x4.exr"),
              x1 = testing::read_exr_float(tmp / "x1.exr");
  const auto pixels = [](const Image& im) {
    return std::vector<float>(im.data(), im.data() + im.pixel_count() * im.channels());
  };
  ASSERT_GT(alias.pixel_count(), 0);
  EXPECT_EQ(pixels(alias), pixels(x4));
  EXPECT_NE(pixels(alias), pixels(x1)) << "the ensemble changes the pixels, so the comparison above can fail";
  OIIO::ImageBuf img((tmp / "alias.exr").string());
  ASSERT_TRUE(img.read());
  EXPECT_EQ(img.spec().get_int_attribute("residue:ensemble", -1), 4);
}

}  // namespace
}  // namespace residue
