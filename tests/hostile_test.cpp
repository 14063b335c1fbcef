// Hostile input, failing disks and interrupted work, end to end (issue:
// "Hostile input, full disks and interrupted studies"): each test names the
// item of the issue it covers. Every failure must name the file (and line
// or key), exit non-zero, and leave nothing behind.
#include "cli_support.h"

#include "hand_made_tiff.h"
#include "xgauge/image/tiff.h"

#include <nlohmann/json.hpp>

#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <tiffio.h>
#include <unistd.h>

#include <chrono>
#include <sstream>
#include <thread>
#include <vector>


namespace xgauge {
namespace {

// A tiny virtual lab: a cuboid on a 160 x 128 detector, three shots 10 mm
// apart; simulated in about a second, measured in about two.
const char* kTinyMachine = R"({"source_detector_distance_mm": 1000,
  "detector": {"columns": 160, "rows": 128, "pixel_pitch_mm": [0.8, 0.8]}})";

std::string tinyRecipe(const std::string& base_translation = "[-15, 0, 500]", int count = 3,
                       double distance_mm = 10.0) {
  return R"({"seed": 7, "machine": "machine.json",
    "beam": {"tube_kv": 150.0, "filters": [],
             "detector_window": {"compound": "Al", "density_g_cm3": 2.699, "thickness_mm": 0.5},
             "scintillator": {"compound": "CsI", "density_g_cm3": 4.51, "thickness_mm": 0.6}},
    "material": {"compound": "Al", "density_g_cm3": 2.699},
    "detector": {"area_samples": 2, "noise": {"photons_per_open_pixel": 20000}},
    "part": {"model": ")" +
         kRoot + R"(/parts/cuboid.json", "dimensions": {"size_x": 20.3, "size_y": 30.2, "size_z": 9.8}},
    "shots": {"base_pose": {"rotation_deg": [10, 20, 5], "translation_mm": )" +
         base_translation + R"(},
              "translations": {"count": )" +
         std::to_string(count) + R"(, "distance_mm": )" + fmt::format("{}", distance_mm) +
         R"(, "axis": [1, 0, 0]}}})";
}

std::string tinySettings(const std::string& loss = "l2") {
  return R"({"material": "fit",
    "dimensions": {"start": {"size_x": 20, "size_y": 30, "size_z": 10}},
    "pose_bounds": {"rotation_deg": [[0, 20], [10, 30], [-5, 15]],
                    "centre_mm": [[-30, 30], [-20, 20], [480, 520]]},
    "loss": ")" +
         loss + R"("})";
}

