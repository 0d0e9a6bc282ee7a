// Mutated scene files: each bundled scene, edited by a seeded mutator (tests/mutate.h), is either
// refused with a SceneError naming the file (and, for a value, its line), or accepted and then
// runs: a few frames and ticks of the real server in lock-step virtual time give finite forces
// within every device's limit. Never a crash, another exception type or a NaN (README: "Bad
// input always gets a clear error that names what was wrong").
#include <gtest/gtest.h>

#include <cmath>
#include <exception>
#include <filesystem>
#include <string>
#include <vector>

#include "compare/lockstep.h"
#include "recordings/trace.h"
#include "scene/scene_file.h"
#include "server/server_spec.h"
#include "sim_loop/cloth.h"
#include "tests/mutate.h"
#include "tests/recordings/test_util.h"
#include "tests/test_env.h"

namespace felt {
namespace {

// Mutants per scene (tests/mutate.h, MutantCount), and of those accepted, how many run.
int Mutants() { return test::MutantCount(150, 20); }
int Runs() { return test::MutantCount(8, 1); }

// Particle-substeps per frame up to which an accepted mutant is run (the bundled 32 x 32 curtain
// is about 6k): a mutant may legally ask for a 4096 x 4096 cloth or 100000 substeps, which is a
// valid scene but not a test's budget. Self-collision scenes count eight times.
constexpr double kRunBudget = 2.0e5;

TEST(BadScenes, MutatedScenesAreRefusedNamingTheFileOrRunWithBoundedForces) {
  const std::string dir = test::ScratchDir("bad_scenes");
  const Trace poke = ReadTrace(FELT_SOURCE_DIR "/recordings/poke_hold.trace");
  // 0.15 s from the press: 150 ticks, 9 frames (under a sanitizer 0.05 s: 50 ticks, 3 frames).
  const double end_s = testing::Sanitized() ? 1.05 : 1.15;
  std::vector<TraceSample> samples;
  for (const TraceSample& s : poke.samples) {
    if (s.t_s >= 1.0 && s.t_s < end_s) samples.push_back(s);
  }
  ASSERT_GT(samples.size(), 40u);
  uint64_t seed = 100;
  int refused = 0, accepted = 0, ran = 0;
  for (const auto& entry : std::filesystem::directory_iterator(FELT_SOURCE_DIR "/scenes")) {
    if (entry.path().extension() != ".toml") continue;
    const std::string good = test::ReadFile(entry.path().string());
    const std::string name = entry.path().filename().string();
    test::Mutator mutate(++seed);
    int runs_here = 0;
    for (int i = 0; i < Mutants(); ++i) {
      const std::string text = mutate.Text(good);
      const std::string source = "mutant_" + name;
      const std::string what =
          name + " (seed " + std::to_string(seed) + ", mutant " + std::to_string(i) + ")";
      ServerSpec spec;
      try {
        spec = CheckWholeScene(ParseSceneText(text, source));
      } catch (const SceneError& e) {
        ++refused;
        EXPECT_EQ(std::string(e.what()).rfind(source + ":", 0), 0u)
            << what << ": the error does not start with the file: " << e.what();
        continue;
      } catch (const std::exception& e) {
        ADD_FAILURE() << what << ": not a SceneError: " << e.what() << "\n" << text;
        return;
      }
      ++accepted;
      if (runs_here >= Runs()) continue;
      ClothModel model;
      try {
        model = BuildClothModel(spec.sim);
      } catch (const std::exception& e) {
        ADD_FAILURE() << what << ": accepted, but the cloth cannot be built: " << e.what() << "\n"
                      << text;
        return;
      }
      const double cost = static_cast<double>(model.num_particles()) * model.substeps *
                          (spec.sim.self_collision ? 8.0 : 1.0);
      if (cost > kRunBudget) continue;
      ++runs_here;
      ++ran;
      LockstepRun run;
      try {
        run = RunLockstep(spec, samples);
      } catch (const std::exception& e) {
        ADD_FAILURE() << what << ": accepted, but the server refused it: " << e.what() << "\n"
                      << text;
        return;
      }
      for (size_t k = 0; k < run.force_D_N.size(); ++k) {
        const Vec3& f = run.force_D_N[k];
        const double limit = spec.devices[k % run.devices].max_force_N;
        ASSERT_TRUE(f.allFinite() && f.norm() <= limit * (1.0 + 1e-12))
            << what << ": tick " << k / run.devices << " force " << f.transpose() << " (limit "
            << limit << ")\n"
            << text;
      }
    }
  }
  // Every scene was mutated, some mutants were refused and some ran.
  EXPECT_GT(refused, 0);
  EXPECT_GT(ran, 0);
  std::printf("mutated scenes: %d refused, %d accepted, %d run\n", refused, accepted, ran);
}

}  // namespace
}  // namespace felt
