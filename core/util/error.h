// Errors that reach the user. Each says what was wrong, where (file, channel) and what was expected.
#pragma once

#include <stdexcept>
#include <string>

namespace residue {

enum class ErrorKind {
  Input,    // an input file is missing, unreadable, or lacks what is needed (bad AOVs, bad sizes)
  Mapping,  // a channel mapping given by the user is malformed or names channels that do not exist
  Output,   // an output cannot be written, or exists and may not be replaced
  Usage,    // arguments that contradict each other or are out of range
};

class Error : public std::runtime_error {
 public:
  Error(ErrorKind kind, const std::string& message) : std::runtime_error(message), kind_(kind) {}
  ErrorKind kind() const { return kind_; }

 private:
  ErrorKind kind_;
};

}  // namespace residue