std::string readText(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

// Starts xgauge without waiting; its output goes to `log`.
pid_t spawnXgauge(const std::vector<std::string>& arguments, const fs::path& log) {
  std::vector<std::string> argv_strings = {XGAUGE_EXECUTABLE};
  argv_strings.insert(argv_strings.end(), arguments.begin(), arguments.end());
  std::vector<char*> argv;
  for (auto& a : argv_strings) argv.push_back(a.data());
  argv.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_adddup2(&actions, 1, 2);
  pid_t pid = 0;
  EXPECT_EQ(posix_spawn(&pid, argv[0], &actions, nullptr, argv.data(), environ), 0);
  posix_spawn_file_actions_destroy(&actions);
  return pid;
}

// Every file under `folder` whose name marks it as temporary.
std::vector<std::string> temporaries(const fs::path& folder) {
  std::vector<std::string> found;
  if (!fs::exists(folder)) return found;
  for (const auto& entry : fs::recursive_directory_iterator(folder))
    if (entry.path().extension() == ".tmp" ||
        entry.path().filename().string().find(".xgauge-probe") != std::string::npos)
      found.push_back(entry.path().string());
  return found;
}

class Hostile : public Cli {
 protected:
  // Simulates the tiny lab into dir/ds; `lag`: the fraction of each exposure
  // the next one records.
  void simulateTinyLab(double lag = 0.0) {
    write("machine.json", kTinyMachine);
    std::string recipe = tinyRecipe();
    if (lag > 0.0) {
      const std::string noise = R"("photons_per_open_pixel": 20000)";
      recipe.replace(recipe.find(noise), noise.size(),
                     noise + fmt::format(R"(, "ghost_fraction": {})", lag));
    }
    const CommandResult r =
        run("simulate " + write("recipe.json", recipe) + " -o " + out("ds") + " -q");
    ASSERT_EQ(r.status, 0) << r.output;
  }
  // A measurement job over t00 and t01 of the tiny lab; `dimensions` and
  // `centre` replace the defaults.
  std::string tinyJob(const std::string& dimensions = R"({"start": {"size_x": 20, "size_y": 30, "size_z": 10}})",
                      const std::string& centre = "[[-30, 30], [-20, 20], [480, 520]]",
                      const std::string& extra = "") {
    write("material.json", R"({"model": "monochromatic", "compound": "Al",
                               "density_g_cm3": 2.699, "energy_kev": 60})");
    return write("job.json", R"({"part": ")" + kRoot + R"(/parts/cuboid.json",
      "machine": "machine.json", "material": "material.json",
      "dimensions": )" + dimensions + R"(,
      "radiographs": [
        {"name": "t00", "image": "ds/t00.tif", "dark": "ds/dark.tif", "flat": "ds/flat.tif",
         "white_region": [3, 3, 16, 16], "pattern": "free"},
        {"name": "t01", "image": "ds/t01.tif", "dark": "ds/dark.tif", "flat": "ds/flat.tif",
         "white_region": [3, 3, 16, 16], "pattern": "translated", "reference": "t00",
         "distance_mm": 10}],
      "pose_bounds": {"rotation_deg": [[0, 20], [10, 30], [-5, 15]], "centre_mm": )" +
                                     centre + "}" + extra + "}");
  }
  void expectFailure(const CommandResult& r, const std::vector<std::string>& parts) {
    EXPECT_NE(r.status, 0) << r.output;
    for (const auto& part : parts)
      EXPECT_NE(r.output.find(part), std::string::npos) << "expected '" << part << "' in:\n"
                                                        << r.output;
    EXPECT_EQ(r.output.find("internal error"), std::string::npos) << r.output;
    EXPECT_TRUE(temporaries(dir_).empty()) << temporaries(dir_).front();
  }
};

// Item 1: a job nested 100,000 levels deep used to crash measure (SIGSEGV).
TEST_F(Hostile, DeeplyNestedJobIsRefusedWithItsLine) {
  const std::string job = write(
      "job.json", "{\n\"dimensions\": {\"start\": {\"width\":\n" + std::string(100000, '[') +
                      std::string(100000, ']') + "}}}\n");
  const CommandResult r = run("measure " + job + " -o " + out("out"));
  expectFailure(r, {job + ":3:", "nested more than 128 levels"});
  EXPECT_LT(r.output.size(), 400u);
  EXPECT_FALSE(fs::exists(out("out")));
}

// Item 2: 1e400 used to give the JSON library's message, with no file or line.
TEST_F(Hostile, NumberOverflowIsRefusedWithItsLine) {
  const std::string machine = write("machine.json", R"({"source_detector_distance_mm": 1000,
  "detector": {"columns": 1e400, "rows": 96, "pixel_pitch_mm": [0.5, 0.5]}})");
  const CommandResult r = run(renderArgs(kRoot + "/parts/cuboid.json", machine, "-q"));
  expectFailure(r, {machine + ":2:", "number overflow"});
  EXPECT_EQ(r.output.find("json.exception"), std::string::npos) << r.output;
}

// Item 3: tiny files declaring huge images used to take 2 GB, 8 GiB or a 35 GB
// tile buffer. Now: refused before allocating, in little memory.
TEST_F(Hostile, HostileTiffsAreRefusedInLittleMemory) {
  testing::writeDeclaredStripTiff(out("huge16.tif"), 32768, 32768, 16, 1, 1, 100, 198);
  testing::writeDeclaredStripTiff(out("huge64.tif"), 32768, 32768, 64, 3, 1, 100, 198);
  testing::writeDeclaredTileTiff(out("tile.tif"), 1090519056, 300);
  for (const char* name : {"huge16.tif", "huge64.tif"})
    expectFailure(run("normalize " + out(name) + " --white 0 0 4 4 -o " + out("n.tif")),
                  {out(name) + ": the file declares 32768x32768 pixels"});
  expectFailure(run("normalize " + out("tile.tif") + " --white 0 0 4 4 -o " + out("n.tif")),
                {out("tile.tif") + ": the file declares tiles of 17448304896 bytes"});
  // The limit is the user's to set.
  writeTiff(out("fine.tif"), Image(600, 600, 100.0f), TiffFormat::kFloat32);
  expectFailure(run("--max-image-mb 1 normalize " + out("fine.tif") + " --white 0 0 4 4 -o " + out("n.tif")),
                {out("fine.tif") + ": the file declares 600x600 pixels, 1.4 MiB as floats: more than the "
                                   "limit of 1.0 MiB"});
  EXPECT_EQ(run("normalize " + out("fine.tif") + " --white 0 0 4 4 -o " + out("n.tif") + " -q").status, 0);
  fs::remove(out("n.tif"));
  rusage usage{};
  ASSERT_EQ(getrusage(RUSAGE_CHILDREN, &usage), 0);
  EXPECT_LT(usage.ru_maxrss, 100 * 1024) << "peak resident memory of a child, KiB";
  EXPECT_FALSE(fs::exists(out("n.tif")));
}

