#pragma once
// Scene files: TOML documents that declare the cloth and its simulation, and (read by their own
// modules) the devices, proxy and loops of a Felt session. docs/scenes.md is the format reference.
//
//   SceneDocument doc = LoadSceneDocument("scenes/curtain.toml");  // syntax, known sections
//   SceneInfo info = ParseSceneInfo(doc);                           // [scene]
//   SimSpec sim = ParseSimSpec(doc);                                // [cloth], [[obstacles]], ...
//
// Another module parses its own section with a SceneTable, declaring the keys it knows:
//
//   if (std::optional<SceneTable> proxy = SceneTable::Section(doc, "proxy")) {
//     proxy->ExpectKeys({"radius_m", "stiffness_N_per_m"});
//     spec.radius_m = proxy->Number("radius_m", 0.005, Positive());
//   }
//
// and adds the section's name to the registry in scene_file.cc (KnownSceneSections), the one list
// of top-level sections: LoadSceneDocument rejects any other, so a typo such as [clth] is caught
// by every command, whichever sections it reads.
//
// Every error is a SceneError whose message reads
//   scenes/curtain.toml:12:3: cloth.structural.stiffness_N_per_m: must be > 0, got -5
// i.e. file, line and column (of the key; of the element for a bad vector element; of the table's
// header for a missing key), the dotted field path, then the rule broken. None of this is
// real-time safe.

#include <toml++/toml.h>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <initializer_list>
#include <limits>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "collision/mesh.h"

namespace felt {

/// A bad scene: the message names the file, line, column and field, e.g.
/// "scenes/curtain.toml:12:3: cloth.structural.stiffness_N_per_m: must be > 0, got -5".
class SceneError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Whether a top-level section is written [name] (one table) or [[name]] (an array of tables).
enum class SectionShape { kTable, kArrayOfTables };

/// One top-level section of the scene format.
struct SceneSectionInfo {
  std::string_view name;   ///< e.g. "cloth"
  SectionShape shape;      ///< [name] or [[name]]
  std::string_view owner;  ///< who reads it, e.g. "ParseSimSpec (scene/scene_file.h)"
};

/// The registry of every top-level section a Felt scene may contain, in documentation order.
/// Sections whose parser has not been written yet are listed with the module that will read them,
/// so scenes may already carry them. To add a section, add a line in scene_file.cc.
std::span<const SceneSectionInfo> KnownSceneSections();

/// A parsed scene file: the TOML tree (toml++ keeps each node's line and column) and the name
/// every message starts with. Move-only in practice (the tree is large); SceneTables point into it.
struct SceneDocument {
  std::string source_name;  ///< the file as given, e.g. "scenes/curtain.toml"
  toml::table root;         ///< the document's top-level table
};

/// Reads and parses the scene file at `path`, then checks that every top-level key is a known
/// section (KnownSceneSections) of the right shape. Throws SceneError: "<path>: cannot read scene
/// file: <reason>" when it cannot be read, "<path>:<line>:<col>: syntax error: <what>" for bad
/// TOML, "<path>:<line>:<col>: unknown section [clth] (did you mean [cloth]?) ..." for an unknown
/// section.
SceneDocument LoadSceneDocument(const std::filesystem::path& path);

/// Same as LoadSceneDocument for text already in memory (tests); `source_name` starts messages.
SceneDocument ParseSceneText(std::string_view text, std::string source_name);

/// An allowed range for a number read from a scene. The default allows any finite number.
struct NumberLimits {
  double min = -std::numeric_limits<double>::infinity();  ///< lower bound
  bool min_exclusive = false;                             ///< true: value > min, else >= min
  double max = std::numeric_limits<double>::infinity();   ///< upper bound
  bool max_exclusive = false;                             ///< true: value < max, else <= max
  bool allow_infinite = false;  ///< accept inf / -inf (where within the bounds); nan never
};

/// value > 0.
constexpr NumberLimits Positive() { return NumberLimits{.min = 0.0, .min_exclusive = true}; }
/// value >= 0.
constexpr NumberLimits NonNegative() { return NumberLimits{.min = 0.0}; }
/// value >= min.
constexpr NumberLimits AtLeast(double min) { return NumberLimits{.min = min}; }
/// min <= value <= max.
constexpr NumberLimits InRange(double min, double max) {
  return NumberLimits{.min = min, .max = max};
}
/// min < value <= max.
constexpr NumberLimits InRangeOpenMin(double min, double max) {
  return NumberLimits{.min = min, .min_exclusive = true, .max = max};
}

/// Passed as a default value: the key must be present.
inline constexpr std::nullopt_t kRequired = std::nullopt;

/// One name of an enumeration as written in a scene file.
template <typename Enum>
struct NamedValue {
  std::string_view name;
  Enum value;
};

/// A view of one TOML table of a scene with its dotted path ("cloth.structural",
/// "cloth.pins[1]"): reads typed values with defaults and rules, and throws SceneError naming file,
/// line, column and field for anything wrong. Cheap to copy; valid while its SceneDocument lives.
class SceneTable {
 public:
  /// The document's top level (path "").
  static SceneTable Root(const SceneDocument& doc);

  /// Top-level section [name], or nullopt when the scene has none. Throws SceneError when `name`
  /// is not a table.
  static std::optional<SceneTable> Section(const SceneDocument& doc, std::string_view name);

  /// The entries of top-level section [[name]] in file order (empty when absent). Throws
  /// SceneError when `name` is not an array of tables.
  static std::vector<SceneTable> SectionArray(const SceneDocument& doc, std::string_view name);

