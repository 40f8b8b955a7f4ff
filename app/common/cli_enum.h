// An option whose value is one of a table's names, stored as the name's enum (or bool): --help lists the names
// ("png|exr|both"), not CLI11's "png->0" mapping, and a value not in the table is refused naming the ones that
// are. Shared by residue-cli and residue-train.
#pragma once

#include <map>
#include <string>
#include <utility>
#include <vector>

#include <CLI/CLI.hpp>

namespace residue::cli {

template <class T>
CLI::Option* add_enum_option(CLI::App* app, const std::string& flags, T& value,
                             std::vector<std::pair<std::string, T>> names, const std::string& help) {
  std::string list, current;
  for (const auto& [n, v] : names) {
    list += (list.empty() ? "" : "|") + n;
    if (v == value) current = n;
  }
  auto* option = app->add_option_function<std::string>(
      flags,
      [&value, names](const std::string& text) {
        for (const auto& [n, v] : names)
          if (n == text) value = v;
      },
      help);
  option->type_name(list)->default_str(current);
  option->check(CLI::Validator(
      [names, list](std::string& text) -> std::string {
        for (const auto& [n, v] : names)
          if (n == text) return {};
        return "'" + text + "' is not one of " + list;
      },
      "", "one of the names"));
  return option;
}

}  // namespace residue::cli