// Item 4: a preview that cannot be written used to leave the TIFF behind.
TEST_F(Hostile, NormalizeLeavesNothingWhenThePreviewCannotBeWritten) {
  writeTiff(out("raw.tif"), Image(16, 16, 1000.0f), TiffFormat::kFloat32);
  fs::create_directories(out("folder.png"));
  expectFailure(run("normalize " + out("raw.tif") + " --white 0 0 4 4 -o " + out("n.tif") +
                    " --png " + out("missing/n.png")),
                {out("missing/n.png"), "does not exist"});
  expectFailure(run("normalize " + out("raw.tif") + " --white 0 0 4 4 -o " + out("n.tif") +
                    " --png " + out("folder.png")),
                {out("folder.png"), "is a folder"});
  EXPECT_FALSE(fs::exists(out("n.tif")));
}

// Item 4: measure used to run the whole fit before failing on its output place.
TEST_F(Hostile, MeasureChecksItsOutputBeforeTheFit) {
  simulateTinyLab();
  const std::string job = tinyJob();
  write("a_file", "x");
  const CommandResult onto_file = run("measure " + job + " -o " + out("a_file"));
  expectFailure(onto_file, {out("a_file"), "exists and is not a folder"});
  EXPECT_EQ(onto_file.output.find("size_x"), std::string::npos) << "the fit ran:\n" << onto_file.output;
  expectFailure(run("measure " + job + " -o /proc/xgauge_out"),
                {"/proc/xgauge_out", "cannot write in the folder /proc"});
}

// Items 4 and 8: pose bounds behind the source used to leave an empty folder
// and blame "part vertex 0"; now the job's key is named and nothing is made.
TEST_F(Hostile, PoseBoundsBehindTheSourceAreNamedAndLeaveNoFolder) {
  simulateTinyLab();
  const std::string job =
      tinyJob(R"({"start": {"size_x": 20, "size_y": 30, "size_z": 10}})",
              "[[-30, 30], [-20, 20], [1100, 1200]]");
  expectFailure(run("measure " + job + " -o " + out("out/deeper")),
                {job + ": /pose_bounds/centre_mm: centre z in [1100, 1200] mm"});
  EXPECT_FALSE(fs::exists(out("out")));
  // Bounds that keep the part 5 m to the side: no pose shows it.
  expectFailure(run("measure " + tinyJob(R"({"start": {"size_x": 20, "size_y": 30, "size_z": 10}})",
                                         "[[4990, 5010], [-20, 20], [480, 520]]") +
                    " -o " + out("out")),
                {"/pose_bounds/centre_mm: no centre within these bounds puts the part in view"});
}

