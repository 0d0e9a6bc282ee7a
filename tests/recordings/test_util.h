#pragma once
// Helpers shared by the recordings tests: scratch files and the real-motion data directory.

#include <filesystem>
#include <fstream>
#include <string>

namespace felt::test {

/// A fresh scratch directory under the build tree for one test, removed first if it exists.
inline std::string ScratchDir(const std::string& name) {
  const std::filesystem::path dir =
      std::filesystem::path(FELT_BINARY_DIR) / "test_scratch" / "recordings" / name;
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir.string();
}

/// Writes `text` to `path` verbatim and returns the path.
inline std::string WriteFile(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out << text;
  return path;
}

/// The whole file as bytes.
inline std::string ReadFile(const std::string& path) {
  std::error_code ec;
  const auto size = std::filesystem::file_size(path, ec);
  if (ec) return {};
  std::string bytes(static_cast<size_t>(size), '\0');
  std::ifstream in(path, std::ios::binary);
  in.read(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  return bytes;
}

/// Where the third-party real recordings live (read in place, never copied into the project).
inline std::string RealMotionDir() {
  return std::string(FELT_SOURCE_DIR "/../shared/data/real-motion");
}

}  // namespace felt::test
