#include "scene/scene_file.h"

#include <algorithm>
#include <array>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <iterator>
#include <sstream>
#include <system_error>
#include <utility>

namespace felt {
namespace {

// The one list of top-level sections (see KnownSceneSections in the header).
constexpr std::array<SceneSectionInfo, 11> kSceneSections = {{
    {"scene", SectionShape::kTable, "ParseSceneInfo (scene/scene_file.h)"},
    {"cloth", SectionShape::kTable, "ParseSimSpec (sim_loop/cloth_scene.h)"},
    {"obstacles", SectionShape::kArrayOfTables, "ParseSimSpec (sim_loop/cloth_scene.h)"},
    {"integration", SectionShape::kTable, "ParseSimSpec (sim_loop/cloth_scene.h)"},
    {"provot", SectionShape::kTable, "ParseSimSpec (sim_loop/cloth_scene.h)"},
    {"self_collision", SectionShape::kTable, "ParseSimSpec (sim_loop/cloth_scene.h)"},
    {"device", SectionShape::kTable, "ParseDeviceSpecs (proxy/proxy_scene.h)"},
    {"devices", SectionShape::kArrayOfTables, "ParseDeviceSpecs (proxy/proxy_scene.h)"},
    {"proxy", SectionShape::kTable, "ParseProxySpec (proxy/proxy_scene.h)"},
    {"haptic", SectionShape::kTable, "ParseHapticSpec (haptic_loop/haptic_spec.h)"},
    {"transport", SectionShape::kTable, "ParseTransportConfig (transport/transport_scene.h)"},
}};

// Levenshtein distance, for "did you mean" hints on short names.
size_t EditDistance(std::string_view a, std::string_view b) {
  std::vector<size_t> row(b.size() + 1);
  for (size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (size_t i = 1; i <= a.size(); ++i) {
    size_t diagonal = row[0];
    row[0] = i;
    for (size_t j = 1; j <= b.size(); ++j) {
      const size_t above = row[j];
      const size_t substitute = diagonal + (a[i - 1] == b[j - 1] ? 0 : 1);
      row[j] = std::min({above + 1, row[j - 1] + 1, substitute});
      diagonal = above;
    }
  }
  return row[b.size()];
}

// The closest of `candidates` to `name` when it is close enough to be a typo, else "".
std::string_view ClosestName(std::string_view name, std::span<const std::string_view> candidates) {
  std::string_view best;
  size_t best_distance = std::max<size_t>(2, name.size() / 3) + 1;
  for (std::string_view candidate : candidates) {
    const size_t distance = EditDistance(name, candidate);
    if (distance < best_distance) {
      best = candidate;
      best_distance = distance;
    }
  }
  return best;
}

std::string JoinNames(std::span<const std::string_view> names) {
  std::string joined;
  for (std::string_view name : names) {
    if (!joined.empty()) joined += ", ";
    joined += name;
  }
  return joined;
}

// A TOML value as a user would write it: -5, 2.5, 2.0, "abc", true.
std::string ValueText(const toml::node& node) {
  if (const auto* integer = node.as_integer()) return std::to_string(integer->get());
  if (const auto* floating = node.as_floating_point()) {
    const double value = floating->get();
    std::string text = FormatSceneNumber(value);
    // Keep "2.0" recognisable as a float.
    if (std::isfinite(value) && text.find_first_of(".e") == std::string::npos) text += ".0";
    return text;
  }
  if (const auto* string = node.as_string()) return "\"" + string->get() + "\"";
  if (const auto* boolean = node.as_boolean()) return boolean->get() ? "true" : "false";
  if (const auto* array = node.as_array()) {
    return "an array of " + std::to_string(array->size()) +
           (array->size() == 1 ? " value" : " values");
  }
  if (node.is_table()) return "a table";
  return "a date/time";
}

// "> 0", "in [0, 1]", "in (0, 1]", ">= 2": the rule `limits` states.
std::string LimitsText(const NumberLimits& limits) {
  const bool has_min = std::isfinite(limits.min);
  const bool has_max = std::isfinite(limits.max);
  if (has_min && has_max) {
    return std::string("in ") + (limits.min_exclusive ? "(" : "[") + FormatSceneNumber(limits.min) +
           ", " + FormatSceneNumber(limits.max) + (limits.max_exclusive ? ")" : "]");
  }
  if (has_min) return (limits.min_exclusive ? "> " : ">= ") + FormatSceneNumber(limits.min);
  if (has_max) return (limits.max_exclusive ? "< " : "<= ") + FormatSceneNumber(limits.max);
  return "a finite number";
}

bool WithinLimits(double value, const NumberLimits& limits) {
  if (std::isnan(value)) return false;
  if (std::isinf(value) && !limits.allow_infinite) return false;
  if (limits.min_exclusive ? !(value > limits.min) : !(value >= limits.min)) return false;
  if (limits.max_exclusive ? !(value < limits.max) : !(value <= limits.max)) return false;
  return true;
}

// The entries of `table` ordered by their position in the file (toml++ keeps keys sorted by name).
std::vector<std::pair<const toml::key*, const toml::node*>> EntriesInFileOrder(
    const toml::table& table) {
  std::vector<std::pair<const toml::key*, const toml::node*>> entries;
  for (auto&& [key, node] : table) entries.emplace_back(&key, &node);
  std::stable_sort(entries.begin(), entries.end(), [](const auto& a, const auto& b) {
    const toml::source_position& pa = a.first->source().begin;
    const toml::source_position& pb = b.first->source().begin;
    return pa.line != pb.line ? pa.line < pb.line : pa.column < pb.column;
  });
  return entries;
}

// "[cloth.structural]", "cloth.pins[1]", "the top level": how messages name a table.
std::string TableLabel(const std::string& path) {
  if (path.empty()) return "the top level";
  if (path.back() == ']') return path;
  return "[" + path + "]";
}

// Checks the top-level keys of a freshly parsed document against the section registry.
void CheckTopLevel(const SceneDocument& doc) {
  std::vector<std::string_view> names;
  for (const SceneSectionInfo& section : kSceneSections) names.push_back(section.name);
  for (const auto& [key, node] : EntriesInFileOrder(doc.root)) {
    const auto known =
        std::find_if(kSceneSections.begin(), kSceneSections.end(),
                     [&](const SceneSectionInfo& s) { return s.name == key->str(); });
    if (known == kSceneSections.end()) {
      std::string rule;
      if (node->is_table() || node->is_array()) {
        rule = "unknown section [" + std::string(key->str()) + "]";
        const std::string_view hint = ClosestName(key->str(), names);
        if (!hint.empty()) rule += " (did you mean [" + std::string(hint) + "]?)";
        rule += "; known sections: " + JoinNames(names);
      } else {
        rule = "unknown top-level key '" + std::string(key->str()) +
               "'; every setting belongs in a section such as [scene] or [cloth]";
      }
      throw SceneError(SceneErrorMessage(doc.source_name, key->source(), "", rule));
    }
    // Right shape: [name] is a table, [[name]] an array of tables.
    if (known->shape == SectionShape::kTable && !node->is_table()) {
      throw SceneError(SceneErrorMessage(
          doc.source_name, key->source(), key->str(),
          "must be a table [" + std::string(key->str()) + "], got " + DescribeSceneValue(*node)));
    }
    if (known->shape == SectionShape::kArrayOfTables && !node->is_array_of_tables() &&
        !(node->is_array() && node->as_array()->empty())) {
      throw SceneError(SceneErrorMessage(doc.source_name, key->source(), key->str(),
                                         "must be an array of tables [[" + std::string(key->str()) +
                                             "]], got " + DescribeSceneValue(*node)));
    }
  }
}

}  // namespace

std::span<const SceneSectionInfo> KnownSceneSections() { return kSceneSections; }

std::string FormatSceneNumber(double value) {
  if (std::isnan(value)) return "nan";
  if (std::isinf(value)) return value > 0 ? "inf" : "-inf";
  std::array<char, 64> buffer{};
  const std::to_chars_result result =
      std::to_chars(buffer.data(), buffer.data() + buffer.size(), value);
  return std::string(buffer.data(), result.ptr);
}

std::string DescribeSceneValue(const toml::node& node) {
  switch (node.type()) {
    case toml::node_type::integer:
      return "an integer " + ValueText(node);
    case toml::node_type::floating_point:
      return "a float " + ValueText(node);
    case toml::node_type::string:
      return "a string " + ValueText(node);
    case toml::node_type::boolean:
      return "a boolean " + ValueText(node);
    case toml::node_type::array:
    case toml::node_type::table:
      return ValueText(node);
    default:
      return "a date/time";
  }
}

std::string SceneErrorMessage(std::string_view source_name, const toml::source_region& where,
                              std::string_view field, std::string_view rule) {
  std::string message(source_name);
  if (where.begin.line > 0) {
    message += ":" + std::to_string(where.begin.line) + ":" + std::to_string(where.begin.column);
  }
  message += ": ";
  if (!field.empty()) {
    message += field;
    message += ": ";
  }
  message += rule;
  return message;
}

toml::source_region SceneFieldRegion(const SceneDocument& doc, std::string_view dotted_field) {
  toml::source_region where{};
  const toml::table* table = &doc.root;
  while (table != nullptr && !dotted_field.empty()) {
    const size_t dot = dotted_field.find('.');
    const std::string_view key = dotted_field.substr(0, dot);
    const toml::node* node = nullptr;
    for (auto&& [k, v] : *table) {
      if (k.str() != key) continue;
      // A value at its key, a table at its header: where the parsers' own messages put them.
      where = v.is_table() ? v.source() : k.source();
      node = &v;
      break;
    }
    if (node == nullptr) break;
    table = node->as_table();
    dotted_field =
        dot == std::string_view::npos ? std::string_view() : dotted_field.substr(dot + 1);
  }
  return where;
}

SceneDocument ParseSceneText(std::string_view text, std::string source_name) {
  SceneDocument doc;
  doc.source_name = std::move(source_name);
  // Syntax: toml++ reports the position of the first error.
  try {
    doc.root = toml::parse(text, std::string_view(doc.source_name));
  } catch (const toml::parse_error& error) {
    throw SceneError(SceneErrorMessage(doc.source_name, error.source(), "",
                                       "syntax error: " + std::string(error.description())));
  }
  CheckTopLevel(doc);
  return doc;
}

SceneDocument LoadSceneDocument(const std::filesystem::path& path) {
  const std::string name = path.string();
  // Read the whole file; a directory or an unreadable file is reported before parsing.
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) {
    throw SceneError(name + ": cannot read scene file: it is a directory");
  }
  std::ifstream file(path, std::ios::binary);
  if (!file) {
    throw SceneError(name + ": cannot read scene file: " + std::strerror(errno));
  }
  std::ostringstream contents;
  contents << file.rdbuf();
  if (file.bad()) throw SceneError(name + ": cannot read scene file: read error");
  return ParseSceneText(contents.str(), name);
}

// ------------------------------------------------------------------------------------------------
// SceneTable

SceneTable SceneTable::Root(const SceneDocument& doc) { return SceneTable(&doc, &doc.root, ""); }

std::optional<SceneTable> SceneTable::Section(const SceneDocument& doc, std::string_view name) {
  return Root(doc).Table(name);
}

std::vector<SceneTable> SceneTable::SectionArray(const SceneDocument& doc, std::string_view name) {
  return Root(doc).ArrayOfTables(name);
}

std::string SceneTable::FieldPath(std::string_view key) const {
  if (path_.empty()) return std::string(key);
  return path_ + "." + std::string(key);
}

const toml::node* SceneTable::Node(std::string_view key) const { return table_->get(key); }

const toml::node* SceneTable::NodeOrDefault(std::string_view key, bool has_default) const {
  const toml::node* node = Node(key);
  if (node == nullptr && !has_default) Fail(key, "missing required key '" + std::string(key) + "'");
  return node;
}

bool SceneTable::Has(std::string_view key) const { return table_->contains(key); }

void SceneTable::Fail(std::string_view key, std::string_view rule) const {
  const auto it = table_->find(key);
  const toml::source_region& where = it != table_->end() ? it->first.source() : table_->source();
  throw SceneError(SceneErrorMessage(doc_->source_name, where, FieldPath(key), rule));
}

void SceneTable::FailHere(std::string_view rule) const {
  throw SceneError(SceneErrorMessage(doc_->source_name, table_->source(), path_, rule));
}

std::optional<SceneTable> SceneTable::Table(std::string_view key) const {
  const toml::node* node = Node(key);
  if (node == nullptr) return std::nullopt;
  if (!node->is_table()) Fail(key, "must be a table, got " + DescribeSceneValue(*node));
  return SceneTable(doc_, node->as_table(), FieldPath(key));
}

std::vector<SceneTable> SceneTable::ArrayOfTables(std::string_view key) const {
  std::vector<SceneTable> entries;
  const toml::node* node = Node(key);
  if (node == nullptr) return entries;
  if (!node->is_array()) {
    Fail(key, "must be an array of tables ([[" + FieldPath(key) + "]]), got " +
                  DescribeSceneValue(*node));
  }
  const toml::array& array = *node->as_array();
  for (size_t i = 0; i < array.size(); ++i) {
    const std::string entry_path = FieldPath(key) + "[" + std::to_string(i) + "]";
    if (!array[i].is_table()) {
      throw SceneError(SceneErrorMessage(doc_->source_name, array[i].source(), entry_path,
                                         "must be a table, got " + DescribeSceneValue(array[i])));
    }
    entries.push_back(SceneTable(doc_, array[i].as_table(), entry_path));
  }
  return entries;
}

void SceneTable::ExpectKeys(std::initializer_list<std::string_view> known) const {
  const std::vector<std::string_view> names(known);
  for (const auto& [key, node] : EntriesInFileOrder(*table_)) {
    if (std::find(names.begin(), names.end(), key->str()) != names.end()) continue;
    std::string rule = "unknown key '" + std::string(key->str()) + "' in " + TableLabel(path_);
    const std::string_view hint = ClosestName(key->str(), names);
    if (!hint.empty()) {
      rule += " (did you mean '" + std::string(hint) + "'?)";
    } else {
      rule += "; known keys: " + JoinNames(names);
    }
    throw SceneError(
        SceneErrorMessage(doc_->source_name, key->source(), FieldPath(key->str()), rule));
  }
}

double SceneTable::Number(std::string_view key, std::optional<double> default_value,
                          NumberLimits limits) const {
  const toml::node* node = NodeOrDefault(key, default_value.has_value());
  if (node == nullptr) return *default_value;
  double value = 0.0;
  if (const auto* integer = node->as_integer()) {
    value = static_cast<double>(integer->get());
  } else if (const auto* floating = node->as_floating_point()) {
    value = floating->get();
  } else {
    Fail(key, "must be a number, got " + DescribeSceneValue(*node));
  }
  if (!WithinLimits(value, limits)) {
    Fail(key, "must be " + LimitsText(limits) + ", got " + ValueText(*node));
  }
  return value;
}

int32_t SceneTable::Integer(std::string_view key, std::optional<int32_t> default_value,
                            NumberLimits limits) const {
  const toml::node* node = NodeOrDefault(key, default_value.has_value());
  if (node == nullptr) return *default_value;
  const auto* integer = node->as_integer();
  if (integer == nullptr) Fail(key, "must be an integer, got " + DescribeSceneValue(*node));
  const int64_t value = integer->get();
  if (value < std::numeric_limits<int32_t>::min() || value > std::numeric_limits<int32_t>::max()) {
    Fail(key, "must fit in a 32-bit integer, got " + ValueText(*node));
  }
  if (!WithinLimits(static_cast<double>(value), limits)) {
    Fail(key, "must be " + LimitsText(limits) + ", got " + ValueText(*node));
  }
  return static_cast<int32_t>(value);
}

bool SceneTable::Bool(std::string_view key, std::optional<bool> default_value) const {
  const toml::node* node = NodeOrDefault(key, default_value.has_value());
  if (node == nullptr) return *default_value;
  const auto* boolean = node->as_boolean();
  if (boolean == nullptr) Fail(key, "must be true or false, got " + DescribeSceneValue(*node));
  return boolean->get();
}

std::string SceneTable::String(std::string_view key, std::optional<std::string> default_value,
                               bool non_empty) const {
  const toml::node* node = NodeOrDefault(key, default_value.has_value());
  if (node == nullptr) return *std::move(default_value);
  const auto* string = node->as_string();
  if (string == nullptr) Fail(key, "must be a string, got " + DescribeSceneValue(*node));
  if (non_empty && string->get().empty()) Fail(key, "must not be empty");
  return string->get();
}

Vec3 SceneTable::Vector(std::string_view key, std::optional<Vec3> default_value) const {
  const toml::node* node = NodeOrDefault(key, default_value.has_value());
  if (node == nullptr) return *default_value;
  const auto* array = node->as_array();
  if (array == nullptr || array->size() != 3) {
    Fail(key, "must be an array of 3 numbers [x, y, z], got " + DescribeSceneValue(*node));
  }
  Vec3 value;
  for (size_t i = 0; i < 3; ++i) {
    const toml::node& element = (*array)[i];
    const std::string element_path = FieldPath(key) + "[" + std::to_string(i) + "]";
    double component = 0.0;
    if (const auto* integer = element.as_integer()) {
      component = static_cast<double>(integer->get());
    } else if (const auto* floating = element.as_floating_point()) {
      component = floating->get();
    } else {
      throw SceneError(SceneErrorMessage(doc_->source_name, element.source(), element_path,
                                         "must be a number, got " + DescribeSceneValue(element)));
    }
    if (!std::isfinite(component)) {
      throw SceneError(SceneErrorMessage(doc_->source_name, element.source(), element_path,
                                         "must be a finite number, got " + ValueText(element)));
    }
    value[static_cast<Eigen::Index>(i)] = component;
  }
  return value;
}

Vec3 SceneTable::Direction(std::string_view key, std::optional<Vec3> default_value) const {
  const Vec3 value = Vector(key, default_value);
  const double length = value.norm();
  if (!(length > 1e-12) || !std::isfinite(length)) {
    Fail(key, "must be a non-zero vector (a direction), got a vector of length " +
                  FormatSceneNumber(length));
  }
  return value / length;
}

size_t SceneTable::ChoiceIndex(std::string_view key, std::optional<size_t> default_index,
                               std::span<const std::string_view> names) const {
  const toml::node* node = Node(key);
  if (node == nullptr) {
    if (!default_index) {
      Fail(key, "missing required key '" + std::string(key) + "', one of: " + JoinNames(names));
    }
    return *default_index;
  }
  const auto* string = node->as_string();
  if (string == nullptr) {
    Fail(key,
         "must be a string, one of: " + JoinNames(names) + "; got " + DescribeSceneValue(*node));
  }
  const std::string& value = string->get();
  const auto it = std::find(names.begin(), names.end(), value);
  if (it != names.end()) return static_cast<size_t>(std::distance(names.begin(), it));
  std::string rule = "unknown value '" + value + "'";
  const std::string_view hint = ClosestName(value, names);
  if (!hint.empty()) rule += " (did you mean '" + std::string(hint) + "'?)";
  rule += "; expected one of: " + JoinNames(names);
  Fail(key, rule);
}

// ------------------------------------------------------------------------------------------------
// [scene]

SceneInfo ParseSceneInfo(const SceneDocument& doc) {
  SceneInfo info;
  info.name = std::filesystem::path(doc.source_name).stem().string();
  const std::optional<SceneTable> scene = SceneTable::Section(doc, "scene");
  if (!scene) return info;
  scene->ExpectKeys({"name", "description", "duration_s"});
  info.name = scene->String("name", info.name, /*non_empty=*/true);
  info.description = scene->String("description", info.description);
  info.duration_s = scene->Number("duration_s", info.duration_s, Positive());
  return info;
}

}  // namespace felt