// A material.json from a wedge calibration carries the detector's scatter;
// a study whose settings give none measures every run with it (each run's
// job.json names the study's material.json, which carries it, so the job
// measured by hand takes it too) and records it.
TEST_F(Hostile, StudyRunsTakeTheScatterTheirMaterialCarries) {
  simulateTinyLab();
  write("material.json", R"({"model": "exponential_sum", "terms": [{"weight": 1, "mu_per_mm": 0.05}],
    "scatter": {"weight": 0.07, "sigma_mm": 12.5}})");
  std::string settings = tinySettings();
  settings.replace(settings.find(R"("fit")"), 5, R"("material.json")");
  // This material (one exponential, not the lab's curve) leaves 20 times the
  // noise: no measurement by the failure rule, which this test is not about.
  settings.insert(1, R"("acceptance": {"max_misfit_ratio": 1000, "max_region_share": 1, )"
                     R"("fail_at_bound": false}, )");
  const CommandResult r = run("study " + out("ds") + " -o " + out("study") + " -q --limit 1 -s " +
                              write("settings.json", settings));
  ASSERT_EQ(r.status, 0) << r.output;
  const std::string job = readText(out("study/runs/t00-t01/job.json"));
  EXPECT_EQ(job.find("scatter"), std::string::npos) << job;
  EXPECT_NE(readText(out("study/material.json")).find("\"weight\": 0.07"), std::string::npos);
  const std::string result = readText(out("study/runs/t00-t01/result.json"));
  EXPECT_NE(result.find("w = 0.07 +- 0.0035"), std::string::npos) << result;
  // The same job measured by hand gives the same dimensions.
  const CommandResult again = run("measure " + out("study/runs/t00-t01/job.json") + " -q -o " + out("again"));
  ASSERT_EQ(again.status, 0) << again.output;
  const auto a = nlohmann::json::parse(result), b = nlohmann::json::parse(readText(out("again/result.json")));
  for (size_t k = 0; k < a["dimensions"].size(); ++k)
    EXPECT_NEAR(a["dimensions"][k]["value_mm"].get<double>(), b["dimensions"][k]["value_mm"].get<double>(), 1e-9);
}

// With "previous_frames", each shot but the first names the one exposed
// before it, and its lag (1 % in this lab) is estimated and subtracted.
TEST_F(Hostile, AStudyWithPreviousFramesSubtractsEachShotsLag) {
  simulateTinyLab(0.01);
  std::string settings = tinySettings();
  settings.insert(1, R"("previous_frames": true, )");
  const CommandResult r = run("study " + out("ds") + " -o " + out("study") + " -q --limit 1 -s " +
                              write("settings.json", settings));
  ASSERT_EQ(r.status, 0) << r.output;
  const auto job = nlohmann::json::parse(readText(out("study/runs/t00-t01/job.json")));
  EXPECT_FALSE(job["radiographs"][0].contains("previous"));
  EXPECT_EQ(fs::path(job["radiographs"][1]["previous"].get<std::string>()).filename(), "t00.tif");
  const auto result = nlohmann::json::parse(readText(out("study/runs/t00-t01/result.json")));
  const auto& lag = result["radiographs"][1]["lag"];
  EXPECT_EQ(lag["source"], "estimated");
  EXPECT_NEAR(lag["fraction"].get<double>(), 0.01, 3.0 * lag["uncertainty"].get<double>()) << lag;
  EXPECT_FALSE(result["radiographs"][0].contains("lag"));
}

// A study's "lag_fraction" is the lab's known lag: written into the study's
// machine, subtracted as stated (no estimate), refused out of range or
// without previous frames to subtract it from.
TEST_F(Hostile, AStudysStatedLagIsSubtractedAsStated) {
  simulateTinyLab(0.01);
  const std::string study = "study " + out("ds") + " -o " + out("study") + " -q --limit 1 -s ";
  std::string settings = tinySettings();
  settings.insert(1, R"("previous_frames": true, "lag_fraction": 0.0125, )");
  const CommandResult r = run(study + write("settings.json", settings));
  ASSERT_EQ(r.status, 0) << r.output;
  const auto machine = nlohmann::json::parse(readText(out("study/machine.json")));
  EXPECT_DOUBLE_EQ(machine["detector"]["lag_fraction"].get<double>(), 0.0125);
  const auto result = nlohmann::json::parse(readText(out("study/runs/t00-t01/result.json")));
  const auto& lag = result["radiographs"][1]["lag"];
  EXPECT_EQ(lag["source"], "machine") << lag;
  EXPECT_DOUBLE_EQ(lag["fraction"].get<double>(), 0.0125);
  // With the machine's default uncertainty, a tenth of the fraction.
  EXPECT_DOUBLE_EQ(lag["uncertainty"].get<double>(), 0.00125);

  // Settings with `keys` added are refused with `message`.
  const auto refused = [&](const std::string& file, const std::string& keys,
                           const std::string& message) {
    std::string text = tinySettings();
    text.insert(1, keys);
    const CommandResult answer = run(study + write(file, text));
    EXPECT_NE(answer.status, 0) << file;
    EXPECT_NE(answer.output.find(message), std::string::npos) << answer.output;
  };
  refused("high.json", R"("previous_frames": true, "lag_fraction": 0.7, )",
          "high.json: /lag_fraction: expected a number from 0 to 0.5");
  refused("alone.json", R"("lag_fraction": 0.01, )",
          "only subtracted with \"previous_frames\": true");
  // An uncertainty without the fraction it belongs to, and one out of range.
  refused("orphan.json", R"("previous_frames": true, "lag_fraction_uncertainty": 0.001, )",
          "orphan.json: /lag_fraction_uncertainty: needs a \"lag_fraction\"");
  refused("wide.json",
          R"("previous_frames": true, "lag_fraction": 0.01, "lag_fraction_uncertainty": -1, )",
          "wide.json: /lag_fraction_uncertainty: expected a number from 0 to 0.5");
}

