#include "core/aov/channel_mapping.h"

#include <cctype>
#include <fstream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "core/util/error.h"
#include "core/util/input_file.h"

namespace residue {
namespace {

std::vector<std::string> split_commas(const std::string& s) {
  std::vector<std::string> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ','))
    if (!item.empty()) out.push_back(item);
  return out;
}

AovRole parse_role(const std::string& name, const std::string& where) {
  auto role = aov_role_from_string(name);
  if (!role)
    throw Error(ErrorKind::Mapping, where + ": unknown AOV \"" + name +
                                        "\"; expected one of color, albedo, normal, depth, variance, reference");
  return *role;
}

}  // namespace

namespace {

// A value that can only be a file name (a folder in it, or an image's extension), never a channel list.
bool names_a_file(const std::string& value) {
  if (value.find('/') != std::string::npos) return true;
  std::string extension = std::filesystem::path(value).extension().string();
  for (char& c : extension) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  for (const char* e : {".exr", ".hdr", ".pfm", ".tif", ".tiff", ".png", ".jpg"})
    if (extension == e) return true;
  return false;
}

}  // namespace

void ChannelMapping::add_flag(const std::string& flag) {
  const auto eq = flag.find('=');
  if (eq == std::string::npos || eq == 0 || eq + 1 == flag.size())
    throw Error(ErrorKind::Mapping, "mapping \"" + flag + "\": expected ROLE=[FILE:]CHANNELS, e.g. "
                                    "albedo=diffuse.R,diffuse.G,diffuse.B or depth=z.exr");
  const AovRole role = parse_role(flag.substr(0, eq), "mapping \"" + flag + "\"");
  const std::string value = flag.substr(eq + 1);
  ChannelBinding b;
  const auto colon = value.rfind(':');
  if (colon != std::string::npos) {
    b.file = value.substr(0, colon);
    b.channels = split_commas(value.substr(colon + 1));
  } else if (std::filesystem::is_regular_file(value)) {
    b.file = value;
  } else if (names_a_file(value)) {
    check_input_file(value, "mapping \"" + flag + "\": the file");  // says what it is instead
  } else {
    b.channels = split_commas(value);
  }
  roles[role] = b;
}

ChannelMapping ChannelMapping::from_json_file(const std::filesystem::path& path) {
  check_input_file(path, "mapping file");
  std::ifstream in(path);
  if (!in) throw Error(ErrorKind::Mapping, "cannot open mapping file '" + path.string() + "'");
  nlohmann::json j;
  try {
    in >> j;
  } catch (const std::exception& e) {
    throw Error(ErrorKind::Mapping, "mapping file '" + path.string() + "' is not valid JSON: " + e.what());
  }
  if (!j.is_object())
    throw Error(ErrorKind::Mapping, "mapping file '" + path.string() + "': expected a JSON object");
  ChannelMapping m;
  const std::filesystem::path base = path.parent_path();
  for (auto it = j.begin(); it != j.end(); ++it) {
    const std::string where = "mapping file '" + path.string() + "', key \"" + it.key() + "\"";
    if (it.key() == "layer") {
      if (!it->is_string()) throw Error(ErrorKind::Mapping, where + ": expected a string");
      m.layer_prefix = it->get<std::string>();
      continue;
    }
    const AovRole role = parse_role(it.key(), where);
    if (!it->is_object())
      throw Error(ErrorKind::Mapping, where + ": expected an object with \"file\" and/or \"channels\"");
    ChannelBinding b;
    try {
      for (auto f = it->begin(); f != it->end(); ++f) {
        if (f.key() == "file") {
          std::filesystem::path file = f->get<std::string>();
          b.file = (file.is_relative() ? base / file : file).string();
        } else if (f.key() == "channels") {
          b.channels = f->is_string() ? std::vector<std::string>{f->get<std::string>()}
                                      : f->get<std::vector<std::string>>();
        } else if (f.key() == "space") {
          auto space = normal_space_from_string(f->get<std::string>());
          if (!space) throw Error(ErrorKind::Mapping, where + ": \"space\" must be camera, world or unknown");
          b.normal_space = space;
        } else if (f.key() == "background") {
          b.depth_background = f->get<double>();
        } else {
          throw Error(ErrorKind::Mapping, where + ": unknown field \"" + f.key() +
                                              "\" (expected file, channels, space, background)");
        }
      }
    } catch (const nlohmann::json::exception& e) {
      throw Error(ErrorKind::Mapping, where + ": " + e.what());
    }
    m.roles[role] = b;
  }
  return m;
}

void ChannelMapping::merge(const ChannelMapping& other) {
  for (const auto& [role, binding] : other.roles) roles[role] = binding;
  if (!other.layer_prefix.empty()) layer_prefix = other.layer_prefix;
}

}  // namespace residue