  /// Subtable `key` ([path.key] or key = { ... }), or nullopt when absent. Throws SceneError when
  /// it is not a table.
  std::optional<SceneTable> Table(std::string_view key) const;

  /// The entries of [[path.key]] in file order, paths "path.key[0]", ...; empty when absent.
  /// Throws SceneError when it is not an array of tables.
  std::vector<SceneTable> ArrayOfTables(std::string_view key) const;

  /// Declares the keys this table may hold: throws SceneError for the first other key in file
  /// order, "unknown key 'stifness_N_per_m' in [cloth.structural] (did you mean
  /// 'stiffness_N_per_m'?)", at the key's position.
  void ExpectKeys(std::initializer_list<std::string_view> known) const;

  /// Whether `key` is present.
  bool Has(std::string_view key) const;

  /// A number (TOML integer or float) within `limits`; `default_value` when absent (kRequired: a
  /// missing key throws). Throws SceneError for a wrong type, nan, or a value outside the limits.
  double Number(std::string_view key, std::optional<double> default_value,
                NumberLimits limits = {}) const;

  /// A TOML integer that fits int32 and lies within `limits` (2.0 is not an integer).
  int32_t Integer(std::string_view key, std::optional<int32_t> default_value,
                  NumberLimits limits = {}) const;

  /// A TOML boolean.
  bool Bool(std::string_view key, std::optional<bool> default_value) const;

  /// A TOML string; `non_empty` rejects "".
  std::string String(std::string_view key, std::optional<std::string> default_value,
                     bool non_empty = false) const;

  /// A 3-vector written as an array of exactly 3 finite numbers, e.g. origin_m = [-0.248, 0.25, 0].
  Vec3 Vector(std::string_view key, std::optional<Vec3> default_value) const;

  /// A direction: a non-zero 3-vector, returned normalised (the file need not give unit length).
  Vec3 Direction(std::string_view key, std::optional<Vec3> default_value) const;

  /// A string that must be one of `names`; returns its value. The error lists the allowed names:
  /// "unknown value 'rk5', expected one of: leapfrog_verlet, explicit_euler, ...".
  template <typename Enum>
  Enum Choice(std::string_view key, std::optional<Enum> default_value,
              std::span<const NamedValue<Enum>> names) const {
    std::vector<std::string_view> plain;
    plain.reserve(names.size());
    std::optional<size_t> default_index;
    for (size_t i = 0; i < names.size(); ++i) {
      plain.push_back(names[i].name);
      if (default_value && names[i].value == *default_value) default_index = i;
    }
    return names[ChoiceIndex(key, default_index, plain)].value;
  }

  /// Index into `names` of the string at `key` (the untyped form of Choice).
  size_t ChoiceIndex(std::string_view key, std::optional<size_t> default_index,
                     std::span<const std::string_view> names) const;

  /// The raw TOML node at `key`, or nullptr when absent: for values of more than one type (e.g.
  /// substeps = "auto" or 8), checked by the caller, which reports with Fail.
  const toml::node* Node(std::string_view key) const;

  /// Throws SceneError "<file>:<line>:<col>: <path.key>: <rule>" at `key`, or at this table when
  /// `key` is absent.
  [[noreturn]] void Fail(std::string_view key, std::string_view rule) const;

  /// Throws SceneError "<file>:<line>:<col>: <path>: <rule>" at this table.
  [[noreturn]] void FailHere(std::string_view rule) const;

  /// The dotted path of `key` in this table, e.g. "cloth.structural.stiffness_N_per_m".
  std::string FieldPath(std::string_view key) const;

  /// This table's dotted path ("" for the top level).
  const std::string& path() const { return path_; }

  /// The file name messages start with.
  const std::string& source_name() const { return doc_->source_name; }

  /// The TOML table itself.
  const toml::table& table() const { return *table_; }

 private:
  /// The node at `key`, or nullptr when it is absent and the caller has a default to return;
  /// Fail("missing required key '<key>'") when it is absent without one.
  const toml::node* NodeOrDefault(std::string_view key, bool has_default) const;

  SceneTable(const SceneDocument* doc, const toml::table* table, std::string path)
      : doc_(doc), table_(table), path_(std::move(path)) {}

  const SceneDocument* doc_;
  const toml::table* table_;
  std::string path_;
};

/// Formats a SceneError message: "<file>:<line>:<col>: <field>: <rule>" (the position and field
/// parts are left out when unknown: line 0, empty field). For other modules' own checks.
std::string SceneErrorMessage(std::string_view source_name, const toml::source_region& where,
                              std::string_view field, std::string_view rule);

/// Where a dotted field ("integration.substeps") is written: its key's region, else the
/// deepest table on its path the file writes, else an empty region (line 0: the whole file).
toml::source_region SceneFieldRegion(const SceneDocument& doc, std::string_view dotted_field);

/// Formats a number for a message the way a user would write it (shortest round-trip form).
std::string FormatSceneNumber(double value);

/// A TOML value with its type, for wrong-type messages: "a string \"abc\"", "an integer 5".
std::string DescribeSceneValue(const toml::node& node);

/// What a scene says about itself ([scene]).
struct SceneInfo {
  std::string name;         ///< short name; default: the file's stem ("curtain")
  std::string description;  ///< one or two sentences; default ""
  double duration_s = 5.0;  ///< how long `felt run` runs it by default, > 0
};

/// Reads [scene] (keys name, description, duration_s). Throws SceneError.
SceneInfo ParseSceneInfo(const SceneDocument& doc);

}  // namespace felt