// Item 5: a study run again with other settings used to return the old
// numbers; a damaged run file stopped a resume with the library's message.
TEST_F(Hostile, StudyNeverReusesResultsOfOtherSettings) {
  simulateTinyLab();
  const std::string study = "study " + out("ds") + " -o " + out("study") + " -q -s ";
  const CommandResult l2 = run(study + write("l2.json", tinySettings("l2")));
  ASSERT_EQ(l2.status, 0) << l2.output;
  const std::string l2_csv = readText(out("study/study.csv"));
  const CommandResult l1 = run(study + write("l1.json", tinySettings("l1")));
  ASSERT_EQ(l1.status, 0) << l1.output;
  EXPECT_NE(l1.output.find("measured with other settings or inputs; measuring again"),
            std::string::npos)
      << l1.output;
  const std::string run_job = readText(out("study/runs/t00-t01/job.json"));
  EXPECT_NE(run_job.find("\"l1\""), std::string::npos) << run_job;
  // Back to l2: the same numbers as the first time (seconds aside).
  ASSERT_EQ(run(study + out("l2.json")).status, 0);
  const auto errors = [](const std::string& csv) {
    std::string kept;
    std::istringstream lines(csv);
    for (std::string line; std::getline(lines, line);) {
      const auto first = line.find(','), second = line.find(',', first + 1);
      kept += line.substr(0, first) + line.substr(second) + "\n";
    }
    return kept;
  };
  EXPECT_EQ(errors(readText(out("study/study.csv"))), errors(l2_csv));
  // A damaged run file is named and measured again.
  write("study/runs/t00-t02/result.json", "{\"dimensions\": [");
  const CommandResult damaged = run(study + out("l2.json"));
  ASSERT_EQ(damaged.status, 0) << damaged.output;
  EXPECT_NE(damaged.output.find(out("study/runs/t00-t02/result.json") + ":1:"),
            std::string::npos)
      << damaged.output;
  EXPECT_EQ(errors(readText(out("study/study.csv"))), errors(l2_csv));
}

// Item 5 and 10: a study killed mid-run (SIGKILL: no cleanup at all) and
// resumed gives the same table as one run straight through.
TEST_F(Hostile, KilledStudyResumesToTheSameTable) {
  simulateTinyLab();
  const std::string settings = write("settings.json", tinySettings());
  ASSERT_EQ(run("study " + out("ds") + " -s " + settings + " -o " + out("whole") + " -q -j 1").status, 0);
  const pid_t pid = spawnXgauge({"study", out("ds"), "-s", settings, "-o", out("cut"), "-q", "-j", "1"},
                                out("cut.log"));
  // Wait for the first run to finish, then kill during the next.
  for (int i = 0; i < 600 && !fs::exists(out("cut/runs/t00-t01/fingerprint.sha256")); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  ::kill(pid, SIGKILL);
  int status = 0;
  ::waitpid(pid, &status, 0);
  ASSERT_TRUE(WIFSIGNALED(status)) << "the study finished before it was killed";
  EXPECT_FALSE(fs::exists(out("cut/study.csv")));
  const CommandResult resumed = run("study " + out("ds") + " -s " + settings + " -o " + out("cut") + " -q -j 1");
  ASSERT_EQ(resumed.status, 0) << resumed.output;
  const std::string whole = readText(out("whole/study.json")), cut = readText(out("cut/study.json"));
  const auto errors_of = [](const std::string& json) { return json.substr(json.find("\"dimensions\"")); };
  // The per-dimension statistics come before the runs' seconds.
  const auto statistics = [&](const std::string& json) {
    const std::string s = errors_of(json);
    return s.substr(0, s.find("\"median_seconds\""));
  };
  EXPECT_EQ(statistics(cut), statistics(whole));
  EXPECT_TRUE(temporaries(out("cut")).empty());
}

// Item 6: a material that does not attenuate used to return the start values.
TEST_F(Hostile, MaterialThatDoesNotAttenuateIsRefused) {
  simulateTinyLab();
  const std::string job = tinyJob();
  write("material.json", R"({"model": "exponential_sum",
    "terms": [{"weight": 0.5, "mu_per_mm": 0}, {"weight": 0.5, "mu_per_mm": 0}]})");
  expectFailure(run("measure " + job + " -o " + out("out")),
                {out("material.json") + ":2: /terms: every mu_per_mm is 0"});
  EXPECT_FALSE(fs::exists(out("out")));
}

