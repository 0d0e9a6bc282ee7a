// The floor plan (issue 19; README.md "Layout"): modules form layers, and a module includes only
// from itself and the modules below it. This test reads every source file of the project and
// fails on an include that runs upward or sideways, so the rule stays true as the code grows.
// Also: only transport/ (and the example driver) includes Cyclone DDS, and only the command line
// (app/, bench/ and the example) includes CLI11.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <vector>

namespace felt {
namespace {

namespace fs = std::filesystem;

// The layers, bottom first. A module may include from modules of a lower layer only; modules of
// one layer (scene and recordings) do not include each other.
const std::map<std::string, int>& Layers() {
  static const std::map<std::string, int> layers = {
      {"base", 0},         // check macro, JSON, reports, CPU features
      {"rt", 1},           // triple buffer, SPSC queue, periodic loop, real-time settings, stats
      {"ros2", 1},         // ROS 2 messages: CDR bytes and ros2msg schemas (no DDS, no files)
      {"collision", 2},    // mesh, geometry, BVH, spatial hash, naive, collision structures
      {"scene", 3},        // the TOML scene document and its file:line:field errors
      {"recordings", 3},   // pointer traces: format, import, generation
      {"sim_loop", 4},     // the 60 Hz loop: cloth physics, snapshot, the sim frame
      {"proxy", 5},        // the god-object proxy and its scene sections
      {"haptic_loop", 6},  // the 1 kHz loop: per device proxy, safety, force out
      {"transport", 7},    // DDS
      {"server", 8},       // the threads and the monitor around both loops, wired to transport
      {"examples", 8},     // a device driver: transport only
      {"compare", 9},      // the offline lock-step driver of `felt compare`
      {"view", 9},         // the live view in the browser (HTTP + WebSocket, civetweb)
      {"app", 10},         // the `felt` command
      {"bench", 11},       // the benchmarks (register `felt bench` commands)
  };
  return layers;
}

// The quoted or bracketed target of an #include line, opening delimiter kept ("sim_loop/x.h or
// <dds/dds.h); "" for any other line.
std::string IncludeTarget(const std::string& line) {
  size_t p = line.find_first_not_of(" \t");
  if (p == std::string::npos || line[p] != '#') return "";
  p = line.find_first_not_of(" \t", p + 1);
  if (p == std::string::npos || line.compare(p, 7, "include") != 0) return "";
  p = line.find_first_of("\"<", p + 7);
  if (p == std::string::npos) return "";
  const size_t end = line.find_first_of("\">", p + 1);
  return end == std::string::npos ? "" : line.substr(p, end - p);
}

struct Violation {
  std::string file;
  int line;
  std::string text;
};

std::vector<Violation> Check() {
  const fs::path root = FELT_SOURCE_DIR;
  std::vector<Violation> out;
  for (const auto& [module, layer] : Layers()) {
    if (!fs::is_directory(root / module)) continue;
    for (const fs::directory_entry& entry : fs::recursive_directory_iterator(root / module)) {
      const std::string ext = entry.path().extension().string();
      if (ext != ".h" && ext != ".cc" && ext != ".cpp") continue;
      std::ifstream in(entry.path());
      std::string text;
      int line = 0;
      const std::string name = fs::relative(entry.path(), root).string();
      while (std::getline(in, text)) {
        ++line;
        const std::string target = IncludeTarget(text);
        if (target.empty()) continue;
        const std::string to =
            target.substr(1, target.find('/') == std::string::npos ? 0 : target.find('/') - 1);
        const auto it = Layers().find(to);
        if (target[0] == '"' && to != module && it != Layers().end() && it->second >= layer) {
          out.push_back({name, line, text + "  (" + module + " may not include " + to + ")"});
        }
        if ((to == "dds" || to == "ddsc") && module != "transport" && module != "examples") {
          out.push_back({name, line, text + "  (only transport/ includes Cyclone DDS)"});
        }
        if (to == "CLI" && module != "app" && module != "bench" && module != "examples") {
          out.push_back({name, line, text + "  (only the command line parses arguments)"});
        }
      }
    }
  }
  return out;
}

TEST(Layering, NoModuleIncludesFromAModuleAboveIt) {
  const std::vector<Violation> violations = Check();
  std::string report;
  for (const Violation& v : violations) {
    report += v.file + ":" + std::to_string(v.line) + ": " + v.text + "\n";
  }
  EXPECT_TRUE(violations.empty()) << report;
}

TEST(Layering, EveryTopLevelSourceFolderIsALayer) {
  // A new folder of code must be given its place in the floor plan.
  const fs::path root = FELT_SOURCE_DIR;
  for (const fs::directory_entry& entry : fs::directory_iterator(root)) {
    if (!entry.is_directory()) continue;
    const std::string name = entry.path().filename().string();
    if (name.empty() || name[0] == '.' || name == "tests" || name.rfind("build", 0) == 0) continue;
    bool has_code = false;
    for (const fs::directory_entry& f : fs::directory_iterator(entry.path())) {
      const std::string ext = f.path().extension().string();
      has_code = has_code || ext == ".h" || ext == ".cc" || ext == ".cpp";
    }
    if (has_code) {
      EXPECT_TRUE(Layers().count(name)) << name << "/ holds code but has no layer";
    }
  }
}

}  // namespace
}  // namespace felt