// Item 6: a part turning inside out at in-bounds values used to render as
// an all-1.0 image.
TEST_F(Hostile, PartTurnedInsideOutIsRefusedWithTheValues) {
  const std::string part = kRoot + "/tests/data/box_turning_inside_out.json";
  const std::string machine = write("machine.json", kTinyMachine);
  const CommandResult r = run(renderArgs(part, machine, "--set s=4 -q"));
  expectFailure(r, {"the surface turns inside out", "at s=4 mm"});
  EXPECT_FALSE(fs::exists(out("out.tif")));
  EXPECT_EQ(run(renderArgs(part, machine, "--set s=7 -q")).status, 0);
}

// Item 6: a part 5 m out of the beam used to simulate and render silently.
TEST_F(Hostile, PartOutOfTheBeamIsRefused) {
  write("machine.json", kTinyMachine);
  expectFailure(run("simulate " + write("recipe.json", tinyRecipe("[5000, 0, 500]")) + " -o " +
                    out("ds") + " -q"),
                {out("recipe.json") + ": shot t00: the part's shadow", "misses the 160x128 detector"});
  EXPECT_FALSE(fs::exists(out("ds")));
  const std::string machine = out("machine.json");
  const CommandResult r =
      run("render " + kRoot + "/parts/cuboid.json --machine " + machine + " --material " + kRoot +
          "/examples/aluminium_60kev.json --rotation-deg 0 0 0 --translation-mm 5000 0 400 -o " +
          out("out.tif"));
  expectFailure(r, {"misses the 160x128 detector"});
  EXPECT_FALSE(fs::exists(out("out.tif")));
}

// Item 7: duplicate keys, a fractional seed, bounds beyond the model's, a
// start for a fixed dimension and a multi-page TIFF used to pass silently.
TEST_F(Hostile, SilentlyAcceptedInputIsRefused) {
  simulateTinyLab();
  const std::string start = R"("start": {"size_x": 20, "size_y": 30, "size_z": 10})";
  expectFailure(run("measure " + tinyJob("{" + start + ",\n" + start + "}") + " -o " + out("o")),
                {out("job.json") + ":4:", "key 'start' appears twice in the object at /dimensions"});
  expectFailure(run("measure " + tinyJob("{" + start + "}", "[[-30, 30], [-20, 20], [480, 520]]",
                                         R"(, "seed": 2.5)") +
                    " -o " + out("o")),
                {out("job.json") + ":10: /seed: expected a whole number, got 2.5"});
  expectFailure(run("measure " + tinyJob(R"({"bounds": {"size_x": [5, 25]}})") + " -o " + out("o")),
                {"/dimensions/bounds/size_x: bounds [5, 25] reach beyond the part model's [10, 30] mm"});
  expectFailure(
      run("measure " + tinyJob(R"({"fixed": {"size_x": 20}, "start": {"size_x": 21}})") + " -o " +
          out("o")),
      {"/dimensions/start/size_x: 'size_x' is fixed; a start value does not apply to it"});
  // Two pages of different sizes (pages of one size are averaged).
  TIFF* tif = TIFFOpen(out("pages.tif").c_str(), "w");
  ASSERT_NE(tif, nullptr);
  std::vector<float> row(16, 100.0f);
  for (int page = 0; page < 2; ++page) {
    TIFFSetField(tif, TIFFTAG_IMAGEWIDTH, page == 0 ? 16 : 8);
    TIFFSetField(tif, TIFFTAG_IMAGELENGTH, 1);
    TIFFSetField(tif, TIFFTAG_BITSPERSAMPLE, 32);
    TIFFSetField(tif, TIFFTAG_SAMPLEFORMAT, SAMPLEFORMAT_IEEEFP);
    TIFFSetField(tif, TIFFTAG_SAMPLESPERPIXEL, 1);
    TIFFSetField(tif, TIFFTAG_PHOTOMETRIC, PHOTOMETRIC_MINISBLACK);
    ASSERT_EQ(TIFFWriteScanline(tif, row.data(), 0, 0), 1);
    ASSERT_EQ(TIFFWriteDirectory(tif), 1);
  }
  TIFFClose(tif);
  expectFailure(run("normalize " + out("pages.tif") + " --white 0 0 4 1 -o " + out("n.tif")),
                {out("pages.tif") + ": page 2 is 8x1 pixels of 32-bit float but page 1 is 16x1"});
}

// Issue 48, readers: every format converts and normalizes through the CLI,
// and hostile files of each are refused naming the file, in little memory.
TEST_F(Hostile, RadiographFilesOfEveryFormat) {
  Image image(64, 48);
  for (int y = 0; y < 48; ++y)
    for (int x = 0; x < 64; ++x) image(x, y) = static_cast<float>(1000 + 7 * x + 13 * y);
  writeTiff(out("shot.tif"), image, TiffFormat::kUInt16);
  for (const char* name : {"shot.raw", "shot.nxs", "shot.dcm"}) {
    ASSERT_EQ(run(std::string("convert ") + out("shot.tif") + " " + out(name) + " -q").status, 0)
        << name;
    // Back to TIFF: the same pixels.
    ASSERT_EQ(run(std::string("convert ") + out(name) + " " + out(name) + ".tif -q").status, 0);
    const Image back = readTiff(out(name) + ".tif");
    EXPECT_TRUE(std::equal(back.pixels().begin(), back.pixels().end(), image.pixels().begin()))
        << name;
    EXPECT_EQ(
        run(std::string("normalize ") + out(name) + " --white 0 0 8 8 -o " + out("n.tif") + " -q")
            .status,
        0)
        << name;
  }
  EXPECT_EQ(run("convert " + out("shot.nxs") + "#projection=0 " + out("p.dcm") + " -q").status, 0);
  expectFailure(run("convert " + out("shot.nxs") + "#dark " + out("d.tif")),
                {out("shot.nxs") + "#dark: #dark: the file holds 1 projection(s), 0 flat(s) and 0 "
                                   "dark(s)"});
  expectFailure(run("convert " + out("shot.tif") + " " + out("x.png")),
                {out("x.png") + ": cannot tell the format from the extension '.png'"});
  // A sidecar that does not describe its file, and a misspelled key.
  write("shot.raw.json",
        R"({"width": 64, "height": 49, "type": "uint16", "byte_order": "little"})");
  expectFailure(run("normalize " + out("shot.raw") + " --white 0 0 4 4 -o " + out("n.tif")),
                {out("shot.raw") + ": is 6144 bytes long but its sidecar shot.raw.json declares "
                                   "6272 bytes"});
  write("shot.raw.json",
        R"({"width": 64, "height": 48, "type": "uint16", "byte_order": "little", "ofset": 0})");
  expectFailure(run("normalize " + out("shot.raw") + " --white 0 0 4 4 -o " + out("n.tif")),
                {"shot.raw.json", "unknown key 'ofset'; did you mean 'offset'?"});
  // The memory limit applies to every reader.
  writeTiff(out("big.tif"), Image(600, 600, 100.0f), TiffFormat::kUInt16);
  for (const char* name : {"big.raw", "big.nxs", "big.dcm"}) {
    ASSERT_EQ(run(std::string("convert ") + out("big.tif") + " " + out(name) + " -q").status, 0);
    expectFailure(run(std::string("--max-image-mb 1 convert ") + out(name) + " " + out("b.tif")),
                  {out(name) + ": ", "more than the limit of 1.0 MiB (--max-image-mb)"});
  }
  // Truncated NXtomo and DICONDE files: clear errors, no crash, no output.
  const std::string nxs = readText(out("shot.nxs")), dcm = readText(out("shot.dcm"));
  write("cut.nxs", nxs.substr(0, nxs.size() / 2));
  write("cut.dcm", dcm.substr(0, dcm.size() / 2));
  for (const char* name : {"cut.nxs", "cut.dcm"}) {
    const CommandResult r = run(std::string("convert ") + out(name) + " " + out("cut.tif"));
    expectFailure(r, {out(name) + ": "});
    EXPECT_FALSE(fs::exists(out("cut.tif")));
  }
}

// Item 8: messages that named no file or key.
TEST_F(Hostile, MessagesNameTheFileAndKey) {
  simulateTinyLab();
  // A start outside the model's bounds, with no job bounds.
  expectFailure(run("measure " + tinyJob(R"({"start": {"size_x": 35}})") + " -o " + out("o")),
                {out("job.json") + ":3: /dimensions/start/size_x: start 35 lies outside the bounds [10, 30]"});
  // A constraint broken by the start values is the job's doing.
  const std::string part = readText(kRoot + "/parts/cuboid.json");
  const auto at = part.find("\"shape\"");
  write("constrained.json", part.substr(0, at) +
                                R"("constraints": [{"expr": "size_y - size_x", "message": "y must exceed x"}], )" +
                                part.substr(at));
  std::string job = readText(tinyJob(R"({"start": {"size_x": 25, "size_y": 20}})"));
  job.replace(job.find(kRoot + "/parts/cuboid.json"), (kRoot + "/parts/cuboid.json").size(),
              out("constrained.json"));
  write("job.json", job);
  expectFailure(run("measure " + out("job.json") + " -o " + out("o")),
                {out("job.json") + ":3: /dimensions: the start values", "y must exceed x"});
  // The white region of a radiograph in darkness.
  writeTiff(out("dark.tif"), Image(16, 16, 0.0f), TiffFormat::kFloat32);
  expectFailure(run("normalize " + out("dark.tif") + " --white 0 0 4 4 -o " + out("n.tif")),
                {out("dark.tif") + ": the white region"});
  // An unknown compound in a recipe.
  std::string recipe = tinyRecipe();
  recipe.replace(recipe.find(R"("compound": "Al", "density_g_cm3": 2.699})"), 16, R"("compound": "Qq")");
  expectFailure(run("simulate " + write("bad_recipe.json", recipe) + " -o " + out("ds2") + " -q"),
                {out("bad_recipe.json") + ":5: /material/compound"});
  EXPECT_FALSE(fs::exists(out("ds2")));
}

// Item 10: an interrupted simulate or measure leaves no temporary file and
// no half-made output folder.
TEST_F(Hostile, InterruptedCommandsLeaveNothingBehind) {
  write("machine.json", kTinyMachine);
  const std::string recipe = write("many.json", tinyRecipe("[-15, 0, 500]", 400, 0.01));
  // 400 shots on one thread: seconds of work, interrupted after its first files.
  const pid_t pid =
      spawnXgauge({"simulate", recipe, "-o", out("many"), "-q", "-j", "1"}, out("sim.log"));
  for (int i = 0; i < 1000 && !fs::exists(out("many")); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  ::kill(pid, SIGINT);
  int status = 0;
  ::waitpid(pid, &status, 0);
  ASSERT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGINT)
      << "simulate ended before the interrupt: " << readText(out("sim.log"));
  EXPECT_FALSE(fs::exists(out("many"))) << readText(out("sim.log"));
  EXPECT_EQ(temporaries(dir_), std::vector<std::string>{});

  simulateTinyLab();
  const pid_t measure =
      spawnXgauge({"measure", tinyJob(), "-o", out("m"), "-j", "1"}, out("m.log"));
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  ::kill(measure, SIGTERM);
  ::waitpid(measure, &status, 0);
  ASSERT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGTERM)
      << "measure ended before the interrupt: " << readText(out("m.log"));
  EXPECT_FALSE(fs::exists(out("m"))) << readText(out("m.log"));
  EXPECT_EQ(temporaries(dir_), std::vector<std::string>{});
}

}  // namespace
}  // namespace xgauge
